-- A robot localising itself on a field map: the 2024 map's data, its conversion into tagpose's
-- tag frame (checked on the corners, in the field and in the image), the code of
-- docs/layouts.md's section run on views projected from known robot poses, layout.solve on the
-- benchmark's views against their truth, and the benchmark's commands.
local tagpose = require("tagpose")
local compat = require("tagpose.core.compat")
local run = require("support.run")

local map = dofile("bench/field_map.lua")

local sqrt, sin, cos, rad, abs = math.sqrt, math.sin, math.cos, math.rad, math.abs
local atan2 = compat.atan2

local MAP = "bench/field/2024-crescendo.json"
local SIZE = 0.1651
local CAMERA = { fx = 910, fy = 910, cx = 639.5, cy = 399.5 }
local WIDTH, HEIGHT = 1280, 800

-- The published placements: centre in inches, yaw in degrees (bench/field/README.md).
local PUBLISHED = {
  { 1, 593.68, 9.68, 53.38, 120 }, { 2, 637.21, 34.79, 53.38, 120 },
  { 3, 652.73, 196.17, 57.13, 180 }, { 4, 652.73, 218.42, 57.13, 180 },
  { 5, 578.77, 323.00, 53.38, 270 }, { 6, 72.5, 323.00, 53.38, 270 },
  { 7, -1.50, 218.42, 57.13, 0 }, { 8, -1.50, 196.17, 57.13, 0 },
  { 9, 14.02, 34.79, 53.38, 60 }, { 10, 57.54, 9.68, 53.38, 60 },
  { 11, 468.69, 146.19, 52.00, 300 }, { 12, 468.69, 177.10, 52.00, 60 },
  { 13, 441.74, 161.62, 52.00, 180 }, { 14, 209.48, 161.62, 52.00, 0 },
  { 15, 182.73, 177.10, 52.00, 120 }, { 16, 182.73, 146.19, 52.00, 240 },
}

local function cross(a, b)
  return { a[2] * b[3] - a[3] * b[2], a[3] * b[1] - a[1] * b[3], a[1] * b[2] - a[2] * b[1] }
end

local function unit(a)
  local n = sqrt(a[1] ^ 2 + a[2] ^ 2 + a[3] ^ 2)
  return { a[1] / n, a[2] / n, a[3] / n }
end

-- A camera at c in the field looking along `ahead`, upright: its axes (x right, y down,
-- z forward) in the field.
local function look(ahead, roll)
  local z = unit(ahead)
  local x0 = unit(cross(z, { 0, 0, 1 }))
  local y0 = cross(z, x0)
  local cr, sr = cos(roll or 0), sin(roll or 0)
  local x, y = {}, {}
  for i = 1, 3 do
    x[i], y[i] = cr * x0[i] + sr * y0[i], -sr * x0[i] + cr * y0[i]
  end
  return x, y, z
end

-- The pixel of a field point seen by a camera (default CAMERA) at c with axes x, y, z (field
-- frame); nil behind it.
local function project(p, c, x, y, z, camera)
  camera = camera or CAMERA
  local d = { p[1] - c[1], p[2] - c[2], p[3] - c[3] }
  local X, Y, Z = x[1] * d[1] + x[2] * d[2] + x[3] * d[3], y[1] * d[1] + y[2] * d[2] + y[3] * d[3],
    z[1] * d[1] + z[2] * d[2] + z[3] * d[3]
  if Z <= 0 then return nil end
  return camera.fx * X / Z + camera.cx, camera.fy * Y / Z + camera.cy
end

-- Exact detections of every tag the camera sees (facing it, in the image).
local function view(field, c, x, y, z)
  local dets = {}
  for _, id in ipairs(field.ids) do
    local t = field.tags[id]
    local nx, ny, nz = map.normal(t)
    if (c[1] - t.x) * nx + (c[2] - t.y) * ny + (c[3] - t.z) * nz > 0 then
      local corners = {}
      for k, p in ipairs(map.corners(t, SIZE)) do
        local u, v = project(p, c, x, y, z)
        if u and u > 0 and v > 0 and u < WIDTH - 1 and v < HEIGHT - 1 then corners[k] = { u, v } end
      end
      if corners[1] and corners[2] and corners[3] and corners[4] then
        dets[#dets + 1] = { id = id, corners = corners }
      end
    end
  end
  return dets
end

-- The robot's pose (x, y, heading) and the camera docs/layouts.md mounts on it (0.3 m ahead,
-- 0.5 m up, pitched up 15°): the camera's centre and axes in the field.
local function robot_camera(rx, ry, heading)
  local f, l = { cos(heading), sin(heading), 0 }, { -sin(heading), cos(heading), 0 }
  local c = { rx + 0.3 * f[1], ry + 0.3 * f[2], 0.5 }
  local p = rad(15)
  local ahead = { cos(p) * f[1], cos(p) * f[2], sin(p) }
  local right = { -l[1], -l[2], 0 }
  return c, right, cross(ahead, right), ahead
end

-- The lua blocks of docs/layouts.md's section on field maps, as one chunk returning its locals.
local function doc_chunk()
  local text = run.read("docs/layouts.md")
  local section = assert(text:match("\n## A robot localising itself on a field map\n(.-)\n## "))
  local code = {}
  for block in section:gmatch("```lua\n(.-)```") do code[#code + 1] = block end
  assert.equal(3, #code)
  return table.concat(code, "\n") .. "\nreturn on_field, robot, body\n"
end

local function run_doc(dets, field_layout)
  local printed = {}
  local env = setmetatable({ detections = dets, camera = CAMERA, field = field_layout,
    print = function(s) printed[#printed + 1] = s end }, { __index = _G })
  local chunk = assert(compat.load_text(doc_chunk(), "=docs/layouts.md", env))
  local on_field, robot, body = chunk()
  return on_field, robot, body, printed
end

describe("a robot on a field map", function()
  local field = map.read(MAP)
  local layout = map.layout(field, SIZE)

  it("has the 2024 field's published tag placements", function()
    assert.same({ 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16 }, field.ids)
    for _, p in ipairs(PUBLISHED) do
      local t = field.tags[p[1]]
      assert.near(p[2] * 0.0254, t.x, 1e-9)
      assert.near(p[3] * 0.0254, t.y, 1e-9)
      assert.near(p[4] * 0.0254, t.z, 1e-9)
      local nx, ny, nz = map.normal(t)
      assert.near(cos(rad(p[5])), nx, 1e-12)
      assert.near(sin(rad(p[5])), ny, 1e-12)
      assert.near(0, nz, 1e-12)
    end
    assert.same({ 16.451, 8.211 }, { field.length, field.width })
  end)

  it("places the converted tags' corners where WPILib's frame puts them", function()
    for _, id in ipairs(field.ids) do
      local e = layout.tags[id]
      local q = e.quaternion
      local w, x, y, z = q.w, q.x, q.y, q.z
      -- tagpose's corners c1..c4 at (∓s/2, ±s/2, 0) in its tag frame, by the quaternion
      local r = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * y + w * z),
        1 - 2 * (x * x + z * z), 2 * (x * z - w * y), 2 * (y * z + w * x) }
      local h = SIZE / 2
      local expected = map.corners(field.tags[id], SIZE)
      for k, c in ipairs({ { -h, h }, { h, h }, { h, -h }, { -h, -h } }) do
        local got = { r[1] * c[1] + r[2] * c[2] + e.position.x,
          r[3] * c[1] + r[4] * c[2] + e.position.y, r[5] * c[1] + r[6] * c[2] + e.position.z }
        assert.vector_near(expected[k], got, 1e-12, "tag " .. id .. ", corner " .. k)
      end
    end
  end)

  it("has c1..c4 bottom-left, bottom-right, top-right, top-left in an upright camera", function()
    for _, id in ipairs(field.ids) do
      local t = field.tags[id]
      local nx, ny = map.normal(t)
      local c = { t.x + 2 * nx + 0.3 * ny, t.y + 2 * ny - 0.3 * nx, t.z - 0.4 }
      local x, y, z = look({ t.x - c[1], t.y - c[2], t.z - c[3] })
      local px = {}
      for k, p in ipairs(map.corners(t, SIZE)) do px[k] = { project(p, c, x, y, z) } end
      local msg = "tag " .. id
      assert.is_true(px[1][1] < px[2][1] and px[4][1] < px[3][1], msg) -- left of
      assert.is_true(px[1][2] > px[4][2] and px[2][2] > px[3][2], msg) -- below
      -- and tagpose solves each alone to that camera
      local pose = assert(tagpose.solve(px, CAMERA, SIZE))
      local e = layout.tags[id].position
      local d = { e.x - c[1], e.y - c[2], e.z - c[3] }
      assert.vector_near({ x[1] * d[1] + x[2] * d[2] + x[3] * d[3],
        y[1] * d[1] + y[2] * d[2] + y[3] * d[3], z[1] * d[1] + z[2] * d[2] + z[3] * d[3] },
        pose.position, 1e-9, msg)
    end
  end)

  describe("docs/layouts.md", function()
    it("puts the camera and the robot where they are (tags on several planes)", function()
      local rx, ry, heading = 8.0, 4.3, rad(-5)
      local c, x, y, z = robot_camera(rx, ry, heading)
      local dets = view(field, c, x, y, z)
      assert.is_true(#dets >= 3, #dets .. " tags seen")
      local on_field, robot, body, printed = run_doc(dets, layout)
      assert.is_nil(body.alternative)
      assert.vector_near(c, on_field.position, 1e-9)
      assert.vector_near({ x[1], x[2], x[3] }, { on_field.rotation[1][1],
        on_field.rotation[2][1], on_field.rotation[3][1] }, 1e-9)
      assert.vector_near({ rx, ry, 0 }, robot.position, 1e-9)
      assert.vector_near({ cos(heading), sin(heading), 0 }, { robot.rotation[1][1],
        robot.rotation[2][1], robot.rotation[3][1] }, 1e-9)
      assert.same({ ("camera at x %.2f, y %.2f, z %.2f m"):format(c[1], c[2], c[3]),
        ("robot at x %.2f, y %.2f, heading %.1f deg"):format(rx, ry, math.deg(heading)) },
        printed)
    end)

    it("reports both branches of a speaker's two tags seen from afar", function()
      local found = 0
      for k = 0, 9 do
        -- 5-7 m from the blue speaker (tags 7 and 8), looking at it from the side
        local rx, ry = 5 + 0.2 * k, 2.2 + 0.1 * k
        local c, x, y, z = robot_camera(rx, ry, atan2(5.27 - ry, -rx))
        -- (the amp's tag and the stage's are in view too: only the speaker's are detected)
        local dets = {}
        for _, d in ipairs(view(field, c, x, y, z)) do
          if d.id == 7 or d.id == 8 then dets[#dets + 1] = d end
        end
        if #dets == 2 then
          local on_field, robot, body, printed = run_doc(dets, layout)
          local alt = body.alternative
          if alt then
            found = found + 1
            assert.near(1, body.confidence + alt.confidence, 1e-12)
            assert.equal(3, #printed)
            -- exact corners: the body is the truth to round-off
            assert.vector_near(c, on_field.position, 1e-6)
            assert.vector_near({ rx, ry, 0 }, robot.position, 1e-6)
            local other = require("tagpose.transform").inverse(alt)
            assert.is_true(sqrt((other.position.x - c[1]) ^ 2 + (other.position.y - c[2]) ^ 2)
              > 0.05, "the alternative is elsewhere")
          end
        end
      end
      assert.is_true(found >= 5, found .. " views with two branches")
    end)
  end)

  describe("bench/field", function()
    local dir = os.tmpname()
    os.remove(dir)

    it("bench/field.sh draws views-1 from seed 1 and prints docs/layouts.md's figures",
      function()
        local text, status = run.run("LUA=" .. run.quote(run.lua()) .. " bench/field.sh "
          .. run.quote(dir) .. " 1 2>&1")
        -- the views, the same on every Lua
        for _, name in ipairs({ "camera.lua", "corners.csv", "truth.csv", "meta.json" }) do
          local committed = run.read("bench/field/views-1/" .. name)
          local made = run.read(dir .. "/" .. name)
          -- (camera.lua's first line names the directory)
          if name == "camera.lua" then
            committed, made = committed:gsub("^[^\n]*\n", ""), made:gsub("^[^\n]*\n", "")
          end
          assert.equal(committed, made, name)
        end
        local doc = run.read("docs/layouts.md")
        local tp, cv = doc:match("\n| seed 1 | [^|]+ | ([^|]-) | ([^|]-) |")
        assert.is_string(tp)
        local median, p95, far = text:match("\ntagpose [^\n]* median ([%d.]+) m, p95 ([%d.]+) "
          .. "m, (%d+) views")
        assert.equal(tp, ("%s m / %.2f m / %s"):format(median, tonumber(p95), far), text)
        run.run("rm -r " .. run.quote(dir))
        if status ~= 0 and text:find("No module named", 1, true) then
          pending("no OpenCV under /usr/bin/python3: OpenCV's side not run")
          return
        end
        assert.equal(0, status, text)
        median, p95, far = text:match("all views  OpenCV SQPNP%+LM%s+%d+/%d+ solved  median "
          .. "([%d.]+) m  p95 ([%d.]+) m  > 0.5 m:%s+(%d+)")
        assert.equal(cv, ("%s m / %.2f m / %s"):format(median, tonumber(p95), far), text)
      end)

    it("layout.solve fits every view of views-1 at least as well as the truth", function()
      local truth, frames, order = {}, {}, {}
      for line in io.lines("bench/field/views-1/truth.csv") do
        local v = {}
        for s in line:gmatch("[^,]+") do v[#v + 1] = tonumber(s) end
        if v[1] then truth[v[1]] = v end
      end
      for line in io.lines("bench/field/views-1/corners.csv") do
        local v = {}
        for s in line:gmatch("[^,]+") do v[#v + 1] = tonumber(s) end
        if v[1] then
          if not frames[v[1]] then
            frames[v[1]] = {}
            order[#order + 1] = v[1]
          end
          local d = frames[v[1]]
          d[#d + 1] = { id = v[2], corners = { { v[3], v[4] }, { v[5], v[6] }, { v[7], v[8] },
            { v[9], v[10] } } }
        end
      end
      local camera = assert(tagpose.calibration.read("bench/field/views-1/camera.lua"))
      local several = 0
      for _, f in ipairs(order) do
        local dets, t = frames[f], truth[f]
        local body = assert(tagpose.layout.solve(dets, camera, layout))
        local msg = "frame " .. f
        assert.equal(#dets, #body.tags, msg)
        -- the squared error at the truth (camera → field: c = (x, y, z), R of the quaternion)
        local R = map.matrix(t[6], t[7], t[8], t[9])
        local sse = 0
        for _, d in ipairs(dets) do
          for k, p in ipairs(map.corners(field.tags[d.id], SIZE)) do
            local u, v = project(p, { t[3], t[4], t[5] }, { R[1], R[4], R[7] },
              { R[2], R[5], R[8] }, { R[3], R[6], R[9] }, camera)
            sse = sse + (u - d.corners[k][1]) ^ 2 + (v - d.corners[k][2]) ^ 2
          end
        end
        assert.is_true(body.error ^ 2 * 4 * #dets <= sse + 1e-9, msg)
        if #dets == 1 then
          assert.is_table(body.alternative, msg)
          assert.near(1, body.confidence + body.alternative.confidence, 1e-12)
        end
        local first = field.tags[dets[1].id]
        local nx, ny = map.normal(first)
        for i = 2, #dets do
          local ox, oy = map.normal(field.tags[dets[i].id])
          if abs(nx * ox + ny * oy - 1) > 1e-9 then
            several = several + 1
            assert.is_nil(body.alternative, msg)
            break
          end
        end
      end
      assert.is_true(several > 100)
    end)
  end)
end)
