-- tagpose.layout.calibrate, from geometry: a cube glued off by known amounts, a camera circling
-- it in sessions on different faces, its corners projected; the glue recovered.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local assertions = require("support.assertions")

local camera = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87, width = 320, height = 240 }
local TAG, BLOCK = 0.0229, 0.0548

-- a log of sessions on the faces -z, +x and +y (every tag seen, chained through the others)
local function log_of(layout, rng, n, sigma)
  local frames = {}
  for _, down in ipairs({ { 0, 0, -1 }, { 1, 0, 0 }, { 0, 1, 0 } }) do
    local session = layouts.session(layout, camera, rng, n, down, sigma)
    for _, f in ipairs(session) do frames[#frames + 1] = f end
  end
  return frames
end

local function absolute_error(a, b)
  local worst_d, worst_r = 0, 0
  for id, e in pairs(a.tags) do
    local o = b.tags[id]
    local d = math.sqrt((e.position.x - o.position.x) ^ 2 + (e.position.y - o.position.y) ^ 2
      + (e.position.z - o.position.z) ^ 2)
    local r = assertions.rotation_angle(layouts.matrix(e.quaternion), layouts.matrix(o.quaternion))
    worst_d, worst_r = math.max(worst_d, d), math.max(worst_r, r)
  end
  return worst_d, worst_r
end

describe("tagpose.layout", function()
  describe("calibrate()", function()
    it("recovers known glue errors exactly from exact corners", function()
      local rng = geometry.rng(101)
      local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0.5)
      local frames = log_of(truth, rng, 20, 0)
      local nd, nr = layouts.pair_error(nominal, truth)
      assert.is_true(nd > 1e-3 and nr > 1, "the glue is visible")
      local calibrated, report = assert(tagpose.layout.calibrate(frames, camera, nominal))
      local d, r = layouts.pair_error(calibrated, truth)
      assert.is_true(d < 1e-9 and r < 1e-6, ("pairs off by %.3g m, %.3g deg"):format(d, r))
      assert.equal(0, #report.unplaced)
      assert.is_true(report.rms < 1e-6 and report.rms_start > 0.1)
      for id = 0, 5 do
        local t = report.tags[id]
        assert.is_true(t.observations > 10, "tag " .. id)
        assert.equal(0, t.outliers)
      end
    end)

    it("puts the result in the nominal body frame: glue in the faces' planes comes out as is",
      function()
        local rng = geometry.rng(102)
        -- glued without tilt: every tag on its nominal plane, so the planes fix the body frame
        local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0)
        local frames = log_of(truth, rng, 20, 0)
        local calibrated, report = assert(tagpose.layout.calibrate(frames, camera, nominal))
        local d, r = absolute_error(calibrated, truth)
        assert.is_true(d < 1e-9 and r < 1e-6, ("tags off by %.3g m, %.3g deg"):format(d, r))
        -- and the report's corrections are the glue
        for id = 0, 5 do
          local t, n, g = report.tags[id], nominal.tags[id], truth.tags[id]
          local shift = { g.position.x - n.position.x, g.position.y - n.position.y,
            g.position.z - n.position.z }
          assert.vector_near(shift, t.shift, 1e-9)
          assert.near(0, t.normal, 1e-9)
          assert.near(0, t.tilt, 1e-8)
          assert.near(assertions.rotation_angle(layouts.matrix(n.quaternion),
            layouts.matrix(g.quaternion)), math.deg(math.abs(t.turn)), 1e-6)
        end
        -- "corners": all corners alike, the same relative layout
        local other = assert(tagpose.layout.calibrate(frames, camera, nominal,
          { gauge = "corners" }))
        local pd, pr = layouts.pair_error(other, truth)
        assert.is_true(pd < 1e-9 and pr < 1e-6)
      end)

    it("recovers the glue from noisy corners, and keeps bad detections from pulling it",
      function()
        local rng = geometry.rng(103)
        local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0.5)
        local frames = log_of(truth, rng, 60, 0.3)
        local calibrated = assert(tagpose.layout.calibrate(frames, camera, nominal))
        local nd, nr = layouts.pair_error(nominal, truth)
        local d, r = layouts.pair_error(calibrated, truth)
        assert.is_true(d < 5e-4 and r < 0.5 and d < 0.2 * nd and r < 0.2 * nr,
          ("pairs off by %.3g mm, %.3g deg (nominal %.3g mm, %.3g deg)"):format(1e3 * d, r,
            1e3 * nd, nr))
        -- ten detections in frames of two or more tags moved by 5-20 px
        local moved, multi = 0, 0
        for _, f in ipairs(frames) do
          if #f >= 2 then multi = multi + 1 end
          if #f >= 2 and multi % 10 == 0 and moved < 10 then
            moved = moved + 1
            local shift = 5 + 15 * rng.uniform()
            for _, c in ipairs(f[1].corners) do c[1], c[2] = c[1] + shift, c[2] - 0.5 * shift end
          end
        end
        assert.equal(10, moved)
        local robust, report = assert(tagpose.layout.calibrate(frames, camera, nominal))
        local rd, rr = layouts.pair_error(robust, truth)
        assert.is_true(rd < 5e-4 and rr < 0.5, ("pairs off by %.3g mm, %.3g deg"):format(1e3 * rd,
          rr))
        assert.is_true(report.detections.outliers >= 10, report.detections.outliers .. " outliers")
      end)

    it("says which tags it could not place, and why", function()
      local rng = geometry.rng(104)
      local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0.5)
      local frames = log_of(truth, rng, 20, 0)
      -- tag 6 never seen; tag 7 seen alone; tags 8 and 9 seen only with each other
      local far = { size = TAG, position = { x = 1, y = 0, z = 0 },
        quaternion = { w = 1, x = 0, y = 0, z = 0 } }
      for id = 6, 9 do nominal.tags[id] = far end
      local extra, pair = {}, nil
      for i, f in ipairs(frames) do
        extra[i] = f
        if #f >= 2 then pair = f end
      end
      extra[#extra + 1] = { { id = 7, corners = frames[1][1].corners } }
      extra[#extra + 1] = { { id = 8, corners = pair[1].corners }, { id = 9,
        corners = pair[2].corners } }
      local _, before = assert(tagpose.layout.calibrate(frames, camera, nominal))
      local calibrated, report = assert(tagpose.layout.calibrate(extra, camera, nominal))
      local reasons = {}
      for _, u in ipairs(report.unplaced) do reasons[u.id] = u.reason end
      assert.matches("never seen in the log", reasons[6])
      assert.matches("seen only in frames without another tag", reasons[7])
      assert.matches("never seen together with the tags linked to the reference", reasons[8])
      assert.matches("never seen together with the tags linked to the reference", reasons[9])
      assert.is_nil(reasons[0])
      -- the unplaced keep their nominal pose; the others are placed
      assert.same(far.position, calibrated.tags[6].position)
      local d = layouts.pair_error({ tags = { [0] = calibrated.tags[0], calibrated.tags[1],
        calibrated.tags[2], calibrated.tags[3], calibrated.tags[4], calibrated.tags[5] } }, truth)
      assert.is_true(d < 1e-9)
      assert.equal(before.frames.single + 1, report.frames.single)
      assert.equal(0, before.frames.elsewhere)
      assert.equal(1, report.frames.elsewhere)
    end)

    it("refuses logs that cannot calibrate, and reports bad detections", function()
      local rng = geometry.rng(105)
      local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0.5)
      local frames = log_of(truth, rng, 20, 0)
      local function refused(pattern, f, l)
        local out, why = tagpose.layout.calibrate(f, camera, l or nominal)
        assert.is_nil(out)
        assert.matches(pattern, why)
      end
      refused("^layout: the log has no frames", {})
      refused("^layout: no frame sees a tag of the layout", { { { id = 77, corners =
        frames[1][1].corners } } })
      refused("^layout: no frame sees two tags of the layout together", { { frames[1][1] } })
      refused("^layout: a layout of one tag", frames, { tags = { [0] = nominal.tags[0] } })
      -- NaN corners: skipped and counted, in frames of one tag or more
      local nan = { { 0 / 0, 1 }, { 2, 3 }, { 4, 5 }, { 6, 7 } }
      local k = 1
      while #frames[k] < 2 do k = k + 1 end
      table.insert(frames[k], 1, { id = frames[k][1].id, corners = nan })
      frames[#frames + 1] = { { id = 0, corners = nan } }
      local _, report = assert(tagpose.layout.calibrate(frames, camera, nominal))
      assert.equal(2, report.detections.skipped)
      -- a bound on the iterations is kept
      local _, short = assert(tagpose.layout.calibrate(frames, camera, nominal,
        { max_iterations = 1 }))
      assert.is_true(short.iterations <= 1)
      assert.is_false(short.converged)
      local raised = assertions.raised
      local name = "layout_calibrate_spec.lua"
      assert.equal("bad argument #1 to 'calibrate' (frames[2]: array of detections expected,"
        .. " got number)", raised(function()
          tagpose.layout.calibrate({ frames[1], 5 }, camera, nominal)
        end, name))
      assert.matches("^bad argument #4 to 'calibrate' %(options.reference: tag 99 is not in",
        raised(function()
          tagpose.layout.calibrate(frames, camera, nominal, { reference = 99 })
        end, name))
      assert.matches("^bad argument #4 to 'calibrate' %(options.gauge:", raised(function()
        tagpose.layout.calibrate(frames, camera, nominal, { gauge = "faces" })
      end, name))
    end)
  end)
end)
