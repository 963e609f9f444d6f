-- One way in, everywhere: every entry point that takes corners takes `options.order`, and its
-- "wrong winding" hint names the call made; options misspelt get a "did you mean", misuse
-- raises at the caller's line; times in milliseconds, sizes in millimetres and angles in
-- degrees are said, not taken silently; tagpose.rotation takes the nested matrices tagpose
-- returns.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")

local NAME = "same_options_spec.lua"
local camera = { fx = 700, fy = 705, cx = 330.2, cy = 236.8 }
local SIZE = 0.05
local raised = assertions.raised

-- What f writes on standard error (io.stderr replaced while it runs).
local function stderr_of(f)
  local saved, parts = io.stderr, {}
  local fake = {}
  function fake.write(self, ...)
    for i = 1, select("#", ...) do parts[#parts + 1] = tostring((select(i, ...))) end
    return self
  end
  rawset(io, "stderr", fake)
  local ok, err = pcall(f)
  rawset(io, "stderr", saved)
  if not ok then error(err, 0) end
  return table.concat(parts)
end

-- camera ← body: X_cam = r·X + t (r flat)
local function to_camera(r, t, x, y, z)
  return r[1] * x + r[2] * y + r[3] * z + t[1], r[4] * x + r[5] * y + r[6] * z + t[2],
    r[7] * x + r[8] * y + r[9] * z + t[3]
end

-- The corners of a tag at (px, py, 0) on a body (tag frame = body frame turned by nothing) in
-- OpenCV's order (top-left, top-right, bottom-right, bottom-left of the printed tag), and in
-- the detection order (c1..c4: the same reversed).
local function corners(r, t, px, py)
  local h = SIZE / 2
  local opencv = {}
  for i, c in ipairs({ { -h, -h }, { h, -h }, { h, h }, { -h, h } }) do
    local x, y, z = to_camera(r, t, px + c[1], py + c[2], 0)
    opencv[i] = { camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy }
  end
  return opencv, { opencv[4], opencv[3], opencv[2], opencv[1] }
end

local function tag(x, y)
  return { size = SIZE, position = { x = x, y = y, z = 0 },
    quaternion = { w = 1, x = 0, y = 0, z = 0 } }
end

describe("the same options everywhere", function()
  describe("options.order = 'opencv'", function()
    local rng = geometry.rng(2626)
    local r, t = geometry.random_pose(rng, camera, SIZE, { width = 90 })
    local opencv, detection = corners(r, t, 0, 0)

    it("layout.solve takes it, and its hint names layout.solve", function()
      local layout = { tags = { [3] = tag(0, 0) } }
      local body = assert(tagpose.layout.solve({ { id = 3, corners = opencv } }, camera, layout,
        { order = "opencv" }))
      local same = assert(tagpose.layout.solve({ { id = 3, corners = detection } }, camera,
        layout))
      assert.same(same.position, body.position)
      local none, why = tagpose.layout.solve({ { id = 3, corners = opencv } }, camera, layout)
      assert.is_nil(none)
      assert.truthy(why:find("wind the wrong way round", 1, true), why)
      assert.truthy(why:find("{order = 'opencv'} in tagpose.layout.solve(", 1, true), why)
    end)

    it("block.solve takes it, and its hint names block.solve", function()
      local blocks = assert(tagpose.block.solve({ { id = 0, corners = opencv } }, camera, SIZE,
        0.06, { order = "opencv" }))
      local same = assert(tagpose.block.solve({ { id = 0, corners = detection } }, camera, SIZE,
        0.06))
      assert.same(same[1].position, blocks[1].position)
      local none, why = tagpose.block.solve({ { id = 0, corners = opencv } }, camera, SIZE, 0.06)
      assert.is_nil(none)
      assert.truthy(why:find("{order = 'opencv'} in tagpose.block.solve(", 1, true), why)
    end)

    it("layout.calibrate takes it, and its failure names layout.calibrate", function()
      local layout = { tags = { [0] = tag(-0.04, 0), [1] = tag(0.04, 0) } }
      local opencv_frames, detection_frames = {}, {}
      for f = 1, 6 do
        local rf, tf = geometry.random_pose(rng, camera, 0.13, { width = 200 })
        local a0, d0 = corners(rf, tf, -0.04, 0)
        local a1, d1 = corners(rf, tf, 0.04, 0)
        opencv_frames[f] = { { id = 0, corners = a0 }, { id = 1, corners = a1 } }
        detection_frames[f] = { { id = 0, corners = d0 }, { id = 1, corners = d1 } }
      end
      local got = assert(tagpose.layout.calibrate(opencv_frames, camera, layout,
        { order = "opencv" }))
      local same = assert(tagpose.layout.calibrate(detection_frames, camera, layout))
      assert.same(same.tags, got.tags)
      local none, why = tagpose.layout.calibrate(opencv_frames, camera, layout)
      assert.is_nil(none)
      assert.truthy(why:find("{order = 'opencv'} in tagpose.layout.calibrate(", 1, true), why)
    end)

    it("the localizer takes 'apriltag' as every other entry point does", function()
      local cam = { fx = 700, fy = 705, cx = 330.2, cy = 236.8,
        mount = { position = { x = 0, y = 0, z = 0.5 },
          quaternion = { w = 0.5, x = -0.5, y = 0.5, z = -0.5 } } }
      local map = { tags = { [1] = { size = 0.1651, position = { x = 3, y = 0, z = 0.5 },
        quaternion = { w = 0.5, x = -0.5, y = 0.5, z = -0.5 } } } }
      for _, order in ipairs({ "apriltag", "detector", "opencv" }) do
        assert.is_nil((tagpose.localize({}, cam, map, { order = order })))
      end
      assert.has_error(function() tagpose.localize({}, cam, map, { order = "aruco" }) end)
    end)

    it("the tracker's hint names tracker.new, where the option goes", function()
      local tr = tagpose.tracker.new(camera, SIZE)
      local seen = tr:update({ { id = 1, corners = opencv } }, 0)
      assert.truthy(seen[1].reason:find("{order = 'opencv'} in tagpose.tracker.new(", 1, true),
        seen[1].reason)
    end)
  end)

  describe("errors", function()
    local layout = { tags = { [0] = tag(0, 0), [1] = tag(0.1, 0) } }

    it("layout.solve, read and calibrate say what a misspelt option meant, at the caller",
      function()
        assert.equal("bad argument #4 to 'solve' (options.sigmaa: unknown key (did you mean "
          .. "'sigma'?))", raised(function()
            tagpose.layout.solve({}, camera, layout, { sigmaa = 1 })
          end, NAME))
        assert.equal("bad argument #4 to 'calibrate' (options.robus: unknown key (did you mean "
          .. "'robust'?))", raised(function()
            tagpose.layout.calibrate({}, camera, layout, { robus = 1 })
          end, NAME))
        assert.equal("bad argument #2 to 'read' (options.Size: unknown key (did you mean "
          .. "'size'?))", raised(function()
            tagpose.layout.read("field.json", { Size = 0.1651 })
          end, NAME))
      end)

    it("tracker.new's options raise at the caller's line", function()
      assert.equal("bad argument #3 to 'new' (options.max_gap: non-negative number expected, "
        .. "got number -1)", raised(function()
          tagpose.tracker.new(camera, SIZE, { max_gap = -1 })
        end, NAME))
      assert.equal("bad argument #3 to 'new' (options.order: 'apriltag' or 'opencv' expected, "
        .. "got string aruco)", raised(function()
          tagpose.tracker.new(camera, SIZE, { order = "aruco" })
        end, NAME))
    end)

    it("one detection passed for the list is said in one wording by every entry point",
      function()
        local d = { id = 0, corners = { { 1, 2 }, { 3, 2 }, { 3, 0 }, { 1, 0 } } }
        local wording = "array of detections expected, got one detection {id =, corners =} "
          .. "(pass {detection})"
        assert.equal("bad argument #1 to 'solve' (" .. wording .. ")",
          raised(function() tagpose.layout.solve(d, camera, layout) end, NAME))
        assert.equal("bad argument #1 to 'solve' (" .. wording .. ")",
          raised(function() tagpose.block.solve(d, camera, SIZE, 0.06) end, NAME))
        local tr = tagpose.tracker.new(camera, SIZE)
        assert.equal("bad argument #1 to 'update' (" .. wording .. ")",
          raised(function() tr:update(d, 0) end, NAME))
        assert.matches("^bad argument #1 to 'calibrate' %(frames%[1%]: " .. wording:gsub("%p",
          "%%%0"), raised(function()
            tagpose.layout.calibrate({ d }, camera, layout)
          end, NAME))
      end)
  end)

  describe("times in milliseconds", function()
    local c = { { 100, 140 }, { 140, 140 }, { 140, 100 }, { 100, 100 } }

    it("the tracker says so on standard error, once", function()
      local tr = tagpose.tracker.new(camera, SIZE)
      local text = stderr_of(function()
        for k = 0, 8 do tr:update({ { id = 1, corners = c } }, 33 * k) end
      end)
      local _, count = text:gsub("milliseconds", "")
      assert.equal(1, count, text)
      assert.matches("^tagpose%.tracker: warning: ", text)
      -- seconds: nothing
      tr = tagpose.tracker.new(camera, SIZE)
      assert.equal("", stderr_of(function()
        for k = 0, 8 do tr:update({ { id = 1, corners = c } }, 0.033 * k) end
      end))
    end)

    it("a max_gap in milliseconds is said at tracker.new", function()
      local text = stderr_of(function() tagpose.tracker.new(camera, SIZE, { max_gap = 500 }) end)
      assert.truthy(text:find("max_gap", 1, true) and text:find("milliseconds", 1, true), text)
      assert.equal("", stderr_of(function()
        tagpose.tracker.new(camera, SIZE, { max_gap = 10 })
      end))
    end)

    it("a chain of solves with prior and time says so on the pose and standard error, once",
      function()
        local pose, warned
        local text = stderr_of(function()
          for k = 0, 8 do
            pose = assert(tagpose.solve(c, camera, SIZE, { prior = pose, time = 33 * k }))
            warned = warned or pose.warning
          end
        end)
        assert.truthy(warned and warned:find("milliseconds", 1, true), tostring(warned))
        local _, count = text:gsub("milliseconds", "")
        assert.equal(1, count, text)
        -- seconds, and a slow camera's steady 2 s: nothing
        for _, step in ipairs({ 1 / 30, 2 }) do
          pose = nil
          assert.equal("", stderr_of(function()
            for k = 0, 8 do
              pose = assert(tagpose.solve(c, camera, SIZE, { prior = pose, time = step * k }))
              assert.is_nil(pose.warning)
            end
          end))
        end
      end)
  end)

  describe("sizes in another unit than the map's", function()
    local FIELD = "spec/fixtures/field/wpilib_field.json"

    it("layout.read refuses a WPILib map's tag size in millimetres", function()
      local none, why = tagpose.layout.read(FIELD, { size = 165.1 })
      assert.is_nil(none)
      assert.truthy(why:find("millimetres", 1, true), why)
      assert.is_table(tagpose.layout.read(FIELD, { size = 0.1651 }))
      assert.is_table(tagpose.layout.read("bench/field/2024-crescendo.json", { size = 0.1651 }))
    end)

    it("layout.read refuses a layout file whose sizes are millimetres beside metres", function()
      local run = require("support.run")
      local dir = run.tmpdir()
      local head = "id,size,x,y,z,qw,qx,qy,qz\n"
      local mm = run.write(dir .. "/mm.csv", head .. "0,24,0,0,-0.0275,1,0,0,0\n"
        .. "1,24,0.0275,0,0,0.7071,0,-0.7071,0\n")
      local none, why = tagpose.layout.read(mm)
      assert.is_nil(none)
      assert.truthy(why:find("millimetres", 1, true), why)
      -- the same cube in metres, and in millimetres throughout
      assert.is_table(tagpose.layout.read(run.write(dir .. "/m.csv", head
        .. "0,0.024,0,0,-0.0275,1,0,0,0\n1,0.024,0.0275,0,0,0.7071,0,-0.7071,0\n")))
      assert.is_table(tagpose.layout.read(run.write(dir .. "/all_mm.csv", head
        .. "0,24,0,0,-27.5,1,0,0,0\n1,24,27.5,0,0,0.7071,0,-0.7071,0\n")))
    end)
  end)

  describe("tagpose.rotation", function()
    local R = tagpose.rotation
    local pose = assert(tagpose.solve({ { 100, 140 }, { 150, 141 }, { 148, 95 }, { 99, 98 } },
      camera, SIZE))

    it("takes the nested matrices tagpose returns", function()
      local flat = R.from_nested(pose.rotation)
      local w, x, y, z = R.to_quaternion(pose.rotation)
      assert.quaternion_near(pose.quaternion, { w = w, x = x, y = y, z = z }, 1e-15)
      assert.same({ R.to_rotation_vector(flat) }, { R.to_rotation_vector(pose.rotation) })
      assert.equal(0, R.angle(pose.rotation, flat))
      -- a matrix answered in the shape given
      local m = R.multiply(pose.rotation, R.transpose(pose.rotation))
      assert.is_table(m[1])
      assert.rotation_near({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, R.from_nested(m), 1e-12)
      assert.same(R.multiply(flat, R.transpose(flat)), R.from_nested(m))
      local q = pose.quaternion
      assert.same(R.from_quaternion(q.w, q.x, q.y, q.z), R.from_quaternion(q))
    end)

    it("raises bad argument for what is not a matrix or a quaternion", function()
      assert.matches("^bad argument #1 to 'to_quaternion' %(3x3 matrix expected",
        raised(function() R.to_quaternion(nil) end, NAME))
      assert.matches("^bad argument #2 to 'multiply' %(3x3 matrix expected",
        raised(function() R.multiply(pose.rotation, { 1, 2 }) end, NAME))
      assert.matches("^bad argument #1 to 'from_quaternion' %(quaternion expected",
        raised(function() R.from_quaternion(nil) end, NAME))
      assert.matches("^bad argument #2 to 'from_rotation_vector' %(finite number expected",
        raised(function() R.from_rotation_vector(0, "a", 0) end, NAME))
    end)

    it("from_rpy says once that angles beyond ±2π look like degrees", function()
      -- a fresh copy of the module: the warning is once per module
      local saved = package.loaded["tagpose.core.rpy"]
      package.loaded["tagpose.core.rpy"] = nil
      local fresh = require("tagpose.core.rpy")
      package.loaded["tagpose.core.rpy"] = saved
      local text = stderr_of(function()
        fresh.from_rpy(0, math.rad(30), 0)
        fresh.from_rpy(0, 30, 0)
        fresh.from_rpy(0, 0, 90)
      end)
      local _, count = text:gsub("degrees", "")
      assert.equal(1, count, text)
      assert.truthy(text:find("from_rpy(0, 30, 0)", 1, true), text)
    end)
  end)

  describe("tagpose.transform", function()
    it("takes a quaternion whose squares overflow as the turn it is", function()
      local p = tagpose.transform.apply({ position = { x = 0, y = 0, z = 0 },
        quaternion = { w = 1e200, x = 1e200, y = 0, z = 0 } }, { x = 0, y = 1, z = 0 })
      assert.vector_near({ 0, 0, 1 }, { p.x, p.y, p.z }, 1e-15)
      local inv = tagpose.transform.inverse({ position = { x = 0, y = 0, z = 0 },
        quaternion = { w = 3e307, x = 3e307, y = 0, z = 0 } })
      assert.quaternion_near({ w = math.sqrt(0.5), x = -math.sqrt(0.5), y = 0, z = 0 },
        inv.quaternion, 1e-15)
    end)
  end)
end)
