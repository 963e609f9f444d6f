local tagpose = require("tagpose")
local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")
local gauss = require("support.gauss")

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
      -- number per id would show as 128 KB and more). On LuaJIT the compiled traces are on
      -- the collector's heap too, and when they are compiled depends on the machine (up to
      -- 100 KB more here with -Ohotloop=1000): they are flushed before each measurement, which
      -- is of the tracker's data
      local jit = rawget(_G, "jit")
      local function heap()
        if jit then jit.flush() end
        collectgarbage()
        collectgarbage()
        return collectgarbage("count")
      end
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
        if f == 40 then before = heap() end
      end
      assert.equal(10000, id)
      -- alive: the two tags, and the glitches of the last max_gap (four frames)
      assert.is_true(tr:count() <= 2 + 4 * 50, "live tracks " .. tr:count())
      local after = heap()
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

  describe("tracking", function()
    -- a tag of `width` px whose tilt swings through face-on along one line, ±20°, `period`
    -- frames a swing, with σ px of noise: per frame the pose and a detection
    local function swinging(seed, frames, width, period, sigma)
      local rng = geometry.rng(seed)
      for _ = 1, 10 do rng.uniform() end
      local azimuth, phase = rng.uniform(0, 2 * pi), rng.uniform(0, 2 * pi)
      local out = {}
      for k = 0, frames - 1 do
        local r, t = pose_at(300, 250, width, rad(20) * math.sin(2 * pi * k / period + phase),
          azimuth)
        out[k + 1] = { r = r, t = t, det = detection(0, r, t, rng, sigma), time = k / 30 }
      end
      return out
    end

    it("carries a far tag's branch through face-on, again and again", function()
      -- 30 px, where the tilt hardly leaves the noise: the branch survives a crossing only by
      -- the rate the filter carries into it (before its likelihood of the squared tilt, these
      -- six sequences had 163 rows wrong tracked, 51 smoothed)
      local alone, tracked, smoothed = 0, 0, 0
      for seed = 1, 6 do
        local tr = tagpose.tracker.new(camera, SIZE, { smooth = true })
        local frames, poses = swinging(seed, 360, 30, 120, 0.5), {}
        for k, f in ipairs(frames) do
          poses[k] = tr:update({ f.det }, f.time)[1].pose
          local single = assert(tagpose.solve(f.det.corners, camera, SIZE))
          if angle_to(f.r, single) > 30 then alone = alone + 1 end
          if angle_to(f.r, poses[k]) > 30 then tracked = tracked + 1 end
        end
        local choice = tr:smooth()
        for k, f in ipairs(frames) do
          local p = choice[k] == 2 and poses[k].alternative or poses[k]
          if angle_to(f.r, p) > 30 then smoothed = smoothed + 1 end
        end
      end
      assert.is_true(alone >= 300, "the sequences are ambiguous enough to test: " .. alone)
      assert.is_true(tracked * 4 <= alone and smoothed <= tracked,
        ("of 2160 rows wrong: %d alone, %d tracked, %d smoothed"):format(alone, tracked,
          smoothed))
    end)

    it("starts a new track from the noise its other tracks measured", function()
      -- a tag seen for two seconds with 2 px of noise, then another: its first pose's
      -- uncertainty is that of a single frame at σ = 2 px, not at the 0.5 px default
      local rng = geometry.rng(31)
      local tr = tagpose.tracker.new(camera, SIZE)
      local r, t = pose_at(200, 240, 60, 0.6, 0.3)
      for k = 0, 59 do tr:update({ detection(1, r, t, rng, 2) }, k / 30) end
      local r2, t2 = pose_at(450, 240, 60, 0.5, 1.4)
      local d = detection(2, r2, t2, rng, 2)
      local seen = tr:update({ d }, 2)
      assert.is_true(seen[1].new)
      local first = seen[1].pose.covariance[3][3]
      local known = assert(tagpose.solve(d.corners, camera, SIZE, { sigma = 2 })).covariance[3][3]
      local default = assert(tagpose.solve(d.corners, camera, SIZE)).covariance[3][3]
      assert.is_true(first / known > 0.8 and first / known < 1.5 and default / known < 0.6,
        ("var(z): first %.3g, single frame σ 2 px %.3g, default %.3g"):format(first, known,
          default))
    end)

    it("covers the truth with its covariance, σ given or estimated", function()
      -- the covariance of the candidate on the true branch, its 6-dof 95 % ellipsoid (as
      -- docs/uncertainty.md scores it); with σ estimated its degrees of freedom widen it
      local function coverage(sigma, given)
        local inside, rows = 0, 0
        for seed = 1, 4 do
          local tr = tagpose.tracker.new(camera, SIZE, { sigma = given and sigma or nil })
          for _, f in ipairs(swinging(40 + seed, 150, 40, 150, sigma)) do
            local pose = tr:update({ f.det }, f.time)[1].pose
            local best, alt = pose, pose.alternative
            if alt and angle_to(f.r, alt) < angle_to(f.r, pose) then best = alt end
            local e = gauss.error_of(best, f.r, f.t)
            if gauss.mahalanobis(best.covariance, e) < 12.59 then inside = inside + 1 end
            rows = rows + 1
          end
        end
        return inside / rows
      end
      for _, case in ipairs({ { 0.5, true }, { 0.5, false }, { 1.5, false } }) do
        local c = coverage(case[1], case[2])
        assert.is_true(c > 0.9 and c < 0.99, ("σ %g px %s: %.1f %%"):format(case[1],
          case[2] and "given" or "estimated", 100 * c))
      end
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

  describe("the commands of docs/tracking.md and docs/uncertainty.md", function()
    local run = require("support.run")
    local dir

    setup(function()
      dir = os.tmpname()
      os.remove(dir)
      local out, status = run.script("bench/make_sequences.lua", dir .. "/s", "2", "3101",
        "--kinds", "far_hover,far_wobble", "--frames", "40", "--camera", "random")
      assert(status == 0, out)
    end)

    teardown(function()
      run.run("rm -rf " .. run.quote(dir))
    end)

    it("pools the tracker's figures by kind, per set, with a constant set", function()
      local out, status = run.script("bench/track_pool.lua", dir, "--kinds")
      assert.equal(0, status, out)
      assert.matches("| far_wobble | 40 |", out, 1, true)
      assert.matches("| **all** | 80 |", out, 1, true)
      assert.matches("| flipped (> 30° off) |", out, 1, true)
      assert.matches("| true-branch candidate | 80 |", out, 1, true)
      out, status = run.script("bench/track_pool.lua", dir, "--quick", "--by-set", "--sigma", "0.5",
        "--set", "PROCESS=0.03")
      assert.equal(0, status, out)
      assert.matches("set " .. dir .. "/s rows 80 tracked", out, 1, true)
      assert.is_nil(out:find("coverage of", 1, true))
      out, status = run.script("bench/track_pool.lua", dir, "--set", "NOPE=1")
      assert.equal(2, status, out)
    end)

    it("fits the confidence map and scores the tracker's confidence and covariance", function()
      local out, status = run.script("bench/fit_confidence.lua", dir)
      assert.equal(0, status, out)
      assert.matches("M.CONFIDENCE = { 0, 0.00, 6, ", out, 1, true)
      assert.matches("| posterior log-odds | rows | wrong |", out, 1, true)
      for _, mode in ipairs({ "--track", "--smooth" }) do
        out, status = run.script("examples/accuracy.lua", dir .. "/s", mode)
        assert.equal(0, status, out)
        assert.matches("confidence: ECE", out, 1, true)
      end
      for _, extra in ipairs({ "--sigma", "--default-sigma", "--prior" }) do
        -- (--track with the set's σ given, with σ estimated; and a chain of options.prior)
        if extra == "--prior" then
          out, status = run.script("examples/uncertainty.lua", dir .. "/s", "--prior")
        elseif extra == "--sigma" then
          out, status = run.script("examples/uncertainty.lua", dir .. "/s", "--track")
        else
          out, status = run.script("examples/uncertainty.lua", dir .. "/s", "--track", extra)
        end
        assert.equal(0, status, out)
        assert.matches("rows    80  coverage", out, 1, true)
        assert.matches("(returned ", out, 1, true)
      end
    end)

    it("adds noise to a real log and tables its rows by track age", function()
      local out, status = run.script("bench/real_noise.lua", "--sigma", "2", "--seeds", "1",
        "--from", "16", "--quick", "--by-age", "bench/realdata/builderbot-exp-13")
      assert.equal(0, status, out)
      assert.matches("seeds 16..16", out, 1, true)
      assert.matches("| 2 | **all** | 873 |", out, 1, true)
      assert.matches("| track age (frames) | rows |", out, 1, true)
    end)

    it("runs the rows whose instructions bench/track_instructions.sh counts", function()
      for _, mode in ipairs({ "plain", "tracker" }) do
        local out, status = run.script("bench/track_instructions.lua", mode, "5")
        assert.equal(0, status, out)
      end
      local out, status = run.run("bash -n bench/track_instructions.sh 2>&1")
      assert.equal(0, status, out)
    end)
  end)
end)
