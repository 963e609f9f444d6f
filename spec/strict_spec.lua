-- Nothing silently wrong: the mistakes users make are refused with a message that names them,
-- and inputs that would give a confident wrong answer give none.
local tagpose = require("tagpose")
local assertions = require("support.assertions")
local geometry = require("support.geometry")
local run = require("support.run")
local crowds = require("support.crowds")

local camera = { fx = 700, fy = 700, cx = 639.5, cy = 359.5 }
local corners = { { 600, 400 }, { 680, 400 }, { 680, 320 }, { 600, 320 } }

local function raised(f)
  return assertions.raised(f, "strict_spec.lua")
end

local function with(extra)
  local c = { fx = 700, fy = 700, cx = 639.5, cy = 359.5 }
  for k, v in pairs(extra) do c[k] = v end
  return c
end

describe("strict inputs", function()
  describe("the lens coefficients", function()
    it("take OpenCV's distCoeffs array as the named coefficients", function()
      local named = assert(tagpose.solve(corners, with({ distortion = { k1 = -0.28, k2 = 0.07,
        p1 = 5e-4, p2 = -3e-4, k3 = 0 } }), 0.024))
      local array = assert(tagpose.solve(corners, with({ distortion = { -0.28, 0.07, 5e-4,
        -3e-4, 0 } }), 0.024))
      local pinhole = assert(tagpose.solve(corners, camera, 0.024))
      assert.equal(named.position.z, array.position.z)
      assert.equal(named.error, array.error)
      -- and the lens makes a difference here (0.3 mm at this corner of the image)
      assert.is_true(math.abs(array.position.z - pinhole.position.z) > 1e-4)
      -- 8 (rational) and 4 as well; fisheye 4
      assert(tagpose.solve(corners, with({ distortion = { -0.28, 0.07, 0, 0, 0, 0.1, 0, 0 } }),
        0.024))
      assert(tagpose.solve(corners, with({ distortion = { -0.28, 0.07, 0, 0 } }), 0.024))
      assert(tagpose.solve(corners, with({ model = "fisheye", distortion = { 0.1, 0, 0, 0 } }),
        0.024))
    end)

    it("refuse other lengths, mixed tables and unknown names, naming the likely key", function()
      for _, case in ipairs({
        { { distortion = { 0.1, 0.2, 0.3 } }, "4, 5 or 8 coefficients" },
        { { distortion = { 0.1, 0.2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0 } }, "thin-prism" },
        { { model = "fisheye", distortion = { 0.1, 0.2, 0, 0, 0 } }, "4 fisheye coefficients" },
        { { distortion = { 0.1, 0.2, 0, 0, k3 = 0 } }, "not both" },
        { { distortion = { K1 = 0.1 } }, "camera.distortion.K1: unknown key (did you mean 'k1'?)" },
        { { distortion = { kl = 0.1 } }, "camera.distortion.kl: unknown key (did you mean 'k1'?)" },
        { { model = "fisheye", distortion = { p1 = 0.1 } }, "the fisheye model has no p1" },
        { { k1 = -0.28 }, "camera.k1: unknown key (did you mean camera.distortion.k1?)" },
        { { D = { 0.1, 0, 0, 0 } }, "camera.D: unknown key (did you mean camera.distortion" },
        { { fX = 700 }, "camera.fX: unknown key (did you mean 'fx'?)" },
        { { distortion = { k1 = 0 / 0 } }, "camera.distortion.k1: finite number expected" },
      }) do
        local message = raised(function() tagpose.solve(corners, with(case[1]), 0.024) end)
        assert.truthy(message:find("bad argument #2 to 'solve' (", 1, true), message)
        assert.truthy(message:find(case[2], 1, true), message)
      end
    end)

    it("keep the fields a camera file carries", function()
      assert(tagpose.solve(corners, with({ width = 1280, height = 720, tag_size = 0.024,
        block_size = 0.055, name = "front" }), 0.024))
      local message = raised(function() tagpose.solve(corners, with({ width = -1 }), 0.024) end)
      assert.truthy(message:find("camera.width: positive number expected", 1, true), message)
    end)

    it("give a fisheye without coefficients the fisheye's map, as with {} or zeros", function()
      local none = assert(tagpose.solve(corners, with({ model = "fisheye" }), 0.024))
      local empty = assert(tagpose.solve(corners, with({ model = "fisheye", distortion = {} }),
        0.024))
      local zeros = assert(tagpose.solve(corners, with({ model = "fisheye", distortion = { k1 = 0,
        k2 = 0, k3 = 0, k4 = 0 } }), 0.024))
      assert.equal(empty.position.z, none.position.z)
      assert.equal(zeros.position.z, none.position.z)
    end)
  end)

  describe("a lens folded past its inverse", function()
    it("is refused, not answered (both models)", function()
      for _, cam in ipairs({ with({ distortion = { k1 = -1e10 } }),
        with({ model = "fisheye", distortion = { k1 = -1e10 } }) }) do
        local pose, err = tagpose.solve(corners, cam, 0.024)
        assert.is_nil(pose)
        assert.truthy(err:find("one-to-one", 1, true), err)
      end
    end)

    it("is refused where radial and tangential terms fold it together", function()
      -- the radial part alone stays one-to-one (its slope dips to 0.06 near r = 1.2), the
      -- tangential terms fold it: det J < 0 at 0.7 of the way to this point
      local cam = with({ distortion = { k1 = 0.068982960222747, k2 = -0.30169376814817,
        p1 = 0.017313549349696, p2 = -0.011176079656545, k3 = 0.090730311158453 } })
      local x, err = tagpose.camera.undistort(cam, 1.417989377127, 0.14746137389329)
      assert.is_nil(x)
      assert.truthy(err:find("one-to-one", 1, true), err)
      -- closer in it answers, to round-off
      local xd, yd = geometry.distort(cam, 0.5, 0.05)
      local ux, uy = assert(tagpose.camera.undistort(cam, xd, yd))
      assert.near(0.5, ux, 1e-12)
      assert.near(0.05, uy, 1e-12)
    end)
  end)

  describe("options", function()
    it("refuse unknown keys of solve's options, naming the likely one", function()
      for _, case in ipairs({
        { { methd = "seed" }, "options.methd: unknown key (did you mean 'method'?)" },
        { { prior_pose = {} }, "options.prior_pose: unknown key (did you mean 'prior'?)" },
        { { Into = {} }, "options.Into: unknown key (did you mean 'into'?)" },
        { { [1] = "seed" }, "options: unknown key [1]" },
      }) do
        local message = raised(function() tagpose.solve(corners, camera, 0.024, case[1]) end)
        assert.equal("bad argument #4 to 'solve' (" .. case[2],
          message:sub(1, #("bad argument #4 to 'solve' (" .. case[2])))
      end
    end)

    it("refuse unknown keys of block.solve's options", function()
      local message = raised(function()
        tagpose.block.solve({ { id = 0, corners = corners } }, camera, 0.024, 0.055,
          { upp = { 0, -1, 0 } })
      end)
      assert.truthy(message:find("bad argument #5 to 'solve' (options.upp: unknown key "
        .. "(did you mean 'up'?))", 1, true), message)
    end)
  end)

  describe("sizes and arrays", function()
    it("refuse a block size in another unit than the tag size, naming both", function()
      local message = raised(function()
        tagpose.block.solve({ { id = 0, corners = corners } }, camera, 0.024, 55)
      end)
      assert.truthy(message:find("bad argument #4 to 'solve' (block_size 55 is 2292 times "
        .. "tag_size 0.024", 1, true), message)
    end)

    it("refuse one detection passed without its array", function()
      local message = raised(function()
        tagpose.block.solve({ id = 3, corners = corners }, camera, 0.024, 0.055)
      end)
      assert.truthy(message:find("bad argument #1 to 'solve' (array of detections expected, "
        .. "got one detection", 1, true), message)
    end)

    it("say what is wrong with an absurd focal length or tag size", function()
      local message = raised(function() tagpose.solve(corners, with({ fx = 1e308 }), 0.024) end)
      assert.truthy(message:find("camera.fx: a focal length in pixels", 1, true), message)
      message = raised(function() tagpose.solve(corners, camera, 1e308) end)
      assert.truthy(message:find("bad argument #3 to 'solve' (tag_size between", 1, true),
        message)
    end)

    it("count corners by indexing, whatever a table's __len says", function()
      local lying = setmetatable({ corners[1], corners[2], corners[3] },
        { __len = function() return {} end })
      local message = raised(function() tagpose.solve(lying, camera, 0.024) end)
      assert.equal("bad argument #1 to 'solve' (four corners expected, got 3)", message)
      local four = setmetatable({ corners[1], corners[2], corners[3], corners[4] },
        { __len = function() return 7 end })
      assert(tagpose.solve(four, camera, 0.024))
    end)
  end)

  describe("integer pixels", function()
    it("never wrap around in u - cx, near math.mininteger (Lua 5.3 and 5.4)", function()
      local mi = rawget(math, "mininteger")
      if not mi then return end -- integers exist from Lua 5.3 on
      local cam = { fx = 700, fy = 700, cx = 639, cy = 359 }
      -- offsets below cx and cy wrap around in integer u - cx: these corners then looked like
      -- a tag, and a pose with a 9.4e12 px error came back
      local huge_corners = { { mi + 1227, mi + 36 }, { mi + 558, mi + 37 },
        { mi + 356, mi + 598 }, { mi + 983, mi + 617 } }
      local pose = tagpose.solve(huge_corners, cam, 0.024)
      if pose then
        -- a pose, then one whose error is its own reprojection, not 1e13 px
        local px = assert(geometry.project(cam, assertions.flat(pose.rotation),
          { pose.position.x, pose.position.y, pose.position.z }, 0.024))
        local sum = 0
        for i = 1, 4 do
          sum = sum + (px[i][1] - huge_corners[i][1]) ^ 2 + (px[i][2] - huge_corners[i][2]) ^ 2
        end
        assert.near(math.sqrt(sum / 4), pose.error, 1e-6 * (1 + pose.error))
      end
      -- and the same pixels as floats give the same answer
      local floats = {}
      for i = 1, 4 do floats[i] = { huge_corners[i][1] + 0.0, huge_corners[i][2] + 0.0 } end
      local f = tagpose.solve(floats, cam, 0.024)
      assert.equal(f == nil, pose == nil)
    end)
  end)

  describe("every VM", function()
    it("gives the fisheye solve the same bits (one arc tangent everywhere)", function()
      local script = [[
        package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
        local tagpose = require("tagpose")
        local cam = { fx = 600, fy = 600, cx = 639.5, cy = 359.5, model = "fisheye",
          distortion = { k1 = 0.05, k2 = -0.01, k3 = 0.002, k4 = 0 } }
        local out = {}
        -- the lens map at radii where glibc's atan(r) and atan2(r, 1) differ in the last bit
        -- (about one argument in 2500), and over a grid; then whole solves
        for _, r in ipairs({ 0.073026894160093225, 0.2985118130680694, 0.93189286763402301,
          0.20680360691938715, 0.3313222254306647, 0.34099452818790194, 0.26886886743310318,
          0.27112452419061422, 0.35228918602331039, 0.079738497771200956 }) do
          out[#out + 1] = ("%.17g"):format((tagpose.camera.distort(cam, r, 0)))
        end
        for i = 1, 3000 do
          local x, y = tagpose.camera.distort(cam, 0.001 * i, 0.0007 * i)
          out[#out + 1] = ("%.17g %.17g"):format(x, y)
        end
        for k = 0, 9 do
          local u, v = 100 + 97 * k, 80 + 53 * k
          local p = assert(tagpose.solve({ { u, v + 40 }, { u + 40, v + 41 }, { u + 41, v },
            { u + 1, v - 1 } }, cam, 0.024))
          local q = p.quaternion
          out[#out + 1] = ("%.17g %.17g %.17g %.17g %.17g %.17g"):format(p.position.z, q.w, q.x,
            q.y, p.confidence, p.covariance[6][6])
        end
        print(table.concat(out, ";"))
      ]]
      local outputs, names = {}, {}
      for _, vm in ipairs({ "lua5.1", "lua5.2", "lua5.3", "lua5.4", "luajit" }) do
        local text, status = run.run(vm .. " -e " .. run.quote(script) .. " 2>&1")
        if status == 0 then
          outputs[#outputs + 1], names[#names + 1] = text, vm
        end
      end
      assert.is_true(#outputs >= 2, "fewer than two VMs installed")
      for i = 2, #outputs do
        assert.equal(outputs[1], outputs[i], names[1] .. " and " .. names[i] .. " differ")
      end
    end)
  end)
end)

describe("frames of many tags", function()
  local fit = require("tagpose.block.fit")
  local cam = crowds.CAMERA

  -- n detections: piled at one place, one tag copied, or spread over the image
  local function frame(kind, n)
    return crowds.frame(geometry.rng(99), kind, n)
  end

  it("use every detection once or skip it, with joint fits linear in their number", function()
    local hypothesis = fit.hypothesis
    local fits = 0
    fit.hypothesis = function(...)
      fits = fits + 1
      return hypothesis(...)
    end
    local ok, err = pcall(function()
      for _, kind in ipairs({ "pile", "copies", "spread" }) do
        local n = 240
        fits = 0
        local blocks = assert(tagpose.block.solve(frame(kind, n), cam, 0.024, 0.055))
        local seen = {}
        for _, b in ipairs(blocks) do
          for _, i in ipairs(b.tags) do
            assert.is_nil(seen[i], kind)
            seen[i] = true
          end
          local p = b.position
          assert.is_true(p.x == p.x and p.y == p.y and p.z == p.z, kind)
        end
        for _, s in ipairs(blocks.skipped) do
          assert.is_nil(seen[s.index], kind)
          assert.is_string(s.reason)
          seen[s.index] = true
        end
        for i = 1, n do assert.is_true(seen[i], kind .. " detection " .. i) end
        -- (before the fit budget, a pile refitted its hypotheses after every block it found)
        assert.is_true(fits <= n + 32, ("%s: %d joint fits for %d tags"):format(kind, fits, n))
      end
    end)
    fit.hypothesis = hypothesis
    assert(ok, err)
  end)
end)

describe("tag sizes by id in block.solve", function()
  local cam = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 }

  it("solve each tag with its own size, and skip an id without one", function()
    local rng = geometry.rng(5)
    local r, t = geometry.random_pose(rng, cam, 0.048, { width = 40, tilt = math.rad(40) })
    local big = assert(geometry.project(cam, r, t, 0.048))
    local small = assert(geometry.project(cam, r, t, 0.024))
    local blocks = assert(tagpose.block.solve({ { id = 7, corners = big },
      { id = 3, corners = small }, { id = 9, corners = small } }, cam,
      { [7] = 0.048, [3] = 0.024 }, 0.1))
    -- the same tag pose seen twice: one block each, the big tag's centre as far as the small's
    assert.equal(1, #blocks)
    assert.equal(2, #blocks.skipped)
    local reasons = {}
    for _, s in ipairs(blocks.skipped) do reasons[s.index] = s.reason end
    -- the small tag's size right: it lands where the big one is, and overlaps it
    assert.truthy(reasons[2]:find("in its place", 1, true), reasons[2])
    assert.equal("block: tag_size has no size for tag id 9 and no default", reasons[3])
    local p = blocks[1].position
    assert.vector_near({ t[1] + 0.05 * r[3], t[2] + 0.05 * r[6], t[3] + 0.05 * r[9] },
      { p.x, p.y, p.z }, 1e-6)
  end)

  it("refuse a size table with a bad size, naming it", function()
    local message = raised(function()
      tagpose.block.solve({}, cam, { [1] = 0.024, default = -1 }, 0.055)
    end)
    assert.truthy(message:find('tag_size["default"]', 1, true), message)
  end)
end)
