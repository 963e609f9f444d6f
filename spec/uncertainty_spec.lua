-- Covariance and branch confidence (tagpose.uncertainty through tagpose.solve), checked against
-- Monte-Carlo on generated geometry: a known pose projected, Gaussian noise of a known σ added
-- (Box-Muller on Park-Miller, the same numbers on every VM), solved many times.

local tagpose = require("tagpose")
local uncertainty = require("tagpose.uncertainty")
local track = require("tagpose.track")
local rotation = require("tagpose.core.rotation")
local G = require("support.geometry")
local assertions = require("support.assertions")
local gauss = require("support.gauss")
local run = require("support.run")

local sqrt, abs, rad = math.sqrt, math.abs, math.rad

local CAMERA = { fx = 883.98, fy = 860.5, cx = 331.2, cy = 228.7, width = 640, height = 480 }

local error_of, mahalanobis = gauss.error_of, gauss.mahalanobis

local function noisy(px, rng, sigma)
  local out = {}
  for i = 1, 4 do out[i] = { px[i][1] + sigma * rng.normal(), px[i][2] + sigma * rng.normal() } end
  return out
end

-- the candidate of a pose on the true branch (rotation nearer the truth) and its error
local function true_branch(pose, rt, tt)
  local e = error_of(pose, rt, tt)
  local alt = pose.alternative
  if alt then
    local ea = error_of(alt, rt, tt)
    if ea[4] ^ 2 + ea[5] ^ 2 + ea[6] ^ 2 < e[4] ^ 2 + e[5] ^ 2 + e[6] ^ 2 then return alt, ea end
  end
  return pose, e
end

local is_spd = gauss.is_spd

describe("tagpose.uncertainty", function()
  describe("covariance", function()
    it("matches the spread of the estimates of a well-determined view (Monte-Carlo)", function()
      local rng = G.rng(1301)
      local s, sigma, n = 0.05, 0.5, 300
      local r, t = G.random_pose(rng, CAMERA, s, { width = 120, tilt = rad(40), u = 300,
        v = 250 })
      local px = G.project(CAMERA, r, t, s)
      local sum, inside, first = 0, 0, nil
      for k = 1, n do
        local pose = assert(tagpose.solve(noisy(px, rng, sigma), CAMERA, s, { sigma = sigma }))
        local best, e = true_branch(pose, r, t)
        first = first or best.covariance
        local m2 = mahalanobis(best.covariance, e)
        sum = sum + m2
        if m2 < 12.59 then inside = inside + 1 end
        assert.is_true(k > 0)
      end
      -- χ²₆: mean 6, sd of the mean sqrt(12 / n); 95 % inside, sd sqrt(0.95 · 0.05 / n)
      local mean, share = sum / n, inside / n
      assert.is_true(abs(mean - 6) < 4 * sqrt(12 / n), ("mean Mahalanobis² %.2f"):format(mean))
      assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n), ("coverage %.3f"):format(share))
      -- and the covariance is not a multiple of the identity or a placeholder
      assert.is_true(is_spd(first))
      assert.is_true(abs(first[1][3]) > 0 and abs(first[4][5]) > 0)
    end)

    it("covers the truth on ambiguous views (small, nearly face-on tags) as it claims", function()
      -- tilts uniform in angle as the model assumes; the textbook σ² H⁻¹ covers ~80 % here
      local rng = G.rng(1302)
      local s, sigma, n = 0.024, 0.5, 400
      local inside, sum = 0, 0
      for _ = 1, n do
        local r, t = G.random_pose(rng, CAMERA, s, { width = rng.uniform(12, 30),
          tilt = rng.uniform(0, rad(30)) })
        local px = G.project(CAMERA, r, t, s)
        local pose = assert(tagpose.solve(noisy(px, rng, sigma), CAMERA, s, { sigma = sigma }))
        local best, e = true_branch(pose, r, t)
        local m2 = mahalanobis(best.covariance, e)
        sum = sum + m2
        if m2 < 12.59 then inside = inside + 1 end
      end
      local share = inside / n
      assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n), ("coverage %.3f"):format(share))
    end)

    it("scales with σ² and with the tag size², position in tag-size units", function()
      local rng = G.rng(1303)
      local s = 0.05
      local r, t = G.random_pose(rng, CAMERA, s, { width = 150, tilt = rad(50) })
      local px = noisy(G.project(CAMERA, r, t, s), rng, 0.3)
      local a = assert(tagpose.solve(px, CAMERA, s, { sigma = 0.5 }))
      local b = assert(tagpose.solve(px, CAMERA, s, { sigma = 1 }))
      local c = assert(tagpose.solve(px, CAMERA, 1000 * s, { sigma = 0.5 }))
      for i = 1, 6 do
        for j = 1, 6 do
          local ca = a.covariance[i][j]
          -- far from the ambiguity the correction is tiny: σ² H⁻¹ scales exactly
          assert.is_true(abs(b.covariance[i][j] - 4 * ca) <= 0.02 * sqrt(
            4 * a.covariance[i][i] * 4 * a.covariance[j][j]), ("σ: (%d, %d)"):format(i, j))
          local k = (i <= 3 and 1000 or 1) * (j <= 3 and 1000 or 1)
          assert.is_true(abs(c.covariance[i][j] - k * ca) <= 1e-6 * sqrt(
            c.covariance[i][i] * c.covariance[j][j]), ("size: (%d, %d)"):format(i, j))
        end
      end
    end)

    it("is finite, symmetric and positive definite on degenerate and extreme views", function()
      local rng = G.rng(1304)
      local cases = {
        { "face-on, exact", CAMERA, 0.05, { width = 100, tilt = 0, u = 331.2, v = 228.7 }, 0 },
        { "face-on, noisy", CAMERA, 0.05, { width = 100, tilt = 0 }, 0.5 },
        { "tiny", CAMERA, 0.024, { width = 8.5, tilt = rad(20) }, 0.5 },
        { "tiny, exact", CAMERA, 0.024, { width = 8.5, tilt = rad(5) }, 0 },
        { "extremely tilted", CAMERA, 0.05, { width = 200, tilt = rad(87) }, 0.5 },
        { "1e-9 tag", CAMERA, 1e-9, { width = 60, tilt = rad(30) }, 0.5 },
        { "1e9 tag", CAMERA, 1e9, { width = 60, tilt = rad(30) }, 0.5 },
        { "long focal length", { fx = 1e5, fy = 9.7e4, cx = 320, cy = 240 }, 0.1,
          { width = 80, tilt = rad(30), u = 330, v = 250 }, 0.5 },
        { "short focal length", { fx = 30, fy = 45, cx = 320, cy = 240 }, 0.1,
          { width = 40, tilt = rad(30), u = 300, v = 250 }, 0.5 },
        { "through a lens", { fx = 700, fy = 700, cx = 640, cy = 360,
          distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4 } }, 0.1,
          { width = 60, tilt = rad(40), u = 1000, v = 500 }, 0.5 },
      }
      for _, case in ipairs(cases) do
        local name, cam, size, opts, sigma = case[1], case[2], case[3], case[4], case[5]
        for k = 1, 5 do
          local r, t = G.random_pose(rng, cam, size, opts)
          local px = G.project(cam, r, t, size)
          if sigma > 0 then px = noisy(px, rng, sigma) end
          for _, o in ipairs({ {}, { sigma = 0.3 }, { method = "seed" } }) do
            local label = ("%s %d %s"):format(name, k, o.method or o.sigma or "default")
            local pose = tagpose.solve(px, cam, size, o)
            if pose then
              assert.is_true(is_spd(pose.covariance), label)
              if o.method ~= "seed" then
                local c = pose.confidence
                assert.is_true(c >= 0 and c <= 1, label)
                if pose.alternative then
                  assert.is_true(is_spd(pose.alternative.covariance), label .. " alternative")
                  assert.equal(1 - c, pose.alternative.confidence)
                else
                  assert.equal(1, c)
                end
              end
            end
          end
        end
      end
    end)
  end)

  describe("confidence", function()
    it("is as often right as it says, over ambiguous views drawn like the model's prior", function()
      local rng = G.rng(1305)
      local s, sigma, n = 0.024, 1, 700
      local sum, right, z, ok = 0, 0, {}, {}
      for _ = 1, n do
        local r, t = G.random_pose(rng, CAMERA, s, { width = rng.uniform(15, 80),
          tilt = rng.uniform(0, rad(75)) })
        local px = G.project(CAMERA, r, t, s)
        local pose = assert(tagpose.solve(noisy(px, rng, sigma), CAMERA, s, { sigma = sigma }))
        local alt = pose.alternative
        if alt and rotation.angle(rotation.from_nested(pose.rotation),
          rotation.from_nested(alt.rotation)) > rad(10) then
          local c = math.min(math.max(pose.confidence, 1e-9), 1 - 1e-9)
          z[#z + 1] = math.log(c / (1 - c))
          ok[#ok + 1] = true_branch(pose, r, t) == pose
          sum = sum + pose.confidence
          if ok[#ok] then right = right + 1 end
        end
      end
      local count = #z
      -- mean confidence against the frequency of the right branch, within sampling error
      local mean, freq = sum / count, right / count
      assert.is_true(count > 300)
      assert.is_true(abs(mean - freq) < 4 * sqrt(0.25 / count),
        ("confidence %.3f, right %.3f of %d"):format(mean, freq, count))
      -- and the calibration slope: the β that makes logistic(β logit(confidence)) fit the
      -- outcomes best (maximum likelihood, Newton) is 1 for a calibrated confidence (here 1.2:
      -- SPREAD holds the middle range back on purpose); log-odds doubled give 0.74, halved 2.3
      local beta = 1
      for _ = 1, 30 do
        local g, h = 0, 0
        for i = 1, count do
          local y = ok[i] and 1 or 0
          local p = 1 / (1 + math.exp(-beta * z[i]))
          g, h = g + (y - p) * z[i], h + p * (1 - p) * z[i] * z[i]
        end
        beta = beta + g / h
      end
      assert.is_true(beta > 0.85 and beta < 1.65, ("calibration slope %.3f"):format(beta))
      -- and it is informative: neither always 1/2 nor always 1
      assert.is_true(mean > 0.6 and mean < 0.95, ("mean confidence %.3f"):format(mean))
    end)

    it("is 1 for the one minimum, and the alternative's is its complement", function()
      local px = { { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } }
      local pose = assert(tagpose.solve(px, CAMERA, 0.05, { sigma = 0.5 }))
      if pose.alternative then
        assert.equal(1 - pose.confidence, pose.alternative.confidence)
      else
        assert.equal(1, pose.confidence)
      end
    end)

    it("is near 1 for a clearly better fit at small σ, and the prior's split at large σ", function()
      local rng = G.rng(1306)
      local s = 0.024
      local r, t = G.random_pose(rng, CAMERA, s, { width = 60, tilt = rad(25) })
      local px = noisy(G.project(CAMERA, r, t, s), rng, 0.05)
      local pose = assert(tagpose.solve(px, CAMERA, s, { sigma = 0.05 }))
      assert.is_true(pose.alternative ~= nil and pose.confidence > 0.99, tostring(pose.confidence))
      local big = assert(tagpose.solve(px, CAMERA, s, { sigma = 1e3 })).confidence
      local bigger = assert(tagpose.solve(px, CAMERA, s, { sigma = 1e4 })).confidence
      -- the residuals' evidence vanishes: what is left does not depend on σ (the volumes of the
      -- two basins and the tilt prior), and is no decision
      assert.is_true(abs(big - bigger) < 1e-3 and abs(big - 0.5) < 0.1, ("%.4f %.4f"):format(big,
        bigger))
    end)

    it("is not capped where the residuals decide the branch", function()
      -- the other candidate fits worse by Δχ² > 200: its branch is e^100 times less likely
      -- whatever the basins' volumes (a few units of log-odds), and a confidence of 0.995 would
      -- claim one such pose in 200 wrong
      local rng = G.rng(1308)
      local s, sigma, decided = 0.024, 0.2, 0
      for _ = 1, 40 do
        local r, t = G.random_pose(rng, CAMERA, s, { width = rng.uniform(40, 120),
          tilt = rng.uniform(rad(20), rad(70)) })
        local px = noisy(G.project(CAMERA, r, t, s), rng, sigma)
        local pose = assert(tagpose.solve(px, CAMERA, s, { sigma = sigma }))
        local alt = pose.alternative
        if alt and 4 * (alt.error ^ 2 - pose.error ^ 2) / sigma ^ 2 > 200 then
          decided = decided + 1
          assert.equal(pose, true_branch(pose, r, t))
          assert.is_true(pose.confidence > 1 - 1e-4, ("%.6f"):format(pose.confidence))
          assert.is_true(alt.confidence < 1e-4)
        end
      end
      assert.is_true(decided >= 10, tostring(decided))
    end)

    it("with a prior, is the tracker's posterior, on the true branch after a track", function()
      local rng = G.rng(1307)
      local s, sigma = 0.024, 0.8
      local r, t = G.random_pose(rng, CAMERA, s, { width = 40, tilt = rad(30) })
      local px = G.project(CAMERA, r, t, s)
      local prior = nil
      for k = 1, 30 do
        prior = assert(tagpose.solve(noisy(px, rng, sigma), CAMERA, s, { sigma = sigma,
          prior = prior }))
        if prior.alternative and k > 1 then
          -- the state's posterior of the frame's first candidate by error, calibrated
          local p_first = prior.track.first
          local first = prior.error <= prior.alternative.error
          local expected = track.confidence(first and p_first or 1 - p_first)
          assert.is_true(abs(prior.confidence - expected) < 1e-12)
          assert.equal(1 - prior.confidence, prior.alternative.confidence)
        end
      end
      assert.is_true(true_branch(prior, r, t) == prior)
      assert.is_true(prior.confidence > 0.5)
    end)
  end)

  describe("log_odds()", function()
    it("is antisymmetric and its probability the confidence solve reports", function()
      local rng = G.rng(1308)
      local refine = require("tagpose.core.refine")
      local s, sigma = 0.024, 0.7
      for k = 1, 20 do
        local r, t = G.random_pose(rng, CAMERA, s, { width = rng.uniform(15, 60),
          tilt = rng.uniform(0, rad(40)) })
        local c = noisy(G.project(CAMERA, r, t, s), rng, sigma)
        local pose = assert(tagpose.solve(c, CAMERA, s, { sigma = sigma }))
        if pose.alternative then
          local px = {}
          for i = 1, 4 do px[2 * i - 1], px[2 * i] = c[i][1], c[i][2] end
          local function record(p)
            local rr = rotation.from_nested(p.rotation)
            local q = p.position
            local normal = {}
            local sse = refine.normal(CAMERA, px, s / 2, rr, q.x, q.y, q.z, normal)
            return { r = rr, tx = q.x, ty = q.y, tz = q.z, sse = sse, normal = normal }
          end
          local a, b = record(pose), record(pose.alternative)
          local lab, lba = uncertainty.log_odds(a, b, sigma ^ 2), uncertainty.log_odds(b, a,
            sigma ^ 2)
          assert.is_true(abs(lab + lba) <= 1e-9 * (1 + abs(lab)), "case " .. k)
          -- (solve's normal equations are those of refine's last linearisation, at most one
          -- step from the pose: its H differs a little from the one at the pose)
          assert.is_true(abs(uncertainty.probability(lab) - pose.confidence) < 0.1,
            ("case %d: %.6f vs %.6f"):format(k, uncertainty.probability(lab), pose.confidence))
        end
      end
    end)
  end)

  describe("noise() and ellipsoid()", function()
    local Q6 = 12.591587243743977 -- χ²(6; 0.95)

    it("takes a given σ as it is, the covariance without a factor", function()
      local s2, kappa = uncertainty.noise(123, 0.3, 22)
      assert.near(0.09, s2, 1e-15)
      assert.equal(1, kappa)
    end)

    it("tops the residuals up with the default to DEFAULT_DOF + 2 degrees of freedom", function()
      local d2, top = uncertainty.DEFAULT_SIGMA ^ 2, uncertainty.DEFAULT_DOF + 2
      -- one tag's frame: the default pooled with its 2 (the single-tag rule)
      assert.near((uncertainty.DEFAULT_DOF * d2 + 0.7) / top, uncertainty.noise(0.7), 1e-15)
      assert.near((uncertainty.DEFAULT_DOF * d2 + 0.7) / top, uncertainty.noise(0.7, nil, 2),
        1e-15)
      assert.near(((top - 6) * d2 + 0.7) / top, uncertainty.noise(0.7, nil, 6), 1e-15)
      -- a block of two faces (10) or a frame of 22: the residuals alone, whatever σ they show
      assert.near(2.3 / 10, uncertainty.noise(2.3, nil, 10), 1e-15)
      assert.near(0.09, uncertainty.noise(22 * 0.09, nil, 22), 1e-15)
      assert.near(4, uncertainty.noise(22 * 4, nil, 22), 1e-15)
    end)

    it("is Student's from 10 degrees of freedom on: 6 F(6, ν; 0.95) / χ²(6; 0.95)", function()
      -- published 95 % points of F with 6 and ν degrees of freedom
      for _, c in ipairs({ { 10, 3.2172 }, { 12, 2.9961 }, { 20, 2.5990 }, { 30, 2.4205 },
        { 40, 2.3359 }, { 60, 2.2541 }, { 120, 2.1750 } }) do
        local nu, f = c[1], c[2]
        local s2, kappa = uncertainty.noise(nu, nil, nu)
        assert.near(1, s2, 1e-15)
        assert.near(6 * f / Q6, kappa, 2e-3 * kappa, "ν = " .. nu)
        assert.equal(kappa, uncertainty.ellipsoid(nu))
      end
      assert.near(1, uncertainty.ellipsoid(1e6), 1e-4)
    end)

    it("holds 95 % with fewer, σ being the default's (Monte-Carlo)", function()
      -- the errors' Mahalanobis² at the true σ is χ²₆, the residuals' sum χ²_ν, independent
      local rng = G.rng(4711)
      local function chi2(k)
        local sum = 0
        for _ = 1, k do sum = sum + rng.normal() ^ 2 end
        return sum
      end
      local top, n = uncertainty.DEFAULT_DOF + 2, 20000
      for _, nu in ipairs({ 2, 4, 8 }) do
        local kappa, inside = uncertainty.ellipsoid(nu), 0
        for _ = 1, n do
          if chi2(6) < kappa * Q6 * (top - nu + chi2(nu)) / top then inside = inside + 1 end
        end
        local share = inside / n
        assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n),
          ("ν = %d: %.4f inside"):format(nu, share))
      end
    end)

    it("is the table bench/ellipsoid_table.lua computes", function()
      local text, status = run.script("bench/ellipsoid_table.lua")
      assert.equal(0, status, text)
      local numbers = {}
      for v in text:match("ELLIPSOID = (%b{})"):gmatch("[%d.]+") do
        numbers[#numbers + 1] = tonumber(v)
      end
      assert.equal(20, #numbers)
      for i, v in ipairs(numbers) do
        assert.near(v, uncertainty.ellipsoid(2 * i), 1e-12, "ν = " .. 2 * i)
      end
      -- and beyond the table, the tail is within 0.2 % of the exact factor
      local checked = 0
      for exact, tail in text:gmatch("exact ([%d.]+), tail ([%d.]+)") do
        assert.is_true(abs(tonumber(tail) / tonumber(exact) - 1) < 2e-3, text)
        checked = checked + 1
      end
      assert.equal(2, checked)
    end)
  end)

  describe("options", function()
    it("refuses a sigma that is not a positive number", function()
      local px = { { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } }
      for _, bad in ipairs({ 0, -1, 0 / 0, "1" }) do
        local msg = assertions.raised(function()
          tagpose.solve(px, CAMERA, 0.05, { sigma = bad })
        end, "uncertainty_spec.lua")
        assert.truthy(msg:find("bad argument #4 to 'solve' (options.sigma: positive number "
          .. "expected", 1, true), msg)
      end
    end)

    it("reuses the covariance tables of options.into: nothing allocated after warm-up", function()
      if rawget(_G, "jit") then return end -- (LuaJIT's count includes its own traces)
      local rng = G.rng(1309)
      local s = 0.024
      local r, t = G.random_pose(rng, CAMERA, s, { width = 30, tilt = rad(15) })
      local px = G.project(CAMERA, r, t, s)
      local frames = {}
      for k = 1, 50 do frames[k] = noisy(px, rng, 0.5) end
      local into = {}
      local options = { sigma = 0.5, into = into }
      for k = 1, 50 do tagpose.solve(frames[k], CAMERA, s, options) end
      local cov, alt = into.covariance, into.alternative
      collectgarbage("collect")
      collectgarbage("stop")
      -- (the first solve after a full collection regrows the VM's own buffers)
      tagpose.solve(frames[1], CAMERA, s, options)
      local before = collectgarbage("count")
      for k = 1, 50 do tagpose.solve(frames[k], CAMERA, s, options) end
      local grown = collectgarbage("count") - before
      collectgarbage("restart")
      assert.equal(cov, into.covariance)
      if alt and into.alternative then assert.equal(alt.covariance, into.alternative.covariance) end
      assert.is_true(grown < 0.5, ("%.2f KB allocated"):format(grown))
    end)
  end)
end)
