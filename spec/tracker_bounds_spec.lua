-- The tracker's work and memory stay bounded whatever a frame holds, and what every later call
-- would refuse is refused when the tracker is made.
local tagpose = require("tagpose")
local geometry = require("support.geometry")

local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }
local SIZE = 0.024

-- a detection of a tag of `width` px centred at (u, v), tilted a little
local function detection(id, u, v, width, rng, sigma)
  local r, t = geometry.random_pose(nil, camera, SIZE, { width = width, tilt = 0.4,
    azimuth = 0.5, roll = 0.1, u = u, v = v })
  local px = assert(geometry.project(camera, r, t, SIZE))
  local corners = {}
  for j = 1, 4 do
    corners[j] = { px[j][1] + (rng and sigma * rng.normal() or 0),
      px[j][2] + (rng and sigma * rng.normal() or 0) }
  end
  return { id = id, corners = corners }
end

-- the VM instructions a function runs (debug.sethook's count: the same on every run)
local function instructions(f)
  local count = 0
  debug.sethook(function() count = count + 1 end, "", 1000)
  f()
  debug.sethook()
  return count * 1000
end

-- n tags of one id on a grid of spacing 1.2 sides, each within the others' gates
local function crowd(n, shift)
  local list, side, columns = {}, 16, 15
  for i = 0, n - 1 do
    local u = 100 + 1.2 * side * (i % columns) + shift
    local v = 60 + 1.2 * side * math.floor(i / columns)
    list[#list + 1] = detection(0, u, v, side)
  end
  return list
end

describe("tagpose.tracker bounds", function()
  it("does work linear in a frame's detections of one id, however crowded", function()
    -- per detection, a crowded frame of 160 costs about what one of 20 does (pairing every
    -- detection with every track in a sorted list, as before, made it 8 times and more)
    local per = {}
    for _, n in ipairs({ 20, 160 }) do
      local tr = tagpose.tracker.new(camera, SIZE)
      tr:update(crowd(n, 0), 0)
      local second = crowd(n, 2)
      per[n] = instructions(function() tr:update(second, 1 / 30) end) / n
      assert.equal(n, tr:count())
    end
    assert.is_true(per[160] < 2 * per[20], ("%.0f against %.0f instructions a detection")
      :format(per[160], per[20]))
  end)

  it("keeps each of 200 tags of one id on its own track, each in its neighbours' gates",
    function()
      -- 200 id-0 tags 1.25 sides apart (a tag's gate, 1.5 sides, holds its neighbours), each
      -- drifting its own way by up to 2 px a frame, listed in a new order every frame: more
      -- tracks of one id than tagpose.tracker.associate looks at one by one (its k-d tree)
      local rng = geometry.rng(2602)
      local tags, side = {}, 16
      for i = 0, 199 do
        local u, v = 120 + 1.25 * side * (i % 20), 140 + 1.25 * side * math.floor(i / 20)
        tags[i + 1] = { u = u, v = v, du = rng.uniform(-2, 2), dv = rng.uniform(-2, 2),
          roll = rng.uniform(0, 6) }
      end
      assert.is_true(#tags > require("tagpose.tracker.associate").LINEAR)
      local tr = tagpose.tracker.new(camera, SIZE)
      local track_of = {}
      for k = 0, 2 do
        local order, list = {}, {}
        for i = 1, #tags do order[i] = i end
        for i = #order, 2, -1 do
          local j = math.floor(rng.uniform(1, i + 0.999))
          order[i], order[j] = order[j], order[i]
        end
        local truth = {}
        for e, i in ipairs(order) do
          local tag = tags[i]
          local r, t = geometry.random_pose(nil, camera, SIZE, { width = side, tilt = 0.4,
            azimuth = 0.5, roll = tag.roll, u = tag.u + k * tag.du, v = tag.v + k * tag.dv })
          local px = assert(geometry.project(camera, r, t, SIZE))
          list[e], truth[e] = { id = 0, corners = px }, t
        end
        local seen = tr:update(list, k / 30)
        for e, i in ipairs(order) do
          local s = seen[e]
          assert.vector_near(truth[e], s.pose.position, 1e-9)
          if k == 0 then
            assert.is_true(s.new)
            track_of[i] = s.track
          else
            assert.is_false(s.new)
            assert.equal(track_of[i], s.track)
          end
        end
      end
      assert.equal(200, tr:count())
    end)

  it("keeps a track through a frame republished microseconds later", function()
    -- a camera driver that sends the same frame twice, 10 µs apart, with the detector's noise
    local rng = geometry.rng(33)
    local tr = tagpose.tracker.new(camera, SIZE)
    local tracks = {}
    for k = 0, 40 do
      local u = 200 + 3 * k
      for _, dt in ipairs({ 0, 1e-5 }) do
        local seen = tr:update({ detection(7, u, 240, 30, rng, 0.5) }, k / 30 + dt)
        tracks[seen[1].track] = true
      end
    end
    assert.same({ [1] = true }, tracks)
  end)

  it("evicts the least recently seen tracks first, past max_tracks", function()
    local tr = tagpose.tracker.new(camera, SIZE, { max_tracks = 3, max_gap = 10 })
    local t = 0
    local function see(ids)
      t = t + 1 / 30
      local list = {}
      for i, id in ipairs(ids) do list[i] = detection(id, 60 + 90 * id, 240, 30) end
      return tr:update(list, t)
    end
    see({ 1, 2, 3 })
    see({ 1 }) -- 2 and 3 are now the least recently seen
    see({ 4 }) -- one too many: 2 goes
    assert.equal(3, tr:count())
    local seen = see({ 1, 2, 3, 4 })
    assert.is_false(seen[1].new)
    assert.is_true(seen[2].new) -- 2 was evicted
    assert.is_false(seen[4].new)
    assert.equal(3, tr:count())
  end)

  it("refuses at new() what every update would refuse", function()
    for _, bad in ipairs({ 1e300, 1e-300, {}, { [1] = "a" }, { default = 0 } }) do
      assert.has_error(function() tagpose.tracker.new(camera, bad) end)
    end
    assert.has_error(function() tagpose.tracker.new({ fx = 1e-320, fy = 1, cx = 0, cy = 0 },
      SIZE) end)
    assert.has_error(function() tagpose.tracker.new(camera, SIZE, { sigma = -1 }) end,
      "bad argument #3 to 'new' (options.sigma: positive number expected, got number -1)")
  end)

  it("says so when one detection is passed for the list, or times look like milliseconds",
    function()
      local tr = tagpose.tracker.new(camera, SIZE)
      local d = detection(1, 300, 240, 30)
      assert.has_error(function() tr:update(d, 0) end, "bad argument #1 to 'update' (array of "
        .. "detections expected, got one detection {id =, corners =} (pass {detection}))")
      local warned
      for k = 0, 5 do
        -- frames 33 ms apart, in milliseconds: every step is 33 "seconds"
        local seen = tr:update({ d }, 33 * k)
        warned = warned or seen.warning
        if k >= 1 then assert.is_true(seen[1].new) end
      end
      assert.is_truthy(warned and warned:match("milliseconds"), tostring(warned))
      -- seconds: no warning
      tr = tagpose.tracker.new(camera, SIZE)
      for k = 0, 5 do assert.is_nil(tr:update({ d }, 0.033 * k).warning) end
    end)
end)

describe("tracker's camera", function()
  -- the pose's position error for a tag at pose (r, t) seen through `seen_by`, tracked by tr
  local function error_of(tr, seen_by, r, t, time)
    local px = assert(geometry.project(seen_by, r, t, SIZE))
    local seen = tr:update({ { id = 3, corners = px } }, time)
    local p = assert(seen[1].pose, seen[1].why)
    local e = 0
    for k, key in ipairs({ "x", "y", "z" }) do e = math.max(e, math.abs(p.position[key] - t[k])) end
    return e
  end

  it("is the caller's: one recalibrated in place (intrinsics, distortion) is followed", function()
    local cam = { fx = 600, fy = 600, cx = 320, cy = 240, distortion = { k1 = 0.02 } }
    local tr = tagpose.tracker.new(cam, SIZE)
    local r, t = geometry.random_pose(nil, cam, SIZE, { width = 60, tilt = 0.5, azimuth = 0.3,
      roll = 0.2, u = 300, v = 220 })
    for k = 0, 2 do assert.is_true(error_of(tr, cam, r, t, k / 30) < 1e-9) end
    -- the caller's table changed: the corners are now what the new camera sees
    cam.fx, cam.fy = 900, 900
    assert.is_true(error_of(tr, cam, r, t, 3 / 30) < 1e-9)
    cam.distortion.k1 = -0.05
    assert.is_true(error_of(tr, cam, r, t, 4 / 30) < 1e-9)
    cam.distortion = nil
    assert.is_true(error_of(tr, cam, r, t, 5 / 30) < 1e-9)
  end)

  it("changed into one a solve refuses raises at the caller's update", function()
    local cam = { fx = 600, fy = 600, cx = 320, cy = 240 }
    local tr = tagpose.tracker.new(cam, SIZE)
    local r, t = geometry.random_pose(nil, cam, SIZE, { width = 60, tilt = 0.5, azimuth = 0.3,
      roll = 0.2, u = 300, v = 220 })
    local px = assert(geometry.project(cam, r, t, SIZE))
    tr:update({ { id = 3, corners = px } }, 0)
    cam.fx = -1
    local ok, err = pcall(function() tr:update({ { id = 3, corners = px } }, 1 / 30) end)
    assert.is_false(ok)
    assert.matches("bad argument #0 to 'update'", err, 1, true)
    assert.matches("camera was changed", err, 1, true)
    assert.matches("tracker_bounds_spec.lua", err, 1, true)
  end)
end)
