local plot = require("tagpose.tools.plot")
local geometry = require("support.geometry")
local run = require("support.run")

local sin, cos, rad, pi = math.sin, math.cos, math.rad, math.pi

-- a pose table of the shape tagpose.solve returns, from a position and a quaternion
local function make_pose(x, y, z, w, qx, qy, qz)
  return { position = { x = x, y = y, z = z }, quaternion = { w = w, x = qx, y = qy, z = qz },
    error = 0.1, iterations = 2 }
end

-- a smooth approach of the given tags over n frames
local function entries(tags, n, offset)
  local out = {}
  for k = 0, n - 1 do
    for _, tag in ipairs(tags) do
      local a = 0.05 * sin(k / 9 + tag)
      out[#out + 1] = { frame = k, tag = tag, pose = make_pose(0.03 * tag + (offset or 0),
        0.01 * a, 0.6 - 0.002 * k, cos(a), sin(a), 0, 0) }
    end
  end
  return out
end

local function assert_xml(svg)
  local ok, complaint = run.xmllint(svg)
  assert.is_true(ok, "xmllint: " .. tostring(complaint))
  assert.is_nil(svg:lower():find("nan", 1, true), "no NaN in the SVG")
  assert.is_nil(svg:find("inf", 1, true), "no infinity in the SVG")
end

-- the Z-Y'-X'' rotation Rz(yaw) Ry(pitch) Rx(roll), flat, written out from the definition
local function zyx(roll, pitch, yaw)
  local rz = { cos(yaw), -sin(yaw), 0, sin(yaw), cos(yaw), 0, 0, 0, 1 }
  local ry = { cos(pitch), 0, sin(pitch), 0, 1, 0, -sin(pitch), 0, cos(pitch) }
  local rx = { 1, 0, 0, 0, cos(roll), -sin(roll), 0, sin(roll), cos(roll) }
  return geometry.mul(rz, geometry.mul(ry, rx))
end

-- a quaternion of a flat rotation (trace branch and the largest-diagonal branches)
local function quaternion(r)
  local t = r[1] + r[5] + r[9]
  if t > 0 then
    local s = 2 * math.sqrt(1 + t)
    return s / 4, (r[8] - r[6]) / s, (r[3] - r[7]) / s, (r[4] - r[2]) / s
  elseif r[1] > r[5] and r[1] > r[9] then
    local s = 2 * math.sqrt(1 + r[1] - r[5] - r[9])
    return (r[8] - r[6]) / s, s / 4, (r[2] + r[4]) / s, (r[3] + r[7]) / s
  elseif r[5] > r[9] then
    local s = 2 * math.sqrt(1 - r[1] + r[5] - r[9])
    return (r[3] - r[7]) / s, (r[2] + r[4]) / s, s / 4, (r[6] + r[8]) / s
  end
  local s = 2 * math.sqrt(1 - r[1] - r[5] + r[9])
  return (r[4] - r[2]) / s, (r[3] + r[7]) / s, (r[6] + r[8]) / s, s / 4
end

describe("tagpose.tools.plot", function()
  describe("ticks()", function()
    it("puts ticks at 1, 2 or 5 times a power of ten inside the range", function()
      local ticks, step, decimals = plot.ticks(0, 0.7)
      assert.same(7, #ticks - 1)
      assert.near(0.1, step, 1e-15)
      assert.equal(1, decimals)
      for k, v in ipairs(ticks) do assert.near((k - 1) * 0.1, v, 1e-12) end
      ticks, step, decimals = plot.ticks(-0.0131, 0.0124, 5)
      assert.near(0.005, step, 1e-15)
      assert.equal(3, decimals)
      assert.near(-0.01, ticks[1], 1e-15)
      assert.near(0.01, ticks[#ticks], 1e-15)
      assert.is_true(plot.ticks(0, 199, 6)[2] == 50, "frames: steps of 50")
    end)

    it("gives exactly 0 at zero and copes with an empty range", function()
      local ticks = plot.ticks(-0.3, 0.3)
      local zero = false
      for _, v in ipairs(ticks) do if v == 0 then zero = true end end
      assert.is_true(zero)
      assert.is_true(#plot.ticks(2, 2) >= 1)
    end)

    it("always gives at least three labelled ticks, distinct as printed", function()
      local ranges = { { -0.0423, 0.0446, 2 }, { 0, 1, 1 }, { 0.999, 1.001, 1 }, { 2, 2, 2 },
        { -1e-9, 1e-9, 1 }, { 0.11, 0.19, 1 }, { -1, 0, 1 }, { 37, 1051, 2 }, { 0, 0, 1 },
        { 0.9001, 0.9003, 3 } }
      for _, r in ipairs(ranges) do
        local ticks, step, decimals = plot.ticks(r[1], r[2], r[3])
        local label = ("ticks(%g, %g, %g)"):format(r[1], r[2], r[3])
        assert.is_true(#ticks >= 3, label .. " gives " .. #ticks)
        local lo, hi = r[1], r[2]
        if lo == hi then
          local pad = lo ~= 0 and 0.1 * math.abs(lo) or 1
          lo, hi = lo - pad, hi + pad
        end
        local seen = {}
        for k, v in ipairs(ticks) do
          assert.is_true(v >= lo - 1e-9 * step and v <= hi + 1e-9 * step, label)
          if k > 1 then assert.near(step, v - ticks[k - 1], 1e-9 * step, label) end
          local text = ("%." .. decimals .. "f"):format(v)
          assert.is_nil(seen[text], label .. ": label " .. text .. " twice")
          seen[text] = true
        end
      end
    end)

    it("rejects a range that is not finite or reversed", function()
      assert.has_error(function() plot.ticks(0 / 0, 1) end,
        "bad argument #1 to 'ticks' (finite number expected, got number " .. tostring(0 / 0)
          .. ")")
      assert.has_error(function() plot.ticks(1, 0) end,
        "bad argument #2 to 'ticks' (finite number >= lo expected, got number 0)")
    end)
  end)

  describe("roll_pitch_yaw()", function()
    it("inverts R = Rz(yaw) Ry(pitch) Rx(roll) (seed 4242)", function()
      local rng = geometry.rng(4242)
      for i = 1, 200 do
        local roll, pitch, yaw = rng.uniform(-pi, pi), rng.uniform(-1.5, 1.5),
          rng.uniform(-pi, pi)
        local w, x, y, z = quaternion(zyx(roll, pitch, yaw))
        local r2, p2, y2 = plot.roll_pitch_yaw(w, x, y, z)
        local label = ("seed 4242, case %d: %.6f %.6f %.6f"):format(i, roll, pitch, yaw)
        assert.near(roll, r2, 1e-9, label)
        assert.near(pitch, p2, 1e-9, label)
        assert.near(yaw, y2, 1e-9, label)
        -- q and -q, and any length, give the same angles
        local r3, p3, y3 = plot.roll_pitch_yaw(-2 * w, -2 * x, -2 * y, -2 * z)
        assert.near(roll, r3, 1e-9, label)
        assert.near(pitch, p3, 1e-9, label)
        assert.near(yaw, y3, 1e-9, label)
      end
    end)

    it("is zero for a tag seen face-on and upright", function()
      local r, p, y = plot.roll_pitch_yaw(1, 0, 0, 0)
      assert.same({ 0, 0, 0 }, { r, p, y })
    end)

    it("gives a rotation that reproduces the quaternion at gimbal lock", function()
      for _, pitch in ipairs({ pi / 2, -pi / 2 }) do
        local w, x, y, z = quaternion(zyx(0.4, pitch, -1.1))
        local r2, p2, y2 = plot.roll_pitch_yaw(w, x, y, z)
        assert.near(pitch, p2, 1e-6)
        assert.equal(0, r2)
        assert.rotation_near(zyx(0.4, pitch, -1.1), zyx(r2, p2, y2), 1e-5)
      end
    end)
  end)

  describe("poses()", function()
    it("draws a panel per component and a series per tag and source, as valid XML", function()
      local svg, shown = plot.poses({
        { label = "tagpose", entries = entries({ 1, 2 }, 60) },
        { label = "truth", entries = entries({ 1, 2 }, 60, 0.001) },
      }, { title = "approach" })
      assert_xml(svg)
      assert.same({ panels = 7, series = 28, tags = { 1, 2 } }, shown)
      assert.equal(7, run.count(svg, '<g class="panel"'))
      assert.equal(28, run.count(svg, '<g class="series"'))
      assert.equal(7, run.count(svg, 'data-series="4"'))
      for _, name in ipairs({ "x", "y", "z", "qw", "qx", "qy", "qz" }) do
        assert.truthy(svg:find('id="panel-' .. name .. '"', 1, true), name)
      end
      assert.truthy(svg:find('data-panels="7" data-series="28"', 1, true))
      -- each series is one polyline here (no gaps), and the truth's are dashed
      assert.equal(28, run.count(svg, "<polyline"))
      assert.equal(14, run.count(svg, 'data-source="truth" stroke="#'))
      for group in svg:gmatch('<g class="series"[^>]*>') do
        assert.equal(group:find('data-source="truth"', 1, true) ~= nil,
          group:find("stroke-dasharray", 1, true) ~= nil, group)
      end
      -- axes: tick marks and labels in every panel, the units, the legend
      assert.is_true(run.count(svg, 'class="tick-label"') >= 7 * 5)
      assert.truthy(svg:find(">x %(m%)<"))
      assert.truthy(svg:find(">frame<"))
      assert.equal(4, run.count(svg, 'class="legend-label"'))
      assert.truthy(svg:find(">tag 2<", 1, true))
    end)

    it("renders with rsvg-convert", function()
      local svg = plot.poses({ { label = "tagpose", entries = entries({ 1, 2 }, 40) },
        { label = "truth", entries = entries({ 1, 2 }, 40, 0.001) } }, { rotation = "rpy" })
      local path = run.write(os.tmpname(), svg)
      local png = path .. ".png"
      local out, status = run.run("rsvg-convert -o " .. run.quote(png) .. " " .. run.quote(path)
        .. " 2>&1")
      local f = io.open(png, "rb")
      local head = f and f:read(8)
      if f then f:close() end
      os.remove(path)
      os.remove(png)
      assert.equal(0, status, out)
      assert.equal("\137PNG\r\n\26\n", head)
    end)

    it("draws roll, pitch and yaw in degrees when asked", function()
      local svg, shown = plot.poses({ { label = "a", entries = entries({ 3 }, 10) } },
        { rotation = "rpy", length_unit = "mm" })
      assert_xml(svg)
      assert.equal(6, shown.panels)
      for _, name in ipairs({ "roll", "pitch", "yaw" }) do
        assert.truthy(svg:find('id="panel-' .. name .. '"', 1, true), name)
      end
      assert.truthy(svg:find(">yaw %(deg%)<"))
      assert.truthy(svg:find(">z %(mm%)<"))
    end)

    it("breaks lines at failed rows, NaN and gaps, and survives empty or single points", function()
      local e = entries({ 1 }, 30)
      e[10].pose = nil -- a failed row
      e[20].pose.position.y = 0 / 0
      table.remove(e, 25) -- a frame the tag was not seen
      local svg, shown = plot.poses({
        { label = "gappy", entries = e },
        { label = "single",
          entries = { { frame = 5, tag = 1, pose = make_pose(0, 0, 1, 1, 0, 0, 0) } } },
        { label = "empty", entries = {} },
      })
      assert_xml(svg)
      assert.equal(14, shown.series)
      -- x: cut at the failed row and the gap; y also at the NaN
      assert.equal(3, run.count(run.panel(svg, "x"), "<polyline"))
      assert.equal(4, run.count(run.panel(svg, "y"), "<polyline"))
      -- the single point is a dot in every panel
      assert.equal(7, run.count(svg, "<circle"))
    end)

    it("draws empty panels for no data at all", function()
      local svg, shown = plot.poses({})
      assert_xml(svg)
      assert.same({ panels = 7, series = 0, tags = {} }, shown)
      assert.equal(7, run.count(svg, ">no data<"))
      svg = plot.poses({ { label = "failed", entries = { { frame = 1, tag = 4 } } } })
      assert_xml(svg)
    end)

    it("escapes text", function()
      local svg = plot.poses({ { label = "a<b & \"c\"", entries = entries({ 1 }, 3) } },
        { title = "x < y & z" })
      assert_xml(svg)
      assert.truthy(svg:find("x &lt; y &amp; z", 1, true))
    end)

    it("rejects sources and options of the wrong shape", function()
      assert.has_error(function() plot.poses("poses.csv") end,
        "bad argument #1 to 'poses' (array of sources expected, got string)")
      assert.has_error(function() plot.poses({ { label = "a" } }) end,
        "bad argument #1 to 'poses' (sources[1]: {label =, entries = {...}} expected)")
      assert.has_error(function() plot.poses({}, { rotation = "euler" }) end,
        "bad argument #2 to 'poses' (options.rotation: 'quaternion' or 'rpy' expected, got"
          .. " string euler)")
      assert.has_error(function() plot.poses({}, { width = 10 }) end,
        "bad argument #2 to 'poses' (options.width: number >= 100 expected, got number 10)")
    end)
  end)

  describe("poses(), honestly", function()
    -- the y coordinates of the points of every polyline of a series, in order
    local function polylines(svg, name, tag)
      local out = {}
      local text = run.panel(svg, name)
      for group, body in text:gmatch('(<g class="series"[^>]*>)(.-)</g>') do
        if group:find('data-tag="' .. tag .. '"', 1, true) then
          for pts in body:gmatch('<polyline points="([^"]*)"') do
            local ys = {}
            for y in pts:gmatch("[%d.%-]+,([%d.%-]+)") do ys[#ys + 1] = tonumber(y) end
            out[#out + 1] = ys
          end
        end
      end
      return out
    end

    it("keeps the quaternion's sign continuous along a track (poses keep w >= 0)", function()
      -- a turn about z through 180 degrees: the stored quaternion flips sign at w = 0
      local e = {}
      for k = 0, 40 do
        local a = rad(160 + k)
        local w, z = cos(a / 2), sin(a / 2)
        if w < 0 then w, z = -w, -z end
        e[#e + 1] = { frame = k, tag = 1, pose = make_pose(0, 0, 1, w, 0, 0, z) }
      end
      local svg = plot.poses({ { label = "turn", entries = e } })
      for _, name in ipairs({ "qw", "qz" }) do
        local lines = polylines(svg, name, "1")
        assert.equal(1, #lines, name .. ": one unbroken line")
        local ys, jump = lines[1], 0
        for k = 2, #ys do jump = math.max(jump, math.abs(ys[k] - ys[k - 1])) end
        -- one degree a frame moves a component by at most 0.0087: a few px of a 150 px panel
        assert.is_true(jump < 15, name .. ": a jump of " .. jump .. " px")
      end
    end)

    it("tells more than ten tags apart: colour, then marker", function()
      local ids = {}
      for k = 1, 45 do ids[k] = k end
      local svg = plot.poses({ { label = "many", entries = entries(ids, 30) } })
      assert_xml(svg)
      local styles = {}
      for group in run.panel(svg, "x"):gmatch('<g class="series"[^>]*>.-</g>') do
        local colour = group:match('stroke="(#%x+)"')
        local marker = group:match('data%-marker="(%a+)"') or "none"
        local key = colour .. "/" .. marker
        assert.is_nil(styles[key], "two tags drawn as " .. key)
        styles[key] = true
      end
      assert.equal(45, run.count(run.panel(svg, "x"), '<g class="series"'))
      -- the legend shows the marker of each tag past the tenth
      assert.equal(35, run.count(svg:sub(1, svg:find('<g class="panel"', 1, true)),
        'class="marker"'))
    end)

    it("keeps tags that share an id apart by the entries' tracks", function()
      local e = {}
      for k = 0, 30 do
        -- two tags, both id 0, swapping their order in the log every frame; their tracks
        -- (as tagpose.tracker or a truth file's track column gives them) are 11 and 12
        local a = { frame = k, tag = 0, track = 11, pose = make_pose(-0.1, 0, 0.5 + 0.001 * k, 1,
          0, 0, 0) }
        local b = { frame = k, tag = 0, track = 12, pose = make_pose(0.1, 0, 0.6 - 0.001 * k, 1,
          0, 0, 0) }
        if k % 2 == 0 then a, b = b, a end
        e[#e + 1] = a
        e[#e + 1] = b
      end
      local svg, shown = plot.poses({ { label = "twins", entries = e } })
      assert.equal(14, shown.series)
      assert.truthy(svg:find(">tag 0 #1<", 1, true))
      assert.truthy(svg:find(">tag 0 #2<", 1, true))
      for _, ys in ipairs(polylines(svg, "x", "0")) do
        for k = 2, #ys do assert.is_true(math.abs(ys[k] - ys[k - 1]) < 1, "no zig-zag") end
      end
    end)

    it("shows in the legend only what is drawn", function()
      local failed = { { frame = 1, tag = 9 }, { frame = 2, tag = 9 } }
      local svg = plot.poses({ { label = "tagpose", entries = entries({ 1 }, 10) } })
      assert.equal(1, run.count(svg, 'class="legend-label"'), "one source: no source entry")
      svg = plot.poses({ { label = "tagpose", entries = entries({ 1 }, 10) },
        { label = "nothing", entries = failed } })
      assert.is_nil(svg:find(">tag 9<", 1, true), "a tag without a finite pose")
      assert.is_nil(svg:find(">nothing<", 1, true), "a source without a finite pose")
      svg = plot.poses({ { label = "tagpose", entries = entries({ 1 }, 10) },
        { label = "truth", entries = entries({ 1 }, 10, 0.001) } })
      assert.truthy(svg:find(">truth<", 1, true))
      assert.truthy(svg:find(">tagpose<", 1, true))
    end)

    it("keeps a long series in bounded memory without losing its outliers", function()
      local rec = plot.recorder()
      local src = rec:source("long")
      local n = 20 * plot.MAX_POINTS
      for k = 1, n do
        local x = k == 12345 and 5 or 0.01 * sin(k / 50)
        rec:add(src, 1, 1, k, make_pose(x, 0, 1, 1, 0, 0, 0))
      end
      local svg = plot.draw(rec)
      assert_xml(svg)
      local points = 0
      for pts in run.panel(svg, "x"):gmatch('<polyline points="([^"]*)"') do
        points = points + select(2, pts:gsub(",", ""))
      end
      assert.is_true(points <= 2 * plot.MAX_POINTS, points .. " points drawn")
      -- the spike is drawn: the axis reaches past 4 (the rest stays within 0.01)
      assert.truthy(run.panel(svg, "x"):find(">4<", 1, true))
      assert.equal(0, rec.dropped)
    end)

    it("says in every empty panel why it is empty (options.empty)", function()
      local rec = plot.recorder()
      rec:source("none")
      local why = "no pose: no row of corners.csv was solved; 377 of its 377 rows failed with"
        .. " square: corners wind the wrong way round (--order opencv)"
      local svg = plot.draw(rec, { empty = why })
      assert_xml(svg)
      assert.equal(0, run.count(svg, ">no data<"))
      -- in lines that fit the panel, every word of it
      local words = {}
      for text in svg:gmatch('<text class="no%-data".-</text>') do
        local said = {}
        for line in text:gmatch("<tspan[^>]*>(.-)</tspan>") do said[#said + 1] = line end
        assert.is_true(#said >= 2, text)
        words[#words + 1] = table.concat(said, " ")
      end
      assert.equal(7, #words)
      for _, w in ipairs(words) do assert.equal(why, w) end
      assert.has_error(function() plot.draw(rec, { empty = 1 }) end,
        "bad argument #2 to 'draw' (options.empty: string expected, got number 1)")
    end)

    it("keeps at most MAX_SERIES series, counting the points it leaves out", function()
      local rec = plot.recorder()
      local src = rec:source("ids")
      for k = 1, plot.MAX_SERIES + 10 do rec:add(src, k, 1, 1, make_pose(0, 0, 1, 1, 0, 0, 0)) end
      assert.equal(10, rec.skipped)
      local _, shown = plot.draw(rec)
      assert.equal(plot.MAX_SERIES, shown.tracks)
    end)
  end)

  describe("figure()", function()
    it("lays out any panels in columns and shares the frame axis", function()
      local xs, ys = {}, {}
      for k = 1, 50 do xs[k], ys[k] = k, rad(k) end
      local svg, shown = plot.figure({
        columns = {
          { { name = "a", title = "a", unit = "rad", series = { { x = xs, y = ys } } } },
          { { name = "b", series = { { x = { 100 }, y = { 1 } } } },
            { name = "c", range = { -1, 1 }, series = {} } },
        },
      })
      assert_xml(svg)
      assert.same({ panels = 3, series = 2 }, shown)
      assert.equal(3, run.count(svg, '<g class="panel"'))
      -- one x axis for all panels: the same tick labels under each
      local a, c = run.panel(svg, "a"), run.panel(svg, "c")
      assert.truthy(a:find(">100<", 1, true))
      assert.truthy(c:find(">100<", 1, true))
      assert.truthy(c:find(">-1.0<", 1, true))
    end)

    it("rejects a figure without columns", function()
      assert.has_error(function() plot.figure({}) end,
        "bad argument #1 to 'figure' (figure.columns: non-empty array of columns expected)")
    end)
  end)
end)
