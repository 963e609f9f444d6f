local tagpose = require("tagpose")
local track = require("tagpose.track")
local rotation = require("tagpose.rotation")
local geometry = require("support.geometry")

local rad, deg, sin, pi = math.rad, math.deg, math.sin, math.pi

local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }

local function noisy(rng, px, sigma)
  local out = {}
  for i = 1, 4 do out[i] = { px[i][1] + sigma * rng.normal(), px[i][2] + sigma * rng.normal() } end
  return out
end

local function angle_to(r, pose)
  return deg(rotation.angle(r, rotation.from_nested(pose.rotation)))
end

-- a smooth trajectory: frame k -> pose (r, t)
local function wobble(k, opts)
  local tilt = opts.tilt0 + opts.amplitude * sin(2 * pi * k / opts.period)
  local azimuth = opts.azimuth
  if tilt < 0 then tilt, azimuth = -tilt, azimuth + pi end
  return geometry.random_pose(nil, camera, 0.024, { width = opts.width, tilt = tilt,
    azimuth = azimuth, roll = opts.roll + 0.002 * k, u = opts.u + 0.2 * k, v = opts.v })
end

-- solve a sequence; returns the number of frames whose pose is more than 30 degrees off
local function run(rng, frames, opts, tracked, start_prior)
  local prior, flips, last = start_prior, 0, nil
  for k = 0, frames - 1 do
    local r, t = wobble(k, opts)
    local px = noisy(rng, geometry.project(camera, r, t, 0.024), opts.sigma)
    local pose = assert(tagpose.solve(px, camera, 0.024, { prior = tracked and prior or nil }))
    if angle_to(r, pose) > 30 then flips = flips + 1 end
    prior, last = pose, { r = r, pose = pose }
  end
  return flips, last
end

describe("tracking with options.prior", function()
  it("flips far less than choosing by the error alone on small, nearly frontal tags", function()
    local opts = { width = 30, tilt0 = rad(10), amplitude = rad(14), period = 160,
      azimuth = 0.7, roll = 0.3, u = 250, v = 260, sigma = 0.5 }
    local plain = run(geometry.rng(11), 320, opts, false)
    local tracked = run(geometry.rng(11), 320, opts, true)
    assert.is_true(plain >= 20, "the sequence is ambiguous enough to test: " .. plain)
    assert.is_true(tracked * 4 <= plain, ("tracked %d flips, untracked %d"):format(tracked, plain))
  end)

  it("leaves a track that started on the wrong branch", function()
    -- a tilted tag, where the frames clearly favour the true pose; the track starts certain
    -- of the mirrored pose (the most a track can carry)
    local opts = { width = 60, tilt0 = rad(35), amplitude = rad(5), period = 200,
      azimuth = 1.1, roll = 0.2, u = 300, v = 200, sigma = 0.5 }
    local r0, t0 = wobble(0, opts)
    local wrong = {}
    require("tagpose.refine").mirror(r0, t0[1], t0[2], t0[3], wrong)
    local qw = { rotation.to_quaternion(wrong) }
    local qt = { rotation.to_quaternion(r0) }
    local prior = { quaternion = { w = qw[1], x = qw[2], y = qw[3], z = qw[4] },
      track = { qw[1], qw[2], qw[3], qw[4], qt[1], qt[2], qt[3], qt[4], 1e6, 0.25 } }
    local rng = geometry.rng(5)
    local first_right
    for k = 0, 29 do
      local r, t = wobble(k, opts)
      local pose = assert(tagpose.solve(noisy(rng, geometry.project(camera, r, t, 0.024), 0.5),
        camera, 0.024, { prior = prior }))
      if angle_to(r, pose) < 10 then
        first_right = first_right or k
      else
        assert.is_nil(first_right, "went back to the wrong branch at frame " .. k)
      end
      prior = pose
    end
    assert.is_true(first_right ~= nil and first_right <= 5,
      "recovered at " .. tostring(first_right))
  end)

  it("never keeps a clearly worse fit for the sake of the prior", function()
    local rng = geometry.rng(8)
    local lmax = math.log((1 - track.SWITCH) / track.SWITCH)
    local checked = 0
    for _ = 1, 20 do
      local r, t = geometry.random_pose(rng, camera, 0.024, { width = 120, tilt = rad(55) })
      local px = noisy(rng, geometry.project(camera, r, t, 0.024), 0.3)
      local free = assert(tagpose.solve(px, camera, 0.024))
      if free.alternative then
        -- a prior certain of the other branch
        local a, b = free.alternative.quaternion, free.quaternion
        local prior = { quaternion = a, track = { a.w, a.x, a.y, a.z, b.w, b.x, b.y, b.z, 1e6,
          0.09 } }
        local pose = assert(tagpose.solve(px, camera, 0.024, { prior = prior }))
        local sse, sse_alt = 4 * free.error ^ 2, 4 * free.alternative.error ^ 2
        local s2 = (1 - track.NOISE_MEMORY) * 0.09 + track.NOISE_MEMORY * sse / 2
        if track.KAPPA * (sse_alt - sse) / (2 * s2) > lmax then
          checked = checked + 1
          assert.near(free.error, pose.error, 1e-12)
        end
      end
    end
    assert.is_true(checked >= 5, "cases with a clearly worse alternative: " .. checked)
  end)

  it("takes a pose of the caller's own as the prior", function()
    local r, t = geometry.random_pose(geometry.rng(3), camera, 0.024, { width = 50, tilt = 0.5 })
    local px = geometry.project(camera, r, t, 0.024)
    local q = { rotation.to_quaternion(r) }
    local pose = assert(tagpose.solve(px, camera, 0.024,
      { prior = { quaternion = { w = q[1], x = q[2], y = q[3], z = q[4] } } }))
    assert.rotation_near(r, pose.rotation, 1e-6)
    pose = assert(tagpose.solve(px, camera, 0.024,
      { prior = { rotation = geometry.nested(r) } }))
    assert.rotation_near(r, pose.rotation, 1e-6)
    assert.equal(10, #pose.track)
    assert.has_error(function()
      tagpose.solve(px, camera, 0.024, { prior = { position = {} } })
    end, "bad argument #4 to 'solve' (options.prior: pose with a finite quaternion or rotation "
      .. "expected)")
  end)

  describe("tagpose.track", function()
    it("keeps unit references and returns the branch with the positive log-odds", function()
      local a, b = { 1, 0, 0, 0 }, { 0.9950041652780258, 0.09983341664682815, 0, 0 }
      local state = track.start({}, a, 1.0, b, 1.2)
      assert.is_true(state[9] > 0)
      -- the second candidate now fits much better: it wins
      local pick = track.choose(state, a, 5.0, b, 0.1, state)
      assert.equal(2, pick)
      assert.is_true(state[9] >= 0)
      local n = state[1] ^ 2 + state[2] ^ 2 + state[3] ^ 2 + state[4] ^ 2
      assert.near(1, n, 1e-12)
      assert.is_true(state[10] >= track.NOISE_FLOOR)
    end)
  end)
end)
