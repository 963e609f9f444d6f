local tagpose = require("tagpose")
local assertions = require("support.assertions")

local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }
local good = { { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } }
local nan, inf = 0 / 0, math.huge

-- the error raised by f, which must point at this file (the caller's line)
local function raised(f)
  return assertions.raised(f, "errors_spec.lua")
end

local function corners_with(i, u, v)
  local c = {}
  for k = 1, 4 do c[k] = { good[k][1], good[k][2] } end
  c[i] = { u, v }
  return c
end

describe("tagpose.solve() errors", function()
  describe("misuse raises a bad-argument error at the caller's line", function()
    local cases = {
      { function() tagpose.solve(nil, camera, 1) end,
        "bad argument #1 to 'solve' (table of four corners expected, got nil)" },
      { function() tagpose.solve({ good[1], good[2], good[3] }, camera, 1) end,
        "bad argument #1 to 'solve' (four corners expected, got 3)" },
      { function() tagpose.solve({ good[1], good[2], good[3], good[4], good[1] }, camera, 1) end,
        "bad argument #1 to 'solve' (four corners expected, got 5)" },
      { function() tagpose.solve({ good[1], good[2], 7, good[4] }, camera, 1) end,
        "bad argument #1 to 'solve' (corner 3: table expected, got number)" },
      { function() tagpose.solve(corners_with(2, "1", 2), camera, 1) end,
        "bad argument #1 to 'solve' (corner 2: numbers {u, v} or {x =, y =} expected, "
          .. "got string 1 and number 2)" },
      { function() tagpose.solve({ good[1], good[2], good[3], { u = 1, v = 2 } }, camera, 1) end,
        "bad argument #1 to 'solve' (corner 4: numbers {u, v} or {x =, y =} expected, "
          .. "got nil and nil)" },
      { function() tagpose.solve(good, nil, 1) end,
        "bad argument #2 to 'solve' (camera table expected, got nil)" },
      { function() tagpose.solve(good, { fy = 1, cx = 0, cy = 0 }, 1) end,
        "bad argument #2 to 'solve' (camera.fx: positive number expected, got nil)" },
      { function() tagpose.solve(good, { fx = 1, fy = -2, cx = 0, cy = 0 }, 1) end,
        "bad argument #2 to 'solve' (camera.fy: positive number expected, got number -2)" },
      { function() tagpose.solve(good, { fx = 1, fy = 1, cx = nan, cy = 0 }, 1) end,
        "bad argument #2 to 'solve' (camera.cx: finite number expected, got number "
          .. tostring(nan) .. ")" },
      { function() tagpose.solve(good, { fx = 1, fy = 1, cx = 0, cy = "0" }, 1) end,
        "bad argument #2 to 'solve' (camera.cy: finite number expected, got string 0)" },
      { function() tagpose.solve(good, camera) end,
        "bad argument #3 to 'solve' (positive number expected for tag_size, got nil)" },
      { function() tagpose.solve(good, camera, 0) end,
        "bad argument #3 to 'solve' (positive number expected for tag_size, got number 0)" },
      { function() tagpose.solve(good, camera, -1) end,
        "bad argument #3 to 'solve' (positive number expected for tag_size, got number -1)" },
      { function() tagpose.solve(good, camera, inf) end,
        "bad argument #3 to 'solve' (positive number expected for tag_size, got number "
          .. tostring(inf) .. ")" },
      { function() tagpose.solve(good, camera, 1, "seed") end,
        "bad argument #4 to 'solve' (options table expected, got string)" },
      { function() tagpose.solve(good, camera, 1, { method = "fast" }) end,
        "bad argument #4 to 'solve' (options.method: 'refined' or 'seed' expected, "
          .. "got string fast)" },
      { function() tagpose.solve(good, camera, 1, { tolerance = 0 }) end,
        "bad argument #4 to 'solve' (options.tolerance: positive number expected, got number 0)" },
      { function() tagpose.solve(good, camera, 1, { max_iterations = 2.5 }) end,
        "bad argument #4 to 'solve' (options.max_iterations: positive integer expected, "
          .. "got number 2.5)" },
      { function() tagpose.solve(good, camera, 1, { prior = 3 }) end,
        "bad argument #4 to 'solve' (options.prior: pose table expected, got number)" },
      { function() tagpose.solve(good, camera, 1, { prior = { quaternion = { w = 0 / 0 } } }) end,
        "bad argument #4 to 'solve' (options.prior: pose with a finite quaternion or rotation "
          .. "expected)" },
      { function() tagpose.solve(good, camera, 1, { into = "pose" }) end,
        "bad argument #4 to 'solve' (options.into: table expected, got string)" },
      { function() tagpose.solve(good, { fx = 1, fy = 1, cx = 0, cy = 0, model = "kb" }, 1) end,
        "bad argument #2 to 'solve' (camera.model: 'pinhole' or 'fisheye' expected, "
          .. "got string kb)" },
      { function()
          tagpose.solve(good, { fx = 1, fy = 1, cx = 0, cy = 0, distortion = { k1 = "a" } }, 1)
        end,
        "bad argument #2 to 'solve' (camera.distortion.k1: finite number expected, "
          .. "got string a)" },
      { function() tagpose.solve(good, camera, 1, { max_iterations = 0 }) end,
        "bad argument #4 to 'solve' (options.max_iterations: positive integer expected, "
          .. "got number 0)" },
    }
    for i, case in ipairs(cases) do
      it(case[2], function()
        assert.equal(case[2], raised(case[1]), "case " .. i)
      end)
    end
  end)

  describe("bad data returns nil and a message", function()
    local function fails(corners, message, options)
      local pose, err = tagpose.solve(corners, camera, 0.024, options)
      assert.is_nil(pose)
      assert.equal(message, err)
    end

    it("for non-finite corners", function()
      fails(corners_with(1, nan, 200), "tagpose: corner 1 is not finite")
      fails(corners_with(3, 300, inf), "tagpose: corner 3 is not finite")
      fails(corners_with(4, -inf, -inf), "tagpose: corner 4 is not finite")
    end)

    it("for coincident corners", function()
      fails(corners_with(2, 280, 280), "square: corners 1 and 2 coincide")
      fails({ { 5, 5 }, { 5, 5 }, { 5, 5 }, { 5, 5 } }, "square: corners 1 and 2 coincide")
    end)

    it("for collinear corners", function()
      fails(corners_with(2, 280, 240), "square: corners are collinear")
      fails({ { 0, 0 }, { 10, 10 }, { 20, 20 }, { 30, 30 } }, "square: corners are collinear")
    end)

    it("for a quadrilateral that is not convex", function()
      fails(corners_with(4, 340, 260), "square: corners are not a convex quadrilateral")
      -- bow-tie: corners 3 and 4 swapped
      fails({ good[1], good[2], good[4], good[3] },
        "square: corners are not a convex quadrilateral")
    end)

    it("for the mirrored (clockwise) corner order", function()
      fails({ good[1], good[4], good[3], good[2] },
        "square: corners wind the wrong way round (mirrored order, or tag seen from behind; "
          .. "OpenCV's and ArUco's detectors give them top-left first: options.order = "
          .. "'opencv')")
    end)

    it("when solveQuad has no iterations left", function()
      -- a noisy, nearly frontal tag on which the report's update does not converge quickly
      local corners = { { 281.08270152357755, 195.65450302409999 },
        { 285.11424763321133, 291.73892410212289 }, { 380.30871457613046, 288.15949463465211 },
        { 380.11629431401508, 192.58802388230248 } }
      fails(corners, "solvequad: no convergence in 3 iterations",
        { method = "seed", max_iterations = 3 })
    end)
  end)
end)
