local tagpose = require("tagpose")
local track = require("tagpose.track")
local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")

local rad, deg, sin, pi = math.rad, math.deg, math.sin, math.pi

local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }
local SIZE = 0.024

local function noisy(rng, px, sigma)
  local out = {}
  for i = 1, 4 do out[i] = { px[i][1] + sigma * rng.normal(), px[i][2] + sigma * rng.normal() } end
  return out
end

local function angle_to(r, pose)
  return deg(rotation.angle(r, rotation.from_nested(pose.rotation)))
end

-- a pose whose normal is tilted by the signed angle `tilt` along a fixed direction: the tag
-- passes face-on where the sign changes
local function tilted(tilt, opts, k)
  local azimuth = opts.azimuth
  if tilt < 0 then tilt, azimuth = -tilt, azimuth + pi end
  return geometry.random_pose(nil, camera, SIZE, { width = opts.width, tilt = tilt,
    azimuth = azimuth, roll = opts.roll + 0.002 * k, u = opts.u + (opts.du or 0.2) * k,
    v = opts.v })
end

-- a smooth trajectory: frame k -> pose (r, t)
local function wobble(k, opts)
  return tilted(opts.tilt0 + opts.amplitude * sin(2 * pi * k / opts.period), opts, k)
end

-- solve a sequence; returns the number of frames whose pose is more than 30 degrees off
local function run(rng, frames, opts, tracked, start_prior)
  local prior, flips, last = start_prior, 0, nil
  for k = 0, frames - 1 do
    local r, t = wobble(k, opts)
    local px = noisy(rng, geometry.project(camera, r, t, SIZE), opts.sigma)
    local pose = assert(tagpose.solve(px, camera, SIZE, { prior = tracked and prior or nil }))
    if angle_to(r, pose) > 30 then flips = flips + 1 end
    prior, last = pose, { r = r, pose = pose }
  end
  return flips, last
end

-- a tag tilted from +30° to -30° through face-on at a steady rate (20°/s at 30 frames/s);
-- `times(k)` the time of frame k, `skip(k)` true for a missed frame. Returns the frames after
-- the crossing whose tracked pose, and whose best-fitting pose, is more than 30° off.
local function crossing(seed, times, skip)
  local rng = geometry.rng(seed)
  local opts = { width = 40, azimuth = 0.7, roll = 0.3, u = 250, v = 260, du = 1 }
  local prior, tracked, alone = nil, 0, 0
  for k = 0, 59 do
    local tilt = rad(30 - 60 * k / 59)
    local r, t = tilted(tilt, opts, k)
    local px = noisy(rng, geometry.project(camera, r, t, SIZE), 0.5)
    if not (skip and skip(k)) then
      local pose = assert(tagpose.solve(px, camera, SIZE, { prior = prior, time = times(k) }))
      -- every frame's state is one the next frame takes (none of its weights lost)
      assert(track.is_state(pose.track), "a state at frame " .. k)
      if tilt < 0 then
        if angle_to(r, pose) > 30 then tracked = tracked + 1 end
        if angle_to(r, assert(tagpose.solve(px, camera, SIZE))) > 30 then alone = alone + 1 end
      end
      prior = pose
    end
  end
  return tracked, alone
end

local function thirtieths(k) return k / 30 end

describe("tracking with options.prior", function()
  it("flips far less than choosing by the error alone on small, nearly frontal tags", function()
    local opts = { width = 30, tilt0 = rad(10), amplitude = rad(14), period = 160,
      azimuth = 0.7, roll = 0.3, u = 250, v = 260, sigma = 0.5 }
    local plain = run(geometry.rng(11), 320, opts, false)
    local tracked = run(geometry.rng(11), 320, opts, true)
    assert.is_true(plain >= 20, "the sequence is ambiguous enough to test: " .. plain)
    -- (one draw of a tag dipping just past face-on and back: over 40 draws of it the filter
    -- flips 363 rows of the 1840 that the error alone flips, 335 before its likelihood of the
    -- squared tilt; on this one 15 of 52, 9 before)
    assert.is_true(tracked * 3 <= plain, ("tracked %d flips, untracked %d"):format(tracked, plain))
  end)

  it("keeps the branch through a face-on crossing, by the rate it carries", function()
    local tracked, alone = 0, 0
    for seed = 1, 12 do
      local a, b = crossing(seed, thirtieths)
      tracked, alone = tracked + a, alone + b
    end
    -- without the rate (forgotten at once) the crossing is a new start
    local process = track.PROCESS
    track.PROCESS = 1e4
    local ok, forgetful = pcall(function()
      local n = 0
      for seed = 1, 12 do n = n + crossing(seed, thirtieths) end
      return n
    end)
    track.PROCESS = process
    assert(ok, forgetful)
    -- 12 crossings x 30 frames after each
    assert.is_true(alone >= 30, "the crossings are ambiguous enough to test: " .. alone)
    assert.is_true(tracked * 3 <= alone, ("tracked %d flips, alone %d"):format(tracked, alone))
    assert.is_true(tracked * 2 <= forgetful,
      ("tracked %d flips, without the rate %d"):format(tracked, forgetful))
  end)

  it("takes missed frames and uneven spacing into account through options.time", function()
    local tracked, alone = 0, 0
    local jitter = geometry.rng(99)
    local offsets = {}
    for k = 0, 59 do offsets[k] = (k + jitter.uniform(-0.3, 0.3)) / 30 end
    for seed = 1, 12 do
      -- a third of the frames missed, in runs, and the rest unevenly spaced
      local a, b = crossing(seed, function(k) return offsets[k] end,
        function(k) return k % 6 >= 4 end)
      tracked, alone = tracked + a, alone + b
    end
    assert.is_true(alone >= 20, "ambiguous enough: " .. alone)
    assert.is_true(tracked * 4 <= alone, ("tracked %d flips, alone %d"):format(tracked, alone))
  end)

  it("leaves a track that started on the wrong branch", function()
    -- a tilted tag, where the frames clearly favour the true pose; the track starts certain
    -- of the mirrored pose
    local opts = { width = 60, tilt0 = rad(35), amplitude = rad(5), period = 200,
      azimuth = 1.1, roll = 0.2, u = 300, v = 200, sigma = 0.5 }
    local r0, t0 = wobble(0, opts)
    local wrong = {}
    require("tagpose.core.refine").mirror(r0, t0[1], t0[2], t0[3], wrong)
    local qw = { rotation.to_quaternion(wrong) }
    local qt = { rotation.to_quaternion(r0) }
    -- certain of the mirrored pose: its path has all but e⁻³⁰ of the weight
    local state = track.from_pose(track.new_state(), qw, t0, qt, t0,
      { first = 1 - math.exp(-30) })
    local prior = { quaternion = { w = qw[1], x = qw[2], y = qw[3], z = qw[4] }, track = state }
    local rng = geometry.rng(5)
    local first_right
    for k = 0, 29 do
      local r, t = wobble(k, opts)
      local pose = assert(tagpose.solve(noisy(rng, geometry.project(camera, r, t, SIZE), 0.5),
        camera, SIZE, { prior = prior, time = k / 30 }))
      if angle_to(r, pose) < 10 then
        first_right = first_right or k
      else
        assert.is_nil(first_right, "went back to the wrong branch at frame " .. k)
      end
      prior = pose
    end
    -- (six frames of evidence against e⁻³⁰: while σ is an estimate of few degrees of freedom
    -- the evidence of each frame is tempered, its Student-t form)
    assert.is_true(first_right ~= nil and first_right <= 6,
      "recovered at " .. tostring(first_right))
  end)

  it("never keeps a clearly worse fit for the sake of the prior", function()
    local rng = geometry.rng(8)
    local checked = 0
    for _ = 1, 20 do
      local r, t = geometry.random_pose(rng, camera, SIZE, { width = 120, tilt = rad(55) })
      local px = noisy(rng, geometry.project(camera, r, t, SIZE), 0.3)
      local free = assert(tagpose.solve(px, camera, SIZE))
      if free.alternative and free.alternative.error > 3 * free.error + 1 then
        -- a prior certain of the other branch, at rest where that branch is
        local a, b = free.alternative, free
        local qa = { a.quaternion.w, a.quaternion.x, a.quaternion.y, a.quaternion.z }
        local qb = { b.quaternion.w, b.quaternion.x, b.quaternion.y, b.quaternion.z }
        local p = { a.position.x, a.position.y, a.position.z }
        local state = track.from_pose(track.new_state(), qa, p, qb, p,
          { first = 1 - 1e-15, variance = 1e-6, sigma2 = 0.09 })
        local pose = assert(tagpose.solve(px, camera, SIZE, { prior = { quaternion =
          a.quaternion, track = state } }))
        checked = checked + 1
        assert.near(free.error, pose.error, 1e-12)
      end
    end
    assert.is_true(checked >= 5, "cases with a clearly worse alternative: " .. checked)
  end)

  it("takes a pose of the caller's own as the prior", function()
    local r, t = geometry.random_pose(geometry.rng(3), camera, SIZE, { width = 50, tilt = 0.5 })
    local px = geometry.project(camera, r, t, SIZE)
    local q = { rotation.to_quaternion(r) }
    local pose = assert(tagpose.solve(px, camera, SIZE,
      { prior = { quaternion = { w = q[1], x = q[2], y = q[3], z = q[4] } } }))
    assert.rotation_near(r, pose.rotation, 1e-6)
    pose = assert(tagpose.solve(px, camera, SIZE,
      { prior = { rotation = geometry.nested(r), position = { x = t[1], y = t[2], z = t[3] } } }))
    assert.rotation_near(r, pose.rotation, 1e-6)
    assert.is_true(track.is_state(pose.track))
    -- a state this filter did not write (an older version's ten numbers) is not trusted
    pose = assert(tagpose.solve(px, camera, SIZE, { prior = { rotation = geometry.nested(r),
      track = { 1, 0, 0, 0, 1, 0, 0, 0, 50, 0.25 } } }))
    assert.rotation_near(r, pose.rotation, 1e-6)
    assert.has_error(function()
      tagpose.solve(px, camera, SIZE, { prior = { position = {} } })
    end, "bad argument #4 to 'solve' (options.prior: pose with a finite quaternion or rotation "
      .. "expected)")
    assert.has_error(function()
      tagpose.solve(px, camera, SIZE, { time = 0 / 0 })
    end, "bad argument #4 to 'solve' (options.time: finite number expected, got NaN)")
  end)

  it("gives the tracked pose its posterior as confidence, the alternative the rest", function()
    -- a small tag held at 15°: each frame says little, the frames together much
    local opts = { width = 30, tilt0 = rad(15), amplitude = 0, period = 100, azimuth = 0.7,
      roll = 0.3, u = 250, v = 260 }
    local rng, prior = geometry.rng(21), nil
    local alone, tracked, right = 0, 0, 0
    for k = 0, 99 do
      local r, t = wobble(k, opts)
      local px = noisy(rng, geometry.project(camera, r, t, SIZE), 0.5)
      local pose = assert(tagpose.solve(px, camera, SIZE, { prior = prior, time = k / 30 }))
      assert.is_true(pose.confidence >= 0.5 and pose.confidence <= 1)
      if pose.alternative then
        assert.near(1 - pose.confidence, pose.alternative.confidence, 1e-15)
      end
      if k >= 30 then
        alone = alone + assert(tagpose.solve(px, camera, SIZE)).confidence
        tracked = tracked + pose.confidence
        if angle_to(r, pose) < 15 then right = right + 1 end
      end
      prior = pose
    end
    assert.is_true(right >= 65, "right branch in " .. right .. " of 70 frames")
    assert.is_true(tracked / 70 > 0.8 and alone / 70 < 0.7,
      ("mean confidence tracked %.3f, alone %.3f"):format(tracked / 70, alone / 70))
  end)

  describe("tagpose.track", function()
    -- a candidate record as the filter takes it: a pose and its residuals
    local function candidate(r, t, sse)
      local w, x, y, z = rotation.to_quaternion(r)
      return { qw = w, qx = x, qy = y, qz = z, tx = t[1], ty = t[2], tz = t[3], sse = sse }
    end

    it("gives a tilt vector whose mirror is its opposite", function()
      local rng = geometry.rng(4)
      for _ = 1, 20 do
        local r, t = geometry.random_pose(rng, camera, SIZE, { width = 60, max_tilt = rad(70) })
        local m = {}
        require("tagpose.core.refine").mirror(r, t[1], t[2], t[3], m)
        local w, x, y, z = rotation.to_quaternion(r)
        local ax, ay = track.tilt(w, x, y, z, t[1], t[2], t[3])
        w, x, y, z = rotation.to_quaternion(m)
        local bx, by = track.tilt(w, x, y, z, t[1], t[2], t[3])
        assert.near(-ax, bx, 1e-9)
        assert.near(-ay, by, 1e-9)
        -- its size is the sine of the tilt from the line of sight
        local d = math.sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
        local c = (r[3] * t[1] + r[6] * t[2] + r[9] * t[3]) / d
        assert.near(math.sqrt(1 - c * c), math.sqrt(ax * ax + ay * ay), 1e-9)
      end
    end)

    it("keeps a valid state, in place, and returns the better-supported candidate", function()
      local r, t = geometry.random_pose(geometry.rng(6), camera, SIZE, { width = 60, tilt = 0.6 })
      local m = {}
      require("tagpose.core.refine").mirror(r, t[1], t[2], t[3], m)
      local state = track.new_state()
      local pick, p = track.step(nil, candidate(r, t, 1.0), candidate(m, t, 1.2), 40, 0, state)
      assert.equal(1, pick)
      assert.is_true(p > 0.5 and p < 1)
      assert.same({ 0.5, 0.5 }, { state.back_first, state.back_second })
      assert.is_true(track.is_state(state))
      -- the second candidate now fits much better, for many frames: it wins, and the
      -- smoothing numbers say the previous frame's choice was the second too
      for k = 1, 10 do
        pick, p = track.step(state, candidate(r, t, 5.0), candidate(m, t, 0.1), 40, k / 30,
          state)
      end
      assert.equal(2, pick)
      assert.is_true(p > 0.99)
      local a, b = state.back_first, state.back_second
      assert.is_true(a >= 0 and a <= 1 and b >= 0 and b < 0.1, ("a %.3f b %.3f"):format(a, b))
      assert.is_true(track.is_state(state))
      assert.is_true(state.count >= 1 and state.count <= track.HYPOTHESES)
      -- one candidate: it is the choice, with certainty
      pick, p = track.step(state, candidate(r, t, 0.5), nil, 40, 1, state)
      assert.same({ 1, 1 }, { pick, p })
      -- an evidence of the caller's own replaces the reprojection errors
      pick = track.step(nil, candidate(r, t, 1.0), candidate(m, t, 1.0), 40, 0,
        track.new_state(), -8)
      assert.equal(2, pick)
      -- a copy is a state of its own
      local copy = track.copy(state)
      assert.is_true(track.is_state(copy) and copy ~= state)
      assert.same(state.hypotheses, copy.hypotheses)
    end)

    it("keeps finite states however strong or weak the evidence", function()
      local r, t = geometry.random_pose(geometry.rng(7), camera, SIZE, { width = 60, tilt = 0.6 })
      local m = {}
      require("tagpose.core.refine").mirror(r, t[1], t[2], t[3], m)
      local rng = geometry.rng(17)
      local state
      for k = 0, 200 do
        -- evidence from overwhelming (either way) to none, in a random order
        local llr = ({ 1e6, -1e6, 700, -700, 0, 1e-300, 40 })[math.floor(rng.uniform(1, 8))]
        local out = track.new_state()
        track.step(state, candidate(r, t, 1), candidate(m, t, 1), 40, k / 30, out, llr)
        assert(track.is_state(out), "a state after frame " .. k)
        state = out
      end
      -- a state damaged by its holder (not a number in it) starts again, finite
      state.hypotheses[1] = 0 / 0
      local pick, p = track.step(state, candidate(r, t, 1), candidate(m, t, 2), 40, 10, state)
      assert.is_true(pick == 1 and p == p and track.is_state(state))
    end)

    it("estimates the noise from the chosen candidate, the single frame's default first", function()
      local uncertainty = require("tagpose.uncertainty")
      -- no estimate yet: the single-frame default, to the bit
      local s2, dof = track.noise(0, 0, 3)
      assert.equal(uncertainty.noise(3), s2)
      assert.equal(track.NOISE_DOF + 2, dof)
      assert.equal(track.NOISE_SIGMA, uncertainty.DEFAULT_SIGMA)
      assert.equal(track.NOISE_DOF, uncertainty.DEFAULT_DOF)
      -- then the estimate's weight decays by NOISE_MEMORY a frame, two degrees of freedom a frame
      local keep = 1 - track.NOISE_MEMORY
      local s2b, dofb = track.noise(s2, dof, 0.4)
      assert.near((keep * dof * s2 + 0.4) / (keep * dof + 2), s2b, 1e-15)
      assert.near(keep * dof + 2, dofb, 1e-15)
      assert.near(s2b * dofb / (dofb - 2), track.noise_mean(s2b, dofb), 1e-15)
      -- on a far tag near face-on, where the better fit is often the wrong branch, the
      -- estimate is not biased low (the better fit's residuals are: the smaller of two)
      local rng = geometry.rng(21)
      local opts = { width = 30, tilt0 = rad(8), amplitude = rad(6), period = 90, azimuth = 0.4,
        roll = 0.1, u = 300, v = 240 }
      local prior, sum, low, n = nil, 0, 0, 0
      for k = 0, 299 do
        local r, t = wobble(k, opts)
        local pose = assert(tagpose.solve(noisy(rng, geometry.project(camera, r, t, SIZE), 1),
          camera, SIZE, { prior = prior, time = k / 30 }))
        if k >= 100 then
          local alt = pose.alternative
          sum, n = sum + pose.track.sigma2, n + 1
          low = low + 0.5 * math.min(pose.error, alt and alt.error or pose.error) ^ 2 * 4
        end
        prior = pose
      end
      assert.is_true(sum / n > 0.9 and sum / n < 1.1, ("σ² estimated %.3f px²"):format(sum / n))
      assert.is_true(low / n < 0.9, ("the better fit's residuals say %.3f px²"):format(low / n))
    end)

    it("tempers a frame's evidence while σ² is an estimate of few degrees of freedom", function()
      local x = track.EVIDENCE_TO
      -- σ² known (no degrees of freedom given): κ (sse2 - sse1) / 2σ²
      assert.near(track.EVIDENCE_MAX * (9 - 1) / (2 * 0.25), track.evidence(1, 9, 0.25, x),
        1e-12)
      -- tends to it as the degrees of freedom grow, tempered below it, antisymmetric
      assert.near(track.evidence(1, 9, 0.25, x), track.evidence(1, 9, 0.25, x, 1e9), 1e-6)
      local last = 0
      for _, dof in ipairs({ 2, 10, 20, 100, 1000 }) do
        local e = track.evidence(1, 9, 0.25, x, dof)
        assert.is_true(e > last and e < track.evidence(1, 9, 0.25, x))
        assert.near(-e, track.evidence(9, 1, 0.25, x, dof), 1e-12)
        last = e
      end
      -- none near face-on
      assert.equal(0, track.evidence(1, 9, 0.25, track.EVIDENCE_FROM, 10))
    end)

    it("calibrates the confidence as a monotone map onto [0.5, 1]", function()
      assert.equal(0.5, track.confidence(0.5))
      assert.equal(1, track.confidence(1))
      local last = 0.5
      for p = 0.55, 0.999, 0.05 do
        local c = track.confidence(p)
        assert.is_true(c > last and c <= p)
        last = c
      end
    end)
  end)
end)
