local camera_model = require("tagpose.core.camera")
local tagpose = require("tagpose")
local geometry = require("support.geometry")

local sqrt, pi, rad = math.sqrt, math.pi, math.rad

local function cam(distortion, model, f, w, h)
  f, w, h = f or 700, w or 1280, h or 720
  return { fx = f, fy = f * 0.985, cx = (w - 1) / 2, cy = (h - 1) / 2, width = w, height = h,
    distortion = distortion, model = model }
end

-- the lens models a robot meets, each on a camera it belongs to: OpenCV's and ROS's conventions
local LENSES = {
  ["strong barrel (the distorted dev set)"] = cam({ k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4,
    k3 = 0 }),
  ["pincushion"] = cam({ k1 = 0.25, k2 = 0.05 }, nil, 600, 640, 480),
  ["tangential"] = cam({ k1 = -0.1, p1 = 0.01, p2 = -0.008 }, nil, 600, 640, 480),
  ["rational (k4..k6)"] = cam({ k1 = 0.5, k2 = 0.1, k3 = 0.01, k4 = 0.8, k5 = 0.2, k6 = 0.02,
    p1 = 1e-3 }),
  ["BuilderBot (realdata)"] = cam({ k1 = 0.018433447851104852, k2 = 0.16727474183089033,
    p1 = 0, p2 = 0, k3 = -1.5480889084966631 }, nil, 883.96, 640, 360),
  ["fisheye"] = cam({ k1 = -0.013, k2 = 0.02, k3 = -0.008, k4 = 0.001 }, "fisheye", 600),
}

describe("tagpose.core.camera", function()
  describe("check()", function()
    it("accepts pinhole, Brown-Conrady and fisheye cameras", function()
      for _, c in pairs(LENSES) do assert.is_nil(camera_model.check(c)) end
      assert.is_nil(camera_model.check({ fx = 1, fy = 1, cx = 0, cy = 0 }))
    end)

    it("names the field that is wrong", function()
      assert.equal("camera.model: 'pinhole' or 'fisheye' expected, got string kb",
        camera_model.check(cam(nil, "kb")))
      assert.equal("camera.distortion: table expected, got number", camera_model.check(cam(3)))
      assert.equal("camera.distortion.p2: finite number expected, got string x",
        camera_model.check(cam({ k1 = 0.1, p2 = "x" })))
      assert.equal("camera.distortion.k4: finite number expected, got number " .. tostring(1 / 0),
        camera_model.check(cam({ k4 = 1 / 0 }, "fisheye")))
    end)
  end)

  describe("distort()", function()
    it("matches hand-derived values", function()
      -- radial only: r² = 0.25, R = 1 + 0.1·0.25
      local xd, yd = camera_model.distort(cam({ k1 = 0.1 }), 0.5, 0)
      assert.near(0.5125, xd, 1e-15)
      assert.near(0, yd, 1e-15)
      -- tangential only: xd = x + 2 p1 x y, yd = y + p1 (r² + 2y²)
      xd, yd = camera_model.distort(cam({ p1 = 0.01 }), 0.5, 0.2)
      assert.near(0.5 + 2 * 0.01 * 0.1, xd, 1e-15)
      assert.near(0.2 + 0.01 * (0.29 + 0.08), yd, 1e-15)
      -- p2: xd = x + p2 (r² + 2x²), yd = y + 2 p2 x y
      xd, yd = camera_model.distort(cam({ p2 = 0.02 }), 0.5, 0.2)
      assert.near(0.5 + 0.02 * (0.29 + 0.5), xd, 1e-15)
      assert.near(0.2 + 2 * 0.02 * 0.1, yd, 1e-15)
      -- rational: R = 1 / (1 + k4 r²)
      xd = camera_model.distort(cam({ k4 = 0.1 }), 0.5, 0)
      assert.near(0.5 / 1.025, xd, 1e-15)
      -- fisheye with no coefficients: θd = atan(r), so (1, 0) -> (π/4, 0)
      xd, yd = camera_model.distort(cam({ k1 = 0 }, "fisheye"), 1, 0)
      assert.near(pi / 4, xd, 1e-15)
      assert.near(0, yd, 1e-15)
      -- fisheye k1: θd = θ (1 + k1 θ²)
      xd = camera_model.distort(cam({ k1 = 0.1 }, "fisheye"), 1, 0)
      assert.near(pi / 4 * (1 + 0.1 * (pi / 4) ^ 2), xd, 1e-15)
      -- no distortion: identity
      assert.same({ 0.3, -0.2, 1, 0, 0, 1 }, { camera_model.distort(cam(nil), 0.3, -0.2) })
    end)

    it("agrees with the specs' own transcription of OpenCV's models", function()
      for name, c in pairs(LENSES) do
        for _, p in ipairs({ { 0.1, 0.2 }, { -0.6, 0.4 }, { 0.9, -0.5 }, { 1e-9, 0 } }) do
          local xd, yd = camera_model.distort(c, p[1], p[2])
          local ex, ey = geometry.distort(c, p[1], p[2])
          assert.near(ex, xd, 1e-15, name)
          assert.near(ey, yd, 1e-15, name)
        end
      end
    end)

    it("returns the Jacobian of the map (checked by central differences)", function()
      local h = 1e-6
      for name, c in pairs(LENSES) do
        for _, p in ipairs({ { 0.1, 0.2 }, { -0.6, 0.4 }, { 0.7, -0.5 }, { 0, 0 } }) do
          local _, _, a, b, cc, d = camera_model.distort(c, p[1], p[2])
          local xp, yp = camera_model.distort(c, p[1] + h, p[2])
          local xm, ym = camera_model.distort(c, p[1] - h, p[2])
          assert.near((xp - xm) / (2 * h), a, 1e-8, name)
          assert.near((yp - ym) / (2 * h), cc, 1e-8, name)
          xp, yp = camera_model.distort(c, p[1], p[2] + h)
          xm, ym = camera_model.distort(c, p[1], p[2] - h)
          assert.near((xp - xm) / (2 * h), b, 1e-8, name)
          assert.near((yp - ym) / (2 * h), d, 1e-8, name)
        end
      end
    end)
  end)

  describe("undistort()", function()
    it("inverts every model to 1e-9 px over the whole image", function()
      for name, c in pairs(LENSES) do
        local worst = 0
        for u = 0, c.width, 32 do
          for v = 0, c.height, 24 do
            local xd, yd = (u - c.cx) / c.fx, (v - c.cy) / c.fy
            local x, y = camera_model.undistort(c, xd, yd)
            assert.is_number(x, name .. (" at pixel (%d, %d): %s"):format(u, v, tostring(y)))
            local bx, by = geometry.distort(c, x, y)
            local du, dv = (bx - xd) * c.fx, (by - yd) * c.fy
            worst = math.max(worst, sqrt(du * du + dv * dv))
          end
        end
        assert.is_true(worst <= 1e-9, ("%s: worst residual %.3g px"):format(name, worst))
      end
    end)

    it("round-trips undistorted points: undistort(distort(p)) = p", function()
      for name, c in pairs(LENSES) do
        -- points of the image's inner three quarters, in the undistorted plane
        local sx, sy = 0.375 * c.width / c.fx, 0.375 * c.height / c.fy
        for _, p in ipairs({ { 0.3 * sx, 0.1 * sy }, { -sx, sy }, { sx, -0.8 * sy }, { 0, 0 } }) do
          local xd, yd = geometry.distort(c, p[1], p[2])
          local x, y = camera_model.undistort(c, xd, yd)
          assert.near(p[1], x, 1e-12, name)
          assert.near(p[2], y, 1e-12, name)
        end
      end
    end)

    it("refuses fisheye rays 90 degrees or more from the optical axis", function()
      -- θd = θ without coefficients: a distorted radius of 2 rad is 115 degrees off axis, a ray
      -- that normalised coordinates (x/z, y/z) cannot express
      local x, err = camera_model.undistort(cam({ k1 = 0 }, "fisheye"), 2, 0)
      assert.is_nil(x)
      assert.equal("camera: the point is 90 degrees or more from the optical axis", err)
    end)

    it("refuses points outside the region where the model is one-to-one", function()
      -- r_d = r (1 - 0.5 r²) rises to 0.544 at r = 0.816, then falls: beyond, no inverse
      local c = cam({ k1 = -0.5 })
      local x, err = camera_model.undistort(c, 0.6, 0)
      assert.is_nil(x)
      assert.equal("camera: the lens model cannot be inverted at this point", err)
      -- inside, every distorted radius has exactly one preimage in the one-to-one region
      local ok = assert(camera_model.undistort(c, 0.5, 0))
      assert.is_true(ok < sqrt(2 / 3))
      assert.near(0.5, ok * (1 - 0.5 * ok * ok), 1e-15)
    end)
  end)

  describe("from_matrix()", function()
    it("takes OpenCV's K and D (nested or flat, 4, 5 or 8 coefficients)", function()
      local c = camera_model.from_matrix({ { 600, 0, 320 }, { 0, 610, 240 }, { 0, 0, 1 } },
        { -0.28, 0.07, 5e-4, -3e-4, 0.01 })
      assert.same({ fx = 600, fy = 610, cx = 320, cy = 240, model = "pinhole",
        distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0.01 } }, c)
      c = camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0, 1 }, { 0.1, 0.01, 0, 0 })
      assert.same({ k1 = 0.1, k2 = 0.01, p1 = 0, p2 = 0 }, c.distortion)
      c = camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0, 1 },
        { 1, 2, 3, 4, 5, 6, 7, 8 }, "rational_polynomial")
      assert.same({ k1 = 1, k2 = 2, p1 = 3, p2 = 4, k3 = 5, k4 = 6, k5 = 7, k6 = 8 }, c.distortion)
      -- all-zero coefficients and none at all: no distortion
      assert.is_nil(camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0, 1 },
        { 0, 0, 0, 0, 0 }).distortion)
      assert.is_nil(camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0, 1 }).distortion)
    end)

    it("takes a ROS camera_info, equidistant (fisheye) too", function()
      local info = { k = { 285.7, 0, 418.2, 0, 286.1, 403.5, 0, 0, 1 },
        d = { -0.0076, 0.0436, -0.0416, 0.0078 }, distortion_model = "equidistant" }
      local c = camera_model.from_matrix(info.k, info.d, info.distortion_model)
      assert.equal("fisheye", c.model)
      assert.same({ k1 = -0.0076, k2 = 0.0436, k3 = -0.0416, k4 = 0.0078 }, c.distortion)
      assert.is_nil(camera_model.check(c))
    end)

    it("raises a bad-argument error naming what is wrong", function()
      local K = { 600, 0, 320, 0, 610, 240, 0, 0, 1 }
      local cases = {
        { function() camera_model.from_matrix(nil) end,
          "bad argument #1 to 'from_matrix' (table expected for K, got nil)" },
        { function() camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0 }) end,
          "bad argument #1 to 'from_matrix' (K: 9 finite numbers expected, entry 9 is nil)" },
        { function() camera_model.from_matrix({ -600, 0, 320, 0, 610, 240, 0, 0, 1 }) end,
          "bad argument #1 to 'from_matrix' (K: positive focal lengths expected, "
            .. "got fx = -600, fy = 610)" },
        { function() camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 1, 1 }) end,
          "bad argument #1 to 'from_matrix' (K: a camera matrix [[fx, s, cx], [0, fy, cy], "
            .. "[0, 0, 1]] expected)" },
        { function() camera_model.from_matrix(K, { 0.1, 0.2, 0.3 }) end,
          "bad argument #2 to 'from_matrix' (4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, "
            .. "k5, k6]]) expected, got 3)" },
        { function() camera_model.from_matrix(K, { 0.1, 0.2, 0.3, 0.4, 0.5 }, "equidistant") end,
          "bad argument #2 to 'from_matrix' (4 coefficients k1, k2, k3, k4 expected for the "
            .. "equidistant model, got 5)" },
        { function() camera_model.from_matrix(K, { 0.1, 0 / 0, 0, 0 }) end,
          "bad argument #2 to 'from_matrix' (D: coefficient 2 (k2) is number "
            .. tostring(0 / 0) .. ")" },
        { function() camera_model.from_matrix(K, {}, "kannala") end,
          "bad argument #3 to 'from_matrix' (distortion model 'plumb_bob', "
            .. "'rational_polynomial' or 'equidistant' expected, got string kannala)" },
        -- ROS's 3x4 P given for K: named, with what to pass instead
        { function() camera_model.from_matrix({ 900, 0, 320, 0, 0, 900, 240, 0, 0, 0, 1, 0 }) end,
          "bad argument #1 to 'from_matrix' (K: 9 numbers (a 3x3 camera matrix, row-major)"
            .. " expected, got 12: a 3x4 projection matrix (ROS's P)? its first three columns,"
            .. " {P[1], P[2], P[3], P[5], P[6], P[7], P[9], P[10], P[11]}, are the camera matrix"
            .. " of the rectified image)" },
        { function()
          camera_model.from_matrix({ { 900, 0, 320, 0 }, { 0, 900, 240, 0 }, { 0, 0, 1, 0 } })
        end, "bad argument #1 to 'from_matrix' (K: a 3x3 camera matrix expected, got 3x4: a"
          .. " projection matrix (ROS's P)? its first three columns are the camera matrix of the"
          .. " rectified image)" },
        { function() camera_model.from_matrix({ 600, 0, 320, 0, 610, 240, 0, 0, 1, 0 }) end,
          "bad argument #1 to 'from_matrix' (K: 9 numbers (a 3x3 camera matrix, row-major)"
            .. " expected, got 10)" },
        { function() camera_model.from_matrix({ { 600, 0, 320 }, { 0, 610, 240, 7 }, { 0, 0, 1 } })
        end, "bad argument #1 to 'from_matrix' (K[2]: 3 numbers expected, got 4)" },
        -- what solve would refuse on every call is refused here
        { function() camera_model.from_matrix({ 1e-320, 0, 320, 0, 610, 240, 0, 0, 1 }) end,
          "bad argument #1 to 'from_matrix' (K: fx: a focal length in pixels between 1e-09 and"
            .. " 1e+12 expected, got number " .. tostring(1e-320) .. ")" },
        { function() camera_model.from_matrix({ 600, 0, 320, 0, 610, -1e13, 0, 0, 1 }) end,
          "bad argument #1 to 'from_matrix' (K: cy: a principal point coordinate in pixels within"
            .. " 1e+12 expected, got number " .. tostring(-1e13) .. ")" },
      }
      for _, case in ipairs(cases) do
        local ok, err = pcall(case[1])
        assert.is_false(ok)
        assert.equal(case[2], tostring(err):match("camera_spec%.lua:%d+: (.*)$"))
      end
    end)
  end)

  describe("tagpose.solve() through a lens", function()
    it("recovers exact poses for every model, and reports the error in raw pixels", function()
      local rng = geometry.rng(2718)
      for name, c in pairs(LENSES) do
        for n = 1, 40 do
          local s = 0.1
          local r, t = geometry.random_pose(rng, c, s, { width = rng.uniform(20, 200),
            max_tilt = rad(75) })
          local px = geometry.project(c, r, t, s)
          local label = ("%s case %d"):format(name, n)
          for _, method in ipairs({ "seed", "refined" }) do
            local pose = assert(tagpose.solve(px, c, s, { method = method }), label)
            assert.rotation_near(r, pose.rotation, 1e-6, label .. " " .. method)
            local d = sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
            assert.vector_near(t, pose.position, 1e-9 * d, label .. " " .. method)
            assert.is_true(pose.error < 1e-6, label)
          end
        end
      end
    end)

    it("measures the error through the lens: a 1 px shift of a corner shows as such", function()
      local c = LENSES["strong barrel (the distorted dev set)"]
      local r, t = geometry.random_pose(geometry.rng(5), c, 0.1, { width = 120, u = 1100, v = 600,
        tilt = 0.3 })
      local px = geometry.project(c, r, t, 0.1)
      px[2][1] = px[2][1] + 1
      local pose = assert(tagpose.solve(px, c, 0.1, { method = "seed" }))
      -- the seed fits corners 1-3 exactly-ish; corner 2's 1 px shift shows in the error
      assert.is_true(pose.error > 0.1 and pose.error < 1, tostring(pose.error))
    end)
  end)
end)
