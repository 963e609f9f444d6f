--- tagpose.tools.localize_plot against geometry: a 4 m × 3 m room of four wall tags, a robot
-- on a 1 m circle, rows with a covariance whose 95 % ellipse is known (σ 0.10 m and 0.04 m,
-- the major axis at 30°), odometry that is the path seen from a frame turned by 2.0 rad and
-- shifted (never reset), tags rejected.

local localize_plot = require("tagpose.tools.localize_plot")
local tagpose = require("tagpose")
local model = require("tagpose.rigid.model")
local run = require("support.run")
local assertions = require("support.assertions")

local sin, cos, sqrt, pi, rad, deg = math.sin, math.cos, math.sqrt, math.pi, math.rad, math.deg

local CHI2 = 5.991 -- χ²(2) at 95 %

-- A wall tag at (x, y, z) facing the inward normal (nx, ny): tag z = −normal, y = down,
-- x = y × z; r flat, row-major, tag → field.
local function wall_tag(id, x, y, z, nx, ny)
  local zx, zy = -nx, -ny
  -- y = (0, 0, −1): x = y × z = (0·0 − (−1)·zy, (−1)·zx − 0·0, 0)
  local xx, xy = zy, -zx
  return { id = id, x = x, y = y, z = z, size = 0.2, half = 0.1,
    r = { xx, 0, zx, xy, 0, zy, 0, -1, 0 } }
end

local function room()
  local tags = { ids = { 1, 2, 3, 4 } }
  tags[1] = wall_tag(1, 0, 1.5, 1.0, 1, 0) -- west wall, faces +x
  tags[2] = wall_tag(2, 4, 1.5, 1.0, -1, 0) -- east wall, faces −x
  tags[3] = wall_tag(3, 2, 0, 0.8, 0, 1) -- south wall, faces +y
  tags[4] = wall_tag(4, 2, 3, 0.8, 0, -1) -- north wall, faces −y
  return tags
end

-- The covariance C = R(30°) diag(0.10², 0.04²) R(30°)ᵀ, nested 6×6 (x, y first).
local SIGMA1, SIGMA2, ANGLE = 0.10, 0.04, rad(30)

local function covariance()
  local c, s = cos(ANGLE), sin(ANGLE)
  local a, b = SIGMA1 ^ 2, SIGMA2 ^ 2
  local C = {}
  for i = 1, 6 do
    C[i] = {}
    for j = 1, 6 do C[i][j] = i == j and 1e-4 or 0 end
  end
  C[1][1] = c * c * a + s * s * b
  C[1][2] = c * s * (a - b)
  C[2][1] = C[1][2]
  C[2][2] = s * s * a + c * c * b
  return C
end

-- The robot on a circle of 1 m round (2, 1.5), one turn in 8 s, heading along the circle.
local function truth(t)
  local w = 2 * pi / 8
  return 2 + cos(w * t), 1.5 + sin(w * t), w * t + pi / 2
end

-- Rows at 20 Hz over 0-4 s but none in (2, 3.5) (a gap of 1.5 s: the path is broken there);
-- tag 2 rejected in the first 5 rows, tag 99 (not on the map) in two.
local function rows()
  local out = {}
  for k = 0, 80 do
    if k <= 40 or k >= 70 then
      local t = k / 20
      local x, y, yaw = truth(t)
      local r = { time = t, camera = "front", position = { x = x, y = y, z = 0 }, yaw = yaw,
        covariance = covariance(), tags = { 1, 3 }, rejected = {} }
      if k < 5 then r.rejected[#r.rejected + 1] = { id = 2, why = "disagrees" } end
      if k == 7 or k == 8 then r.rejected[#r.rejected + 1] = { id = 99, why = "not on the map" } end
      out[#out + 1] = r
    end
  end
  return out
end

-- The odometry: the truth in a frame o with field = R(THETA)·o + (TX, TY), at 40 Hz from -0.5 s
-- to 4.5 s (every row's time is one of its samples, so interpolation is exact there).
local THETA, TX, TY = 2.0, -3.5, 12.25

local function odometry()
  local out = {}
  local c, s = cos(THETA), sin(THETA)
  for k = -20, 180 do
    local t = k / 40
    local x, y, yaw = truth(t)
    local dx, dy = x - TX, y - TY
    out[#out + 1] = { t, c * dx + s * dy, -s * dx + c * dy, yaw - THETA }
  end
  return out
end

local function assert_xml(svg)
  local ok, complaint = run.xmllint(svg)
  assert.is_true(ok, "xmllint: " .. tostring(complaint))
  assert.is_nil(svg:lower():find("nan", 1, true), "no NaN in the SVG")
  assert.is_nil(svg:find("inf", 1, true), "no infinity in the SVG")
end

-- The attributes of every element of class `class` (or of the first match of a pattern).
local function elements(svg, class)
  local out = {}
  for el in svg:gmatch("<[%w]+ [^>]-class=\"" .. class .. "\"[^>]*>") do
    local attrs = {}
    for k, v in el:gmatch('([%w%-]+)="([^"]*)"') do attrs[k] = v end
    out[#out + 1] = attrs
  end
  return out
end

local function one(svg, class)
  local list = elements(svg, class)
  assert.equal(1, #list, class)
  return list[1]
end

describe("tagpose.tools.localize_plot", function()
  describe("svg()", function()
    local svg, shown = localize_plot.svg(room(), rows(), odometry(), { title = "room" })

    it("is a well-formed SVG document", function()
      assert_xml(svg)
      assert.truthy(svg:find("<title>room</title>", 1, true))
    end)

    it("draws every tag, the path's points, an ellipse every 0.5 s", function()
      assert.equal(4, tonumber(one(svg, "tags")["data-count"]))
      assert.equal(4, #elements(svg, "tag"))
      assert.equal(4, shown.tags)
      -- rows at k = 0..40 and 70..80
      local path = one(svg, "path")
      assert.equal(52, tonumber(path["data-points"]))
      assert.equal(2, tonumber(path["data-runs"]), "broken at the 1.5 s gap")
      assert.equal(3, run.count(svg, "<polyline points="), "two runs and the odometry")
      -- 0, 0.5, 1, 1.5, 2, then 3.5 and 4
      assert.equal(7, tonumber(one(svg, "ellipses")["data-count"]))
      local times = {}
      for _, e in ipairs(elements(svg, "ellipse")) do
        times[#times + 1] = tonumber(e["data-time"])
      end
      assert.same({ 0, 0.5, 1, 1.5, 2, 3.5, 4 }, times)
      assert.equal(7, shown.ellipses)
      assert.equal(52, shown.points)
    end)

    it("marks the rejected tag with its count, and names the one not on the map", function()
      assert.equal(1, tonumber(one(svg, "tags")["data-rejected"]))
      for _, t in ipairs(elements(svg, "tag")) do
        if t["data-id"] == "2" then
          assert.equal("5", t["data-rejected"])
          assert.equal(localize_plot.COLOURS.rejected, t.stroke)
        else
          assert.equal("0", t["data-rejected"])
          assert.equal(localize_plot.COLOURS.tag, t.stroke)
        end
      end
      assert.truthy(svg:find(">2 ×5/5<", 1, true))
      assert.truthy(svg:find("rejected, not on the map: 99 ×2", 1, true))
    end)

    it("draws the 95 % ellipse of a known covariance: axes sqrt(5.991 λ), along the eigenvectors",
      function()
        local C = covariance()
        local a11, a12, a22 = C[1][1], C[1][2], C[2][2]
        -- the eigenvalues as the roots of λ² − tr·λ + det
        local tr, det = a11 + a22, a11 * a22 - a12 * a12
        local l1 = 0.5 * (tr + sqrt(tr * tr - 4 * det))
        local l2 = 0.5 * (tr - sqrt(tr * tr - 4 * det))
        assert.near(SIGMA1 ^ 2, l1, 1e-12)
        assert.near(SIGMA2 ^ 2, l2, 1e-12)
        local field = one(svg, "field%-outline")
        local px_per_m = tonumber(field["data-scale"])
        for _, e in ipairs(elements(svg, "ellipse")) do
          local a, b = tonumber(e["data-a"]), tonumber(e["data-b"])
          assert.near(sqrt(CHI2 * l1), a, 1e-3 * a)
          assert.near(sqrt(CHI2 * l2), b, 1e-3 * b)
          assert.near(deg(ANGLE), tonumber(e["data-angle"]), 1e-3)
          -- one scale for both axes; y up in the field is y down on the page
          assert.near(a * px_per_m, tonumber(e.rx), 1e-3 * a * px_per_m)
          assert.near(b * px_per_m, tonumber(e.ry), 1e-3 * b * px_per_m)
          assert.truthy(e.transform:find("^rotate%(%-30 "), e.transform)
        end
        -- the major axis is an eigenvector: C·v = λ1·v
        local ea, eb, angle = localize_plot.ellipse(a11, a12, a22)
        local vx, vy = cos(angle), sin(angle)
        assert.near(l1 * vx, a11 * vx + a12 * vy, 1e-12)
        assert.near(l1 * vy, a12 * vx + a22 * vy, 1e-12)
        assert.near(sqrt(CHI2 * l1), ea, 1e-3 * ea)
        assert.near(sqrt(CHI2 * l2), eb, 1e-3 * eb)
      end)

    it("frames the tags and the path with a margin, equal x/y scale", function()
      local f = one(svg, "field%-outline")
      local m = localize_plot.MARGIN
      -- tags 1 and 2 at x = 0 and 4, 3 and 4's faces along x at y = 0 and 3 (±0.1)
      assert.near(0 - m, tonumber(f["data-x0"]), 1e-9)
      assert.near(4 + m, tonumber(f["data-x1"]), 1e-9)
      assert.near(0 - m, tonumber(f["data-y0"]), 1e-9)
      assert.near(3 + m, tonumber(f["data-y1"]), 1e-9)
      local s = tonumber(f["data-scale"])
      assert.near((4 + 2 * m) * s, tonumber(f.width), 0.1)
      assert.near((3 + 2 * m) * s, tonumber(f.height), 0.1)
      assert.truthy(svg:find(">x %(m%)<"))
      assert.truthy(svg:find(">y %(m%)<"))
      assert.is_true(#elements(svg, "tick%-label") >= 6)
      assert.equal(5, #elements(svg, "legend%-label"))
    end)

    it("draws the odometry dashed, moved onto the path by the recovered rotation and shift",
      function()
        local o = one(svg, "odometry")
        assert.equal("6 4", o["stroke-dasharray"])
        assert.equal(201, tonumber(o["data-points"]))
        assert.near(deg(THETA), tonumber(o["data-rotation"]), 1e-3) -- 6 digits written
        assert.near(TX, tonumber(o["data-dx"]), 1e-5)
        assert.near(TY, tonumber(o["data-dy"]), 1e-5)
        assert.equal(52, tonumber(o["data-pairs"]))
        assert.truthy(svg:find("odometry, moved onto the path by the best rigid fit (rotated "
          .. ("%.1f"):format(deg(THETA)) .. "°", 1, true))
      end)

    it("renders with rsvg-convert", function()
      local path = run.write(os.tmpname(), svg)
      local png = path .. ".png"
      local out, status = run.run("rsvg-convert -o " .. run.quote(png) .. " " .. run.quote(path)
        .. " 2>&1")
      local f = io.open(png, "rb")
      local head = f and f:read(8)
      local size = f and f:seek("end")
      if f then f:close() end
      os.remove(path)
      os.remove(png)
      assert.equal(0, status, out)
      assert.equal("\137PNG\r\n\26\n", head)
      assert.is_true(size > 1000)
    end)

    it("draws a map alone, and says why the odometry is not drawn", function()
      local text, s = localize_plot.svg(room(), {}, { { 10, 0, 0, 0 }, { 11, 1, 0, 0 } })
      assert_xml(text)
      assert.equal("0", one(text, "path")["data-points"])
      assert.equal("0", one(text, "ellipses")["data-count"])
      assert.equal(0, #elements(text, "odometry"))
      assert.is_string(s.odometry_note)
      assert.truthy(text:find("no estimate", 1, true))
      -- odometry after every row
      local later = localize_plot.svg(room(), rows(), { { 10, 0, 0, 0 }, { 11, 1, 0, 0 } })
      assert.truthy(later:find("odometry not drawn: no row within its times", 1, true))
    end)

    it("raises on misuse at the caller", function()
      assert.equal("bad argument #1 to 'svg' (map tags {ids = {...}, [id] = tag} expected, got "
        .. "nil)", assertions.raised(function() localize_plot.svg(nil, {}) end,
        "localize_plot_spec.lua"))
      assert.equal("bad argument #2 to 'svg' (rows table expected, got string)",
        assertions.raised(function() localize_plot.svg(room(), "rows") end,
        "localize_plot_spec.lua"))
      assert.equal("bad argument #3 to 'svg' (odometry[1]: {t, x, y, yaw} expected)",
        assertions.raised(function() localize_plot.svg(room(), {}, { {} }) end,
        "localize_plot_spec.lua"))
      assert.equal("bad argument #4 to 'svg' (options.ellipse_every: positive number expected, "
        .. "got number 0)", assertions.raised(function()
        localize_plot.svg(room(), {}, nil, { ellipse_every = 0 })
      end, "localize_plot_spec.lua"))
    end)
  end)

  describe("align()", function()
    it("recovers a known rotation and translation", function()
      local al = assert(localize_plot.align(rows(), odometry()))
      assert.near(THETA, al.theta, 1e-9)
      assert.near(TX, al.x, 1e-9)
      assert.near(TY, al.y, 1e-9)
      assert.near(0, al.rms, 1e-9)
      assert.equal(52, al.pairs)
    end)

    it("recovers them between samples, within the interpolation's error", function()
      -- odometry at 25 Hz, offset by 0.013 s: no row time is a sample's
      local c, s = cos(THETA), sin(THETA)
      local odo = {}
      for k = -10, 110 do
        local t = k / 25 + 0.013
        local x, y, yaw = truth(t)
        odo[#odo + 1] = { t, c * (x - TX) + s * (y - TY), -s * (x - TX) + c * (y - TY),
          yaw - THETA }
      end
      local al = assert(localize_plot.align(rows(), odo))
      -- a chord of 0.04 s on a 1 m circle at 0.785 m/s sags by at most (0.0314)² / 8 m
      assert.near(THETA, al.theta, 1e-3)
      assert.near(TX, al.x, 2e-3)
      assert.near(TY, al.y, 2e-3)
      assert.is_true(al.rms < 2e-4, tostring(al.rms))
    end)

    it("takes the headings when the robot stood still", function()
      local still = {}
      for k = 0, 10 do
        still[#still + 1] = { time = k / 10, position = { x = 1, y = 2 }, yaw = 0.5 }
      end
      local c, s = cos(THETA), sin(THETA)
      local ox, oy = c * (1 - TX) + s * (2 - TY), -s * (1 - TX) + c * (2 - TY)
      local al = assert(localize_plot.align(still, { { -1, ox, oy, 0.5 - THETA },
        { 2, ox, oy, 0.5 - THETA } }))
      assert.near(THETA, al.theta, 1e-9)
      assert.near(TX, al.x, 1e-9)
      assert.near(TY, al.y, 1e-9)
    end)

    it("returns nil and a reason without a row in the odometry's times", function()
      local al, err = localize_plot.align(rows(), { { 10, 0, 0, 0 }, { 11, 1, 0, 0 } })
      assert.is_nil(al)
      assert.equal("localize_plot: no row within the odometry's times", err)
    end)
  end)

  describe("tagpose-localize --svg", function()
    -- A robot standing at (1, 1.5) heading +x, one camera 0.5 m up looking ahead at three tags
    -- on the wall x = 3 (facing −x), 30 frames at 30 Hz, corners projected through a pinhole.
    local dir = run.tmpdir()
    local SIZE, F, CX, CY = 0.1651, 600, 320, 240
    local WALL = { { 1, 1.2, 0.6 }, { 2, 1.8, 0.5 }, { 3, 1.5, 0.9 } }
    -- tag → field on the wall x = 3: z = (1, 0, 0) into the wall, y down, x = y × z = (0, −1, 0)
    local R = { 0, 0, 1, -1, 0, 0, 0, -1, 0 }
    local CAM = { 1, 1.5, 0.5 } -- optical → field is R too: optical z along +x, x right (−y)

    local function setup()
      local layout = { tags = {} }
      for _, w in ipairs(WALL) do
        layout.tags[w[1]] = model.entry(R, 3, w[2], w[3], SIZE)
      end
      assert(tagpose.layout.write(dir .. "/map.csv", layout))
      run.write(dir .. "/cameras.lua", ("return { front = { fx = %d, fy = %d, cx = %d, cy = %d,"
        .. " width = 640, height = 480, mount = { position = { x = 0, y = 0, z = 0.5 },"
        .. " quaternion = { w = 0.5, x = -0.5, y = 0.5, z = -0.5 } } } }\n"):format(F, F, CX, CY))
      local lines = { "time,camera,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
      local h = SIZE / 2
      for k = 0, 29 do
        for _, w in ipairs(WALL) do
          local row = { ("%.6f"):format(k / 30), "front", w[1] }
          for _, c in ipairs({ { -h, h }, { h, h }, { h, -h }, { -h, -h } }) do
            -- the corner in the field, then in the camera (Rᵀ (X − CAM))
            local X = { R[1] * c[1] + R[2] * c[2] + 3, R[4] * c[1] + R[5] * c[2] + w[2],
              R[7] * c[1] + R[8] * c[2] + w[3] }
            local d = { X[1] - CAM[1], X[2] - CAM[2], X[3] - CAM[3] }
            local x = R[1] * d[1] + R[4] * d[2] + R[7] * d[3]
            local y = R[2] * d[1] + R[5] * d[2] + R[8] * d[3]
            local z = R[3] * d[1] + R[6] * d[2] + R[9] * d[3]
            row[#row + 1] = ("%.6f,%.6f"):format(F * x / z + CX, F * y / z + CY)
          end
          lines[#lines + 1] = table.concat(row, ",")
        end
      end
      run.write(dir .. "/corners.csv", table.concat(lines, "\n") .. "\n")
      -- odometry standing still elsewhere, turned by 0.3 rad
      run.write(dir .. "/odometry.csv", "time,x,y,yaw\n0,5,-2,-0.3\n1.5,5,-2,-0.3\n")
    end

    it("draws the rows it writes, with the tags and the aligned odometry", function()
      setup()
      local out, status = run.script("bin/tagpose-localize", dir .. "/corners.csv", "--map",
        dir .. "/map.csv", "--cameras", dir .. "/cameras.lua", "--odometry",
        dir .. "/odometry.csv", "--max-gap", "2", "--out", dir .. "/poses.csv", "--svg",
        dir .. "/plot.svg")
      assert.equal(0, status, out)
      local poses = run.read(dir .. "/poses.csv")
      local nrows = run.count(poses, "\n") - 1
      assert.is_true(nrows > 0, poses)
      local svg = run.read(dir .. "/plot.svg")
      assert_xml(svg)
      assert.equal(3, tonumber(one(svg, "tags")["data-count"]))
      assert.equal(0, tonumber(one(svg, "tags")["data-rejected"]))
      assert.equal(nrows, tonumber(one(svg, "path")["data-points"]))
      assert.is_true(tonumber(one(svg, "ellipses")["data-count"]) >= 1)
      -- standing still: the odometry is turned by the headings' difference onto the robot
      local o = one(svg, "odometry")
      assert.near(deg(0.3), tonumber(o["data-rotation"]), 0.5)
      assert.is_true(tonumber(o["data-rms"]) < 0.05, o["data-rms"])
    end)

    it("refuses an --svg that is another output or an input", function()
      setup()
      for _, target in ipairs({ dir .. "/poses.csv", dir .. "/corners.csv" }) do
        local out, status = run.script("bin/tagpose-localize", dir .. "/corners.csv", "--map",
          dir .. "/map.csv", "--cameras", dir .. "/cameras.lua", "--out", dir .. "/poses.csv",
          "--svg", target)
        assert.equal(2, status, out)
        assert.truthy(out:find("--svg", 1, true), out)
      end
    end)
  end)
end)
