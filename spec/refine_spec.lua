local refine = require("tagpose.core.refine")
local lsq = require("tagpose.core.lsq")
local rotation = require("tagpose.core.rotation")
local tagpose = require("tagpose")
local geometry = require("support.geometry")

local sqrt, rad = math.sqrt, math.rad

local camera = { fx = 800, fy = 780, cx = 321.5, cy = 242.5, width = 640, height = 480 }

local function flat_pixels(px)
  local out = {}
  for i = 1, 4 do out[2 * i - 1], out[2 * i] = px[i][1], px[i][2] end
  return out
end

local function noisy(rng, px, sigma)
  local out = {}
  for i = 1, 4 do out[i] = { px[i][1] + sigma * rng.normal(), px[i][2] + sigma * rng.normal() } end
  return out
end

-- refine.refine on a candidate record: the refined translation, cost and linearisations (the
-- rotation r, the start, is replaced by the result)
local function refined(px, half, r, tx, ty, tz, max_iterations)
  local cand = { r = r, tx = tx, ty = ty, tz = tz }
  refine.refine(lsq.pack(camera), px, half, cand, max_iterations)
  return cand.tx, cand.ty, cand.tz, cand.sse, cand.linearisations
end

local function copy(r)
  local c = {}
  for i = 1, 9 do c[i] = r[i] end
  return c
end

-- sum of squared pixel residuals of a pose, computed here from geometry
local function sse(r, t, s, px)
  local back = geometry.project(camera, r, t, s)
  local sum = 0
  for i = 1, 4 do sum = sum + (back[i][1] - px[i][1]) ^ 2 + (back[i][2] - px[i][2]) ^ 2 end
  return sum
end

describe("tagpose.core.refine", function()
  local rng = geometry.rng(31337)

  describe("refine()", function()
    it("leaves an exact pose at round-off, in one linearisation", function()
      for _ = 1, 50 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s)
        local px = geometry.project(camera, r, t, s)
        local est = copy(r)
        local tx, ty, tz, cost, k = refined(flat_pixels(px), s / 2, est,
          t[1], t[2], t[3])
        assert.rotation_near(r, est, 1e-9)
        assert.vector_near(t, { tx, ty, tz }, 1e-12 * t[3])
        assert.is_true(cost < 1e-18)
        assert.equal(1, k)
      end
    end)

    it("brings a perturbed start back to the exact pose", function()
      -- (away from the ambiguity: a nearly frontal tag has the other minimum within degrees)
      for n = 1, 100 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s,
          { tilt = rad(rng.uniform(20, 70)), width = rng.uniform(40, 300) })
        local px = geometry.project(camera, r, t, s)
        -- 5 degrees off about a random axis, 5 % off in position
        local start = geometry.mul(geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
          rad(5)), r)
        local d = sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
        local tx, ty, tz = refined(flat_pixels(px), s / 2, start,
          t[1] + 0.05 * d * rng.normal() / sqrt(3), t[2] + 0.05 * d * rng.normal() / sqrt(3),
          t[3] + 0.05 * d * rng.normal() / sqrt(3))
        assert.rotation_near(r, start, 1e-6, "case " .. n)
        assert.vector_near(t, { tx, ty, tz }, 1e-9 * d, "case " .. n)
      end
    end)

    it("ends at a local minimum of the reprojection error (to its stopping tolerance)", function()
      for _ = 1, 30 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s, { max_tilt = rad(60), width = 80 })
        local px = noisy(rng, geometry.project(camera, r, t, s), 1.0)
        local est = copy(r)
        local tx, ty, tz, cost = refined(flat_pixels(px), s / 2, est,
          t[1], t[2], t[3])
        local best = { tx, ty, tz }
        assert.near(sse(est, best, s, px), cost, 1e-9 * cost)
        -- no small move in any of the six directions does better by more than the tolerance
        -- the refinement stops at (a step that would gain less than STEP_RELATIVE of the cost)
        local floor = cost * (1 - refine.STEP_RELATIVE) - 1e-12
        for axis = 1, 3 do
          for _, h in ipairs({ -1e-4, 1e-4 }) do
            local w = { 0, 0, 0 }
            w[axis] = h
            local moved = rotation.multiply(rotation.from_rotation_vector(w[1], w[2], w[3]), est)
            assert.is_true(sse(moved, best, s, px) >= floor)
            local shifted = { best[1], best[2], best[3] }
            shifted[axis] = shifted[axis] + h * tz
            assert.is_true(sse(est, shifted, s, px) >= floor)
          end
        end
      end
    end)

    it("stops within STEP_RELATIVE of the minimum's cost when a step leaves a small remainder",
      function()
        -- tagpose.solve refines from the local starts and stops after the first step when its
        -- second-order remainder is negligible (a bound, not an exact prediction: hence the
        -- factor 2); a refinement run to 1e-12 from the pose must not find a cost lower by more
        -- than the rule allows (noise 0.2 to 2 px, tags 15 to 300 px)
        local relative, bound = refine.STEP_RELATIVE, refine.MAX_ITERATIONS
        local ok, err = pcall(function()
          for n = 1, 150 do
            local s = 0.05
            local r, t = geometry.random_pose(rng, camera, s, { width = rng.log_uniform(15, 300) })
            local px = noisy(rng, geometry.project(camera, r, t, s), rng.log_uniform(0.2, 2))
            local pose = tagpose.solve(px, camera, s)
            for _, p in ipairs({ pose }) do
              local cost = 4 * p.error ^ 2
              local est = rotation.from_nested(p.rotation, {})
              refine.STEP_RELATIVE, refine.MAX_ITERATIONS = 1e-12, 200
              local _, _, _, best = refined(flat_pixels(px), s / 2, est,
                p.position.x, p.position.y, p.position.z)
              refine.STEP_RELATIVE, refine.MAX_ITERATIONS = relative, bound
              assert.is_true(best <= cost + 1e-12, "case " .. n)
              assert.is_true(cost <= best * (1 + 2 * relative) + 1e-12,
                ("case %d: stopped at %.6g, minimum %.6g"):format(n, cost, best))
            end
          end
        end)
        refine.STEP_RELATIVE, refine.MAX_ITERATIONS = relative, bound
        assert(ok, err)
      end)

    it("never needs more than its bound", function()
      local s = 0.05
      local r, t = geometry.random_pose(rng, camera, s)
      local px = noisy(rng, geometry.project(camera, r, t, s), 3)
      local _, _, _, _, k = refined(flat_pixels(px), s / 2, copy(r), t[1], t[2],
        t[3], 2)
      assert.is_true(k <= 2)
    end)
  end)

  describe("linearise_unrolled() and linearise_looped()", function()
    it("build the same normal equations (each VM runs the faster one)", function()
      for _ = 1, 50 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s, { max_tilt = rad(80) })
        local px = flat_pixels(noisy(rng, geometry.project(camera, r, t, s), 2))
        local C = lsq.pack(camera)
        local Q = { r[1], r[4], r[7], r[2], r[5], r[8], t[1], t[2], t[3] }
        local A, B = {}, {}
        local sa = refine.linearise_unrolled(A, px, C, s / 2, Q)
        local sb = refine.linearise_looped(B, px, C, s / 2, Q)
        assert.near(sa, sb, 1e-12 * sa)
        for k = 1, 27 do
          assert.near(A[k], B[k], 1e-9 * (math.abs(A[k]) + 1), "entry " .. k)
        end
      end
    end)
  end)

  describe("mirror()", function()
    it("reflects the tag's normal about the line of sight and keeps a proper rotation", function()
      for _ = 1, 20 do
        local r, t = geometry.random_pose(rng, camera, 0.05, { tilt = rad(35) })
        local m = refine.mirror(r, t[1], t[2], t[3], {})
        local d = sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
        local l = { t[1] / d, t[2] / d, t[3] / d }
        local n = { r[3], r[6], r[9] }
        local c = n[1] * l[1] + n[2] * l[2] + n[3] * l[3]
        assert.vector_near({ 2 * c * l[1] - n[1], 2 * c * l[2] - n[2], 2 * c * l[3] - n[3] },
          { m[3], m[6], m[9] }, 1e-12)
        local det = m[1] * (m[5] * m[9] - m[6] * m[8]) - m[2] * (m[4] * m[9] - m[6] * m[7])
          + m[3] * (m[4] * m[8] - m[5] * m[7])
        assert.near(1, det, 1e-12)
        -- the tilt from the line of sight is the same
        assert.near(c, m[3] * l[1] + m[6] * l[2] + m[9] * l[3], 1e-12)
      end
    end)
  end)

  describe("the two solutions of tagpose.solve()", function()
    it("both reproject within the noise on ambiguous (small, nearly frontal) tags", function()
      local sigma, found = 0.5, 0
      for _ = 1, 40 do
        local s = 0.024
        local r, t = geometry.random_pose(rng, camera, s, { width = 20, max_tilt = rad(20) })
        local px = noisy(rng, geometry.project(camera, r, t, s), sigma)
        local pose = assert(tagpose.solve(px, camera, s))
        if pose.alternative then
          found = found + 1
          assert.is_true(pose.error <= pose.alternative.error)
          assert.is_true(pose.alternative.error < 3 * sigma)
          -- and each reports its own reprojection error
          local p = pose.alternative.position
          local alt = rotation.from_nested(pose.alternative.rotation)
          assert.near(sqrt(sse(alt, { p.x, p.y, p.z }, s, px) / 4), pose.alternative.error, 1e-9)
        end
      end
      assert.is_true(found >= 30)
    end)

    it("gives the alternative a clearly larger error on strongly tilted, close tags", function()
      for _ = 1, 40 do
        local s = 0.05
        local r, t = geometry.random_pose(rng, camera, s, { width = 150, tilt = rad(60) })
        local px = noisy(rng, geometry.project(camera, r, t, s), 0.3)
        local pose = assert(tagpose.solve(px, camera, s))
        assert.rotation_near(r, pose.rotation, 3)
        if pose.alternative then
          assert.is_true(pose.alternative.error > 5 * pose.error + 1,
            ("main %.3f px, alternative %.3f px"):format(pose.error, pose.alternative.error))
        end
      end
    end)
  end)
end)
