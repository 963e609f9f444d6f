local square = require("tagpose.core.square")
local elimination = require("support.elimination")
local report = require("support.report")
local geometry = require("support.geometry")

local camera = { fx = 800, fy = 760, cx = 322.5, cy = 241.5, width = 640, height = 480 }

-- normalised corners of a pose, plus noise of `sigma` px
local function corners(rng, r, t, s, sigma)
  local px = geometry.project(camera, r, t, s)
  local m = {}
  for i = 1, 4 do
    local u = px[i][1] + (sigma > 0 and sigma * rng.normal() or 0)
    local v = px[i][2] + (sigma > 0 and sigma * rng.normal() or 0)
    m[2 * i - 1], m[2 * i] = (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
  end
  return m
end

-- the report's unknowns (x, y, z, a, b, c, p, q, r) of a pose: A = +y_tag s/2, P = -x_tag s/2
local function unknowns(r, t, s)
  local h = s / 2
  return { t[1], t[2], t[3], r[2] * h, r[5] * h, r[8] * h, -r[1] * h, -r[4] * h, -r[7] * h }
end

describe("tagpose.core.square", function()
  local rng = geometry.rng(20171201)

  describe("the report's camera equations (support.report)", function()
    it("are satisfied by the unknowns of the true pose", function()
      for _ = 1, 100 do
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local m = corners(rng, r, t, 0.05, 0)
        local e = report.camera_equations(m)
        local v = unknowns(r, t, 0.05)
        for row = 0, 7 do
          local s = 0
          for j = 1, 9 do s = s + e[row * 9 + j] * v[j] end
          assert.near(0, s, 1e-15)
        end
      end
    end)
  end)

  describe("proximate()", function()
    it("is the report's eight-equation solution with base z (checked by elimination)", function()
      for _ = 1, 100 do
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local m = corners(rng, r, t, 0.05, 1.0) -- noisy: a parallelogram, not a square
        local e = report.camera_equations(m)
        -- move the z column (z = 1) to the right-hand side, solve for the other eight
        local a, b, cols = {}, {}, { 1, 2, 4, 5, 6, 7, 8, 9 }
        for row = 0, 7 do
          for k, j in ipairs(cols) do a[row * 8 + k] = e[row * 9 + j] end
          b[row + 1] = -e[row * 9 + 3]
        end
        local x = assert(elimination.solve(8, a, b))
        local X0, Y0 = square.proximate(assert(square.shape(m)))
        assert.near(x[5], X0, 1e-12) -- c / z
        assert.near(x[8], Y0, 1e-12) -- r / z
      end
    end)

    it("is the true ratio for exact corners", function()
      for _ = 1, 50 do
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local v = unknowns(r, t, 0.05)
        local X0, Y0 = square.proximate(assert(square.shape(corners(rng, r, t, 0.05, 0))))
        assert.near(v[6] / v[3], X0, 1e-12)
        assert.near(v[9] / v[3], Y0, 1e-12)
      end
    end)
  end)

  describe("quadratics()", function()
    it("are the report's 6+3 reduction (checked by elimination of corners 1-3)", function()
      for _ = 1, 100 do
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local m = corners(rng, r, t, 0.05, 1.0)
        local q = square.quadratics(m)
        local e = report.camera_equations(m)
        -- six equations; unknowns x, y, a, b, p, q on the left, base c, r, z on the right
        local a, b, left, base = {}, {}, { 1, 2, 4, 5, 7, 8 }, { 6, 9, 3 }
        for row = 0, 5 do
          for k, j in ipairs(left) do a[row * 6 + k] = e[row * 9 + j] end
          for k, j in ipairs(base) do b[row * 3 + k] = -e[row * 9 + j] end
        end
        local lin = assert(elimination.solve(6, a, b, 3))
        for _ = 1, 5 do
          local X, Y = rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)
          local v = {} -- x, y, a, b, p, q at c = X, r = Y, z = 1
          for k = 1, 6 do
            v[k] = lin[(k - 1) * 3 + 1] * X + lin[(k - 1) * 3 + 2] * Y + lin[k * 3]
          end
          local g1 = v[3] * v[5] + v[4] * v[6] + X * Y
          local g2 = v[3] ^ 2 + v[4] ^ 2 + X ^ 2 - v[5] ^ 2 - v[6] ^ 2 - Y ^ 2
          local q1 = q[1] * X * X + q[2] * Y * Y + q[3] * X * Y + q[4] * X + q[5] * Y + q[6]
          local q2 = q[7] * X * X + q[8] * Y * Y + q[9] * X * Y + q[10] * X + q[11] * Y + q[12]
          assert.near(g1, q1, 1e-12)
          assert.near(g2, q2, 1e-12)
        end
      end
    end)

    it("vanish at the true pose for exact corners", function()
      for _ = 1, 50 do
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local v = unknowns(r, t, 0.05)
        local q = square.quadratics(corners(rng, r, t, 0.05, 0))
        local X, Y = v[6] / v[3], v[9] / v[3]
        assert.near(0, q[1] * X * X + q[2] * Y * Y + q[3] * X * Y + q[4] * X + q[5] * Y + q[6],
          1e-14)
        assert.near(0, q[7] * X * X + q[8] * Y * Y + q[9] * X * Y + q[10] * X + q[11] * Y + q[12],
          1e-14)
      end
    end)
  end)

  describe("pose()", function()
    it("recovers the pose from the true root", function()
      for _ = 1, 50 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s)
        local v = unknowns(r, t, s)
        local out = {}
        local m = corners(rng, r, t, s, 0)
        local tx, ty, tz = square.pose(m, v[6] / v[3], v[9] / v[3], s / 2, out)
        assert.vector_near(t, { tx, ty, tz }, 1e-12 * tz)
        assert.rotation_near(r, out, 1e-9)
      end
    end)

    it("refuses a root that puts a corner behind the camera", function()
      local m = { -0.1, 0.1, 0.1, 0.1, 0.1, -0.1, -0.1, -0.1 }
      assert.same({ nil, "square: the solution puts a corner behind the camera" },
        { square.pose(m, -2, 0, 0.5, {}) })
    end)
  end)

  describe("shape()", function()
    local ok = { -0.1, 0.1, 0.1, 0.1, 0.1, -0.1, -0.1, -0.1 }

    it("accepts the detection order and returns positive depths", function()
      local l1, l2, l3, l4 = square.shape(ok)
      assert.is_true(l1 > 0 and l2 > 0 and l3 > 0 and l4 > 0)
      assert.near(l1, l3, 1e-15)
    end)

    it("names corners that coincide", function()
      local m = { -0.1, 0.1, 0.1, 0.1, 0.1, 0.1, -0.1, -0.1 }
      assert.same({ nil, "square: corners 2 and 3 coincide" }, { square.shape(m) })
      assert.same({ nil, "square: corners 1 and 2 coincide" },
        { square.shape({ 0, 0, 0, 0, 0, 0, 0, 0 }) })
    end)

    it("rejects three corners on a line", function()
      local m = { -0.1, 0.1, 0, 0.1, 0.1, 0.1, -0.1, -0.1 }
      assert.same({ nil, "square: corners are collinear" }, { square.shape(m) })
      assert.same({ nil, "square: corners are collinear" },
        { square.shape({ 0, 0, 1, 1, 2, 2, 3, 3 }) })
    end)

    it("rejects a quadrilateral that is not convex, and a bow-tie", function()
      local dart = { -0.1, 0.1, 0.1, 0.1, 0.1, -0.1, 0.05, 0.05 }
      assert.same({ nil, "square: corners are not a convex quadrilateral" }, { square.shape(dart) })
      local bowtie = { -0.1, 0.1, 0.1, 0.1, -0.1, -0.1, 0.1, -0.1 }
      assert.same({ nil, "square: corners are not a convex quadrilateral" },
        { square.shape(bowtie) })
    end)

    it("rejects the mirrored (clockwise) order", function()
      local mirrored = { -0.1, 0.1, -0.1, -0.1, 0.1, -0.1, 0.1, 0.1 }
      local _, err = square.shape(mirrored)
      assert.equal("square: corners wind the wrong way round (mirrored order, or tag seen from "
        .. "behind; OpenCV's and ArUco's detectors give them top-left first: options.order = "
        .. "'opencv')", err)
    end)
  end)
end)
