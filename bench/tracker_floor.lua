-- What tracker:update costs beyond its arithmetic: the rows of a sequences set (one detection a
-- frame) fed to tagpose.tracker, beside the same frames run through the work a tracked frame
-- cannot do without — the corners read, the pipeline's refined solve, and the end of the solve
-- (tagpose.result.finish: the tracking filter's step and noise estimate, the result and its
-- confidence) as the tracker's own solve calls them — with none of the tracker's bookkeeping
-- (its argument checks, camera check, entries, association, track records, expiry), and a
-- plain solve of the same rows. Prints, per round, µs per row of each and the ratios to the
-- plain solve: the floor's ratio is what tracker:update would cost with its bookkeeping free.
--
--   lua5.4 bench/tracker_floor.lua [SEQUENCES_DIR] [ROUNDS]   (default bench/dev/sequences, 3)
--
-- SEQUENCES_DIR as bench/dev/sequences: frame = sequence * 1000 + k, the sequence the tag's
-- id, k/30 s its time. Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local args = require("tagpose.core.args")
local pipeline = require("tagpose.core.pipeline")
local result = require("tagpose.result")
local solvequad = require("tagpose.core.solvequad")
local track = require("tagpose.track")
local associate = require("tagpose.tracker.associate")
local log = require("tagpose.tools.log")

local dir, rounds = arg[1] or "bench/dev/sequences", tonumber(arg[2] or 3)
local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
local rows = assert(log.read_corners(dir .. "/corners.csv"))
local n, size = #rows, info.tag_size
local half = 0.5 * size
local floor = math.floor
local frames, times, seqs = {}, {}, {}
for i = 1, n do
  local f = rows[i].frame
  seqs[i], times[i] = floor(f / 1000), (f % 1000) / 30
  frames[i] = { { id = seqs[i], corners = rows[i].corners } }
end

-- the least CPU µs per row of 7 runs of f
local function best(f)
  local b = math.huge
  for _ = 1, 7 do
    collectgarbage()
    local t = os.clock()
    f()
    t = os.clock() - t
    if t < b then b = t end
  end
  return b / n * 1e6
end

local function plain()
  for i = 1, n do tagpose.solve(rows[i].corners, camera, size) end
end

local function tracker()
  -- (a sequence's times start again at 0: the tracker starts again, as it would)
  local tr = tagpose.tracker.new(camera, size)
  for i = 1, n do tr:update(frames[i], times[i]) end
end

local w = pipeline.new()
local function arithmetic()
  local state, seq = nil, nil
  local ctx = result.context(w) -- as a tracker's: it keeps the noise measured so far
  ctx.in_place = true
  for i = 1, n do
    -- (a new track starts from the noise measured so far, as the tracker's do)
    if seqs[i] ~= seq then state, seq = nil, seqs[i] end
    local px = w.px
    args.read_corners(rows[i].corners, px, false)
    local _, _, side = associate.centre_and_side(px)
    assert(pipeline.prepare(w, camera))
    assert(pipeline.refined(w, half, pipeline.REFINED_TOLERANCE, solvequad.MAX_ITERATIONS))
    state = state or track.new_state()
    ctx.camera, ctx.half, ctx.side, ctx.time, ctx.prior = camera, half, side, times[i], state
    assert(result.finish(ctx))
  end
end

local vm = rawget(_G, "jit") and rawget(_G, "jit").version or _VERSION
for r = 1, rounds do
  local s, a, t = best(plain), best(arithmetic), best(tracker)
  print(("%s | round %d | plain solve %.2f | solve and filter %.2f (%.2fx) | tracker:update %.2f"
    .. " (%.2fx)"):format(vm, r, s, a, a / s, t, t / s))
end
