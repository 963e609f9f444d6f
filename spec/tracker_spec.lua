local tagpose = require("tagpose")
local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")

local rad, deg, pi = math.rad, math.deg, math.pi

local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }
local SIZE = 0.024

local function detection(id, r, t, rng, sigma)
  local px = assert(geometry.project(camera, r, t, SIZE))
  local corners = {}
  for j = 1, 4 do
    corners[j] = { x = px[j][1] + (rng and sigma * rng.normal() or 0),
      y = px[j][2] + (rng and sigma * rng.normal() or 0) }
  end
  return { id = id, corners = corners }
end

local function pose_at(u, v, width, tilt, azimuth)
  if tilt < 0 then tilt, azimuth = -tilt, azimuth + pi end
  return geometry.random_pose(nil, camera, SIZE, { width = width, tilt = tilt,
    azimuth = azimuth, roll = 0.2, u = u, v = v })
end

local function angle_to(r, pose)
  return deg(rotation.angle(r, rotation.from_nested(pose.rotation)))
end

describe("tagpose.tracker", function()
  describe("update()", function()
    it("keeps apart tags that share an id by where they are, in any order", function()
      local tr = tagpose.tracker.new(camera, SIZE)
      local tracks = {}
      for k = 0, 20 do
        -- two id-0 tags drifting towards each other, listed in a shuffled order
        local ra, ta = pose_at(200 + 3 * k, 240, 40, 0.5, 0.3)
        local rb, tb = pose_at(440 - 3 * k, 250, 40, 0.5, 1.3)
        local a, b = detection(0, ra, ta), detection(0, rb, tb)
        local swap = k % 3 == 1
        local seen = tr:update(swap and { b, a } or { a, b }, k / 30)
        local sa, sb = seen[swap and 2 or 1], seen[swap and 1 or 2]
        assert.vector_near(ta, sa.pose.position, 1e-9)
        assert.vector_near(tb, sb.pose.position, 1e-9)
        if k == 0 then
          tracks = { sa.track, sb.track }
          assert.is_true(sa.new and sb.new)
        else
          assert.same(tracks, { sa.track, sb.track })
          assert.is_false(sa.new or sb.new)
        end
      end
      assert.equal(2, tr:count())
    end)

    it("bridges a gap of a few frames and starts a new track after max_gap", function()
      local tr = tagpose.tracker.new(camera, SIZE, { max_gap = 0.3 })
      local r, t = pose_at(300, 240, 40, 0.5, 0.3)
      local d = detection(3, r, t)
      local first = tr:update({ d }, 0)[1]
      -- 0.25 s without the tag: the same track, the pose solved with its prior
      assert.equal(first.track, tr:update({ d }, 0.25)[1].track)
      -- 0.4 s: a new one, with a new id
      local later = tr:update({ d }, 0.65)[1]
      assert.is_true(later.new)
      assert.is_true(later.track > first.track)
      -- ids are never reused: not after a reset, nor after the time goes back
      tr:reset()
      local again = tr:update({ d }, 0)
      assert.is_true(again[1].track > later.track)
      local back = tr:update({ d }, -1)
      assert.is_true(back.restarted)
      assert.is_true(back[1].track > again[1].track)
    end)

    it("skips and reports malformed entries, never raises, and solves the others", function()
      local tr = tagpose.tracker.new(camera, { [5] = SIZE })
      local r, t = pose_at(300, 240, 40, 0.5, 0.3)
      local good = detection(5, r, t)
      local seen = tr:update({ false, 42, { corners = good.corners }, { id = 0 / 0,
        corners = good.corners }, { id = 5, corners = { good.corners[1] } },
        { id = 5, corners = "four" }, { id = 9, corners = good.corners }, good,
        { id = 5, corners = { { x = 1 / 0, y = 0 }, good.corners[2], good.corners[3],
          good.corners[4] } } }, 0)
      assert.equal(9, #seen)
      assert.equal(8, seen.skipped)
      for _, i in ipairs({ 1, 2, 3, 4, 5, 6, 7, 9 }) do
        assert.is_nil(seen[i].pose)
        assert.is_string(seen[i].reason)
        assert.equal(i, seen[i].index)
      end
      assert.equal("tracker: no tag size for id 9", seen[7].reason)
      assert.vector_near(t, seen[8].pose.position, 1e-9)
      assert.equal("tracker: entry 9: corner 1 is not finite", seen[9].reason)
      assert.is_nil(seen[9].track)
    end)

    it("refuses what it cannot use at its entry points", function()
      assert.has_error(function() tagpose.tracker.new({ fx = 1 }, SIZE) end,
        "bad argument #1 to 'new' (camera.fy: positive number expected, got nil)")
      assert.has_error(function() tagpose.tracker.new(camera, -1) end,
        "bad argument #2 to 'new' (positive number or table of sizes expected for tag_size, "
          .. "got number -1)")
      assert.has_error(function() tagpose.tracker.new(camera, { default = 0 }) end,
        "bad argument #2 to 'new' (tag_size[default]: positive number expected, got number 0)")
      assert.has_error(function() tagpose.tracker.new(camera, SIZE, { maxgap = 1 }) end,
        "bad argument #3 to 'new' (options.maxgap: unknown key (did you mean 'max_gap'?))")
      local tr = tagpose.tracker.new(camera, SIZE)
      assert.has_error(function() tr:update(42) end,
        "bad argument #1 to 'update' (array of detections expected, got number)")
      assert.has_error(function() tr:update({}, "now") end,
        "bad argument #2 to 'update' (finite number expected for time, got string now)")
    end)

    it("keeps its memory bounded however many ids come and go", function()
      -- 10000 ids, each seen once (fifty a frame), among two tags seen all along: memory
      -- measured after the first 2000 does not grow over the next 8000 (a leak of even a
      -- number per id would show as 128 KB and more)
      local tr = tagpose.tracker.new(camera, SIZE, { max_gap = 0.1 })
      local r, t = pose_at(300, 240, 40, 0.5, 0.3)
      local r2, t2 = pose_at(100, 100, 30, 0.4, 1)
      local keep = { detection("a", r, t), detection("b", r2, t2) }
      -- a detection the solver rejects at once: its track is kept all the same
      local glitch = { { x = 1, y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 }, { x = 4, y = 4 } }
      local frame, id = {}, 0
      local before
      for f = 1, 200 do
        frame[1], frame[2] = keep[1], keep[2]
        for j = 3, 52 do
          id = id + 1
          frame[j] = { id = id, corners = glitch }
        end
        local seen = tr:update(frame, f / 30)
        assert.equal(seen[1].track, 1)
        if f == 40 then
          collectgarbage()
          collectgarbage()
          before = collectgarbage("count")
        end
      end
      assert.equal(10000, id)
      -- alive: the two tags, and the glitches of the last max_gap (four frames)
      assert.is_true(tr:count() <= 2 + 4 * 50, "live tracks " .. tr:count())
      collectgarbage()
      collectgarbage()
      local after = collectgarbage("count")
      assert.is_true(after - before < 64, ("%.0f KB before, %.0f KB after"):format(before, after))
      -- and never more than max_tracks, even in one frame
      local capped = tagpose.tracker.new(camera, SIZE, { max_tracks = 50 })
      local many = {}
      for j = 1, 200 do many[j] = { id = j, corners = glitch } end
      capped:update(many, 0)
      assert.equal(50, capped:count())
    end)
  end)

  describe("assign()", function()
    -- three id-0 tags drifting past each other in a shuffled order; the third leaves for
    -- 0.4 s (beyond max_gap: a new track), and at frame 30 the time goes back (all restart)
    local function frames()
      local out = {}
      for k = 0, 44 do
        local time = k < 30 and k / 30 or (k - 35) / 30
        local list = {}
        for j, u in ipairs({ 150 + 4 * k, 450 - 4 * k, 300 }) do
          if not (j == 3 and k >= 10 and k < 22) then
            local r, t = pose_at(u, 120 + 110 * j, 40, 0.5, j)
            list[#list + 1] = detection(0, r, t)
          end
        end
        if k % 2 == 1 then list[1], list[#list] = list[#list], list[1] end
        out[#out + 1] = { list = list, time = time }
      end
      return out
    end

    it("gives the tracks update gives, without solving", function()
      local solving = tagpose.tracker.new(camera, SIZE, { max_gap = 0.3 })
      local assigning = tagpose.tracker.new(camera, SIZE, { max_gap = 0.3 })
      local numbers = {}
      for k, f in ipairs(frames()) do
        local a, b = solving:update(f.list, f.time), assigning:assign(f.list, f.time)
        assert.equal(#a, #b)
        assert.equal(a.restarted, b.restarted, "frame " .. k)
        for i = 1, #a do
          assert.is_table(a[i].pose)
          assert.is_nil(b[i].pose)
          assert.is_nil(b[i].reason)
          assert.same({ a[i].track, a[i].new }, { b[i].track, b[i].new }, "frame " .. k)
          numbers[a[i].track] = true
        end
      end
      -- 3 tracks, the third's again after its gap, then 3 more after the restart
      local count = 0
      for _ in pairs(numbers) do count = count + 1 end
      assert.equal(7, count)
    end)

    it("leaves a track that update continues with its pose, and checks its arguments", function()
      local tr = tagpose.tracker.new(camera, SIZE)
      local r, t = pose_at(300, 240, 40, 0.5, 0.3)
      local first = tr:assign({ detection(2, r, t) }, 0)[1]
      local next = tr:update({ detection(2, r, t) }, 1 / 30)[1]
      assert.equal(first.track, next.track)
      assert.vector_near(t, next.pose.position, 1e-9)
      assert.equal("tracker: no tag size for id 2", tagpose.tracker.new(camera, { [1] = SIZE })
        :assign({ detection(2, r, t) }, 0)[1].reason)
      assert.has_error(function() tr:assign(detection(2, r, t), 1) end,
        "bad argument #1 to 'assign' (array of detections expected, got one detection "
          .. "{id =, corners =} (pass {detection}))")
      assert.has_error(function() tr:assign({}, math.huge) end,
        "bad argument #2 to 'assign' (finite number expected for time, got number inf)")
    end)
  end)

  describe("smooth()", function()
    -- a small tag coming closer and tilting more: its first frames say little about the
    -- branch, the later ones much
    local function sequence(seed)
      local rng = geometry.rng(seed)
      local frames = {}
      for k = 0, 119 do
        local tilt = rad(20 + 10 * k / 119)
        local r, t = pose_at(300 + k, 240, 22 + 18 * k / 119, tilt, 0.9)
        frames[#frames + 1] = { r = r, det = detection(0, r, t, rng, 0.5), time = k / 30 }
      end
      return frames
    end

    it("revises the early choices with the later frames' evidence", function()
      local causal, smoothed, rows = 0, 0, 0
      for seed = 1, 6 do
        local frames = sequence(seed)
        local tr = tagpose.tracker.new(camera, SIZE, { smooth = true })
        local poses = {}
        for k, f in ipairs(frames) do poses[k] = tr:update({ f.det }, f.time)[1].pose end
        local choice, confidence = tr:smooth()
        assert.equal(#frames, #choice)
        for k, f in ipairs(frames) do
          local p = poses[k]
          local chosen = choice[k] == 2 and p.alternative or p
          assert.is_true(choice[k] == 1 or (choice[k] == 2 and p.alternative ~= nil))
          assert.is_true(confidence[k] >= 0.5 and confidence[k] <= 1)
          rows = rows + 1
          if angle_to(f.r, p) > 30 then causal = causal + 1 end
          if angle_to(f.r, chosen) > 30 then smoothed = smoothed + 1 end
        end
      end
      assert.is_true(causal >= 10, "the sequences are ambiguous enough to test: " .. causal)
      assert.is_true(smoothed * 3 <= causal,
        ("of %d rows, causal %d wrong, smoothed %d"):format(rows, causal, smoothed))
    end)

    it("needs the recording asked for, and gives 0 to rows without a pose", function()
      local tr = tagpose.tracker.new(camera, SIZE)
      assert.has_error(function() tr:smooth() end)
      tr = tagpose.tracker.new(camera, SIZE, { smooth = true })
      local r, t = pose_at(300, 240, 40, 0.5, 0.3)
      tr:update({ false, detection(1, r, t) }, 0)
      tr:update({ detection(1, r, t) }, 1 / 30)
      local choice, confidence = tr:smooth()
      assert.same({ 0, 1, 1 }, choice)
      assert.equal(0, confidence[1])
    end)
  end)
end)
