-- The plot shows what the pose log has: a band of ±2 standard deviations around each value
-- from the pose's covariance, the confidence in a strip, and the time along the horizontal
-- axis when the corner log has a time column. Each is read back from the SVG's geometry (the
-- pixels of a band against the pixels of the axis' ticks) and compared with what the poses
-- say: the position's deviations as given, the rotation's carried to the quaternion and to
-- roll, pitch and yaw by finite differences of turned rotations, written out here.
local plot = require("tagpose.tools.plot")
local geometry = require("support.geometry")
local run = require("support.run")

local sqrt, sin, cos, asin = math.sqrt, math.sin, math.cos, math.asin
local atan2 = require("tagpose.core.compat").atan2

local function tmp(name)
  local base = os.tmpname()
  os.remove(base)
  return base .. "-" .. name
end

-- the vertical axis of a panel: the pixel of a value (from its first and last y ticks)
local function y_axis(text)
  local values, pixels = {}, {}
  for v in text:gmatch('text%-anchor="end">([^<]*)</text>') do values[#values + 1] = tonumber(v) end
  for y1, y2 in text:gmatch('<line class="grid" x1="[^"]*" y1="([^"]*)" x2="[^"]*" y2="([^"]*)"') do
    if y1 == y2 then pixels[#pixels + 1] = tonumber(y1) end
  end
  assert.is_true(#values >= 3 and #pixels == #values, text:sub(1, 300))
  local scale = (pixels[#values] - pixels[1]) / (values[#values] - values[1])
  return function(v) return pixels[1] + (v - values[1]) * scale end, -scale
end

-- the horizontal axis of a panel: the value at a pixel (from its first and last x ticks)
local function x_axis(text)
  local values, pixels = {}, {}
  for v in text:gmatch('text%-anchor="middle">([^<]*)</text>') do
    values[#values + 1] = tonumber(v)
  end
  for x1, x2 in text:gmatch('<line class="grid" x1="([^"]*)" y1="[^"]*" x2="([^"]*)"') do
    if x1 == x2 then pixels[#pixels + 1] = tonumber(x1) end
  end
  assert.is_true(#values >= 3 and #pixels == #values)
  local per = (values[#values] - values[1]) / (pixels[#values] - pixels[1])
  return function(px) return values[1] + (px - pixels[1]) * per end, 1 / per
end

-- the points of the band polygons of a source in a panel: each {x, high px, low px}
local function band_points(text, source)
  local group = text:match('<g class="band" data%-tag="[^"]*" data%-source="' .. source
    .. '"[^>]*>(.-)</g>')
  assert.truthy(group, "a band of " .. source)
  local out = {}
  for pts in group:gmatch('<polygon points="([^"]*)"') do
    local xy = {}
    for x, y in pts:gmatch("([-%d.]+),([-%d.]+)") do xy[#xy + 1] = { tonumber(x), tonumber(y) } end
    local n = #xy / 2
    for k = 1, n do out[#out + 1] = { xy[k][1], xy[k][2], xy[2 * n + 1 - k][2] } end
  end
  return out
end

-- q turned by the rotation vector r on the left (camera frame): exp(r) q
local function turned(q, r)
  local a = sqrt(r[1] ^ 2 + r[2] ^ 2 + r[3] ^ 2)
  local s = a > 0 and sin(a / 2) / a or 0.5
  return geometry.qmul({ cos(a / 2), s * r[1], s * r[2], s * r[3] }, q)
end

-- roll, pitch, yaw (degrees) of R = Rz(yaw) Ry(pitch) Rx(roll), from the matrix of q
local function rpy(q)
  local w, x, y, z = q[1], q[2], q[3], q[4]
  local r31 = 2 * (x * z - w * y)
  local r32, r33 = 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
  local r21, r11 = 2 * (x * y + w * z), 1 - 2 * (y * y + z * z)
  return { math.deg(atan2(r32, r33)), math.deg(asin(-r31)), math.deg(atan2(r21, r11)) }
end

-- the deviations of f(q) for rotation deviations d, the three taken as independent: the
-- derivatives by central differences
local function carried(f, q, d)
  local h = 1e-6
  local var = {}
  for j = 1, 3 do
    local r = { 0, 0, 0 }
    r[j] = h
    local up = f(turned(q, r))
    r[j] = -h
    local down = f(turned(q, r))
    for i = 1, #up do var[i] = (var[i] or 0) + ((up[i] - down[i]) / (2 * h) * d[j]) ^ 2 end
  end
  for i = 1, #var do var[i] = sqrt(var[i]) end
  return var
end

-- a pose turning slowly, with a covariance whose diagonal is d (and one correlation, which
-- the bands do not read: the log has the deviations only)
local function pose_at(k, d)
  local a, b = 0.3 + 0.01 * k, -0.4
  local q = geometry.qmul({ cos(a / 2), 0, sin(a / 2), 0 }, { cos(b / 2), sin(b / 2), 0, 0 })
  local cov = {}
  for i = 1, 6 do
    cov[i] = { 0, 0, 0, 0, 0, 0 }
    cov[i][i] = d[i] * d[i]
  end
  cov[1][3], cov[3][1] = 0.5 * d[1] * d[3], 0.5 * d[1] * d[3]
  return { position = { x = 0.01 * k, y = 0.02 * sin(k / 3), z = 1 + 0.005 * k },
    quaternion = { w = q[1], x = q[2], y = q[3], z = q[4] }, covariance = cov,
    confidence = 0.5 + 0.02 * k }, q
end

local D = { 0.004, 0.003, 0.02, 0.05, 0.03, 0.04 }
local N = 12

-- the figure of N poses of one tag
local function draw_poses(rotation)
  local rec = plot.recorder({ rotation = rotation })
  local src = rec:source("poses")
  local qs = {}
  for k = 1, N do
    local pose
    pose, qs[k] = pose_at(k, D)
    rec:add(src, 7, 1, k, pose)
  end
  local svg, shown = plot.draw(rec)
  local ok, complaint = run.xmllint(svg)
  assert.is_true(ok, complaint)
  return svg, shown, qs
end

-- each band point of a panel against the value and deviation expected at its frame
local function check_band(svg, name, expected)
  local text = run.panel(svg, name)
  local y_of, per_unit = y_axis(text)
  local frame_of = x_axis(text)
  local points = band_points(text, "poses")
  assert.equal(N, #points, name)
  for _, p in ipairs(points) do
    local k = math.floor(frame_of(p[1]) + 0.5)
    local value, sigma = expected(k)
    local tol = 0.06 + 0.002 * 4 * sigma * per_unit
    -- the band's half height is 2 sigma; its middle the value
    assert.near(2 * sigma * per_unit, (p[3] - p[2]) / 2, tol, name .. " at frame " .. k)
    assert.near(y_of(value), (p[2] + p[3]) / 2, tol, name .. " at frame " .. k)
  end
end

describe("tagpose.tools.plot", function()
  describe("draw()", function()
    it("draws a band of ±2σ around each position value, from the covariance", function()
      local svg = draw_poses()
      local values = {
        x = function(k) return 0.01 * k end,
        y = function(k) return 0.02 * sin(k / 3) end,
        z = function(k) return 1 + 0.005 * k end,
      }
      for i, name in ipairs({ "x", "y", "z" }) do
        check_band(svg, name, function(k) return values[name](k), D[i] end)
      end
    end)

    it("carries the rotation's deviations to the quaternion's components", function()
      local svg, _, qs = draw_poses()
      local d = { D[4], D[5], D[6] }
      for i, name in ipairs({ "qw", "qx", "qy", "qz" }) do
        check_band(svg, name, function(k)
          return qs[k][i], carried(function(q) return q end, qs[k], d)[i]
        end)
      end
    end)

    it("carries the rotation's deviations to roll, pitch and yaw", function()
      local svg, _, qs = draw_poses("rpy")
      local d = { D[4], D[5], D[6] }
      for i, name in ipairs({ "roll", "pitch", "yaw" }) do
        check_band(svg, name, function(k) return rpy(qs[k])[i], carried(rpy, qs[k], d)[i] end)
      end
    end)

    it("keeps a long series' band as its extremes over buckets, a wide one included", function()
      local rec = plot.recorder({ max_points = 64 })
      local src = rec:source("long")
      for k = 1, 400 do
        local d = { k == 234 and 0.5 or 0.01, 0.01, 0.01, 0.01, 0.01, 0.01 }
        local pose = pose_at(0, d)
        pose.position.x = 0.1 * sin(k / 10)
        rec:add(src, 1, 1, k, pose)
      end
      local svg = plot.draw(rec)
      local text = run.panel(svg, "x")
      local y_of = y_axis(text)
      local top, bottom = math.huge, -math.huge
      local points = band_points(text, "long")
      assert.is_true(#points <= 64, #points .. " points")
      for _, p in ipairs(points) do
        top, bottom = math.min(top, p[2]), math.max(bottom, p[3])
      end
      -- both reaches are the wide deviation's, ±1 around its frame's value, far past the
      -- others' (±0.02 around values within ±0.1); the lines set the panel's range
      assert.near(y_of(0.1 * sin(23.4) + 1), top, 0.5)
      assert.near(y_of(0.1 * sin(23.4) - 1), bottom, 0.5)
      local y0, y1 = y_of(0.1), y_of(-0.1)
      local inside = 0
      for _, p in ipairs(points) do
        if p[2] > y0 - 20 and p[3] < y1 + 20 then inside = inside + 1 end
      end
      assert.is_true(inside >= #points - 2, inside .. " of " .. #points)
    end)

    it("draws the confidence in a strip under the position, only when a pose has one", function()
      local svg, shown = draw_poses()
      assert.equal(8, shown.panels)
      local text = run.panel(svg, "confidence")
      assert.truthy(text:find(('height="%.1f"'):format(plot.STRIP_HEIGHT), 1, true))
      local y_of = y_axis(text)
      local frame_of = x_axis(text)
      local pts = text:match('<polyline points="([^"]*)"')
      local n = 0
      for x, y in pts:gmatch("([-%d.]+),([-%d.]+)") do
        n = n + 1
        local k = math.floor(frame_of(tonumber(x)) + 0.5)
        assert.near(y_of(0.5 + 0.02 * k), tonumber(y), 0.1)
      end
      assert.equal(N, n)
      -- a pose without confidence nor covariance: no strip, no band
      local rec = plot.recorder()
      local src = rec:source("bare")
      for k = 1, 3 do rec:add(src, 1, 1, k, { position = { x = k, y = 0, z = 1 },
        quaternion = { w = 1, x = 0, y = 0, z = 0 } }) end
      local bare, bare_shown = plot.draw(rec)
      assert.equal(7, bare_shown.panels)
      assert.is_nil(bare:find('class="band"', 1, true))
    end)

    it("draws over time with options.x = 'time', the lines broken at gaps in the frames",
      function()
        local rec = plot.recorder({ x = "time" })
        local src = rec:source("timed")
        -- frames 1..6 and 8..10 (7 missing), at uneven times
        local times = {}
        for k = 1, 10 do
          times[k] = 1700000000 + 0.1 * k + (k % 2 == 0 and 0.03 or 0)
          if k ~= 7 then
            rec:add(src, 1, 1, k, pose_at(k, D), nil, times[k])
          end
        end
        local svg = plot.draw(rec)
        assert.truthy(svg:find(">time %(s%) from 1700000000<"))
        local text = run.panel(svg, "x")
        local t_of = x_axis(text)
        local runs = {}
        for pts in text:gmatch('<polyline points="([^"]*)"') do
          local xs = {}
          for x in pts:gmatch("([-%d.]+),") do xs[#xs + 1] = 1700000000 + t_of(tonumber(x)) end
          runs[#runs + 1] = xs
        end
        -- two runs: before and after the missing frame (the steps in time are uneven)
        assert.equal(2, #runs)
        assert.equal(6, #runs[1])
        assert.equal(3, #runs[2])
        for k, t in ipairs(runs[1]) do assert.near(times[k], t, 0.002) end
        for k, t in ipairs(runs[2]) do assert.near(times[k + 7], t, 0.002) end
        assert.has_error(function() plot.recorder({ x = "seconds" }) end,
          "bad argument #1 to 'recorder' (options.x: 'frame' or 'time' expected, got string"
            .. " seconds)")
      end)
  end)
end)

describe("bin/tagpose-replay --svg", function()
  it("draws over the time column when the log has one, compared rows at their frames' times",
    function()
      -- the bundled approach's first 20 frames, every other frame, at uneven times
      local function time_of(frame) return 5 + 0.05 * frame + (frame % 4 == 2 and 0.01 or 0) end
      local lines = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,margin,time" }
      for line in run.read("examples/data/approach.csv"):gmatch("[^\n]+") do
        local frame = tonumber(line:match("^(%d+),"))
        if frame and frame < 20 and frame % 2 == 0 then
          lines[#lines + 1] = line .. "," .. ("%.17g"):format(time_of(frame))
        end
      end
      local log, svg = run.write(tmp("timed.csv"), table.concat(lines, "\n") .. "\n"),
        tmp("timed.svg")
      local truth = {}
      for line in run.read("examples/data/approach_truth.csv"):gmatch("[^\n]+") do
        local frame = tonumber(line:match("^(%d+),"))
        if not frame or frame < 20 then truth[#truth + 1] = line end
      end
      local truth_path = run.write(tmp("truth.csv"), table.concat(truth, "\n") .. "\n")
      local text, status = run.script("bin/tagpose-replay", log, "--camera",
        "examples/data/camera.lua", "--svg", svg, "--compare", truth_path)
      local figure = run.read(svg)
      os.remove(log)
      os.remove(svg)
      os.remove(truth_path)
      assert.equal(0, status, text)
      assert.is_true(run.xmllint(figure))
      assert.truthy(figure:find('class="axis%-label"[^>]*>time %(s%)<'))
      -- tag 1's truth, every frame 0..19: at its frame's time, odd frames between their
      -- neighbours' times (frame 19, after the log's last, from frames 16 and 18)
      local x = run.panel(figure, "x")
      local t_of = x_axis(x)
      local group = x:match('<g class="series" data%-tag="1" data%-source="[^"]*truth"'
        .. '[^>]*>(.-)</g>')
      local ts = {}
      for pts in group:gmatch('<polyline points="([^"]*)"') do
        for px in pts:gmatch("([-%d.]+),") do ts[#ts + 1] = t_of(tonumber(px)) end
      end
      assert.equal(20, #ts)
      for frame = 0, 19 do
        local want = time_of(frame)
        if frame % 2 == 1 then
          local a = frame < 19 and frame - 1 or 16
          local b = a + 2
          want = time_of(a) + (frame - a) * (time_of(b) - time_of(a)) / (b - a)
        end
        assert.near(want, ts[frame + 1], 0.0005, "frame " .. frame)
      end
      -- and without a time column, the frames
      lines = {}
      for line in run.read("examples/data/approach.csv"):gmatch("[^\n]+") do
        local frame = tonumber(line:match("^(%d+),"))
        if not frame or frame < 4 then lines[#lines + 1] = line end
      end
      log = run.write(tmp("frames.csv"), table.concat(lines, "\n") .. "\n")
      text, status = run.script("bin/tagpose-replay", log, "--camera",
        "examples/data/camera.lua", "--svg", svg)
      figure = run.read(svg)
      os.remove(log)
      os.remove(svg)
      assert.equal(0, status, text)
      assert.truthy(figure:find('class="axis%-label"[^>]*>frame<'))
    end)
end)
