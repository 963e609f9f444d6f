-- The real-trajectory test of the tracking filter: the real BuilderBot corner logs with
-- Gaussian noise added to every corner, scored against the clean log's own poses.
--
--   lua5.4 bench/real_noise.lua [--sigma 2,3] [--seeds N] [--from K] [--frame-time S]
--     [--quick] [--by-age] [--set NAME=VALUE] [DIR ...]
--
-- DIR: data sets in the format of bench/realdata (camera.lua and corners.csv each;
-- default: every bench/realdata/builderbot-*). There is no ground
-- truth: the pseudo-truth of a row is the pose the clean corners give (every solver agrees
-- with it to 0.01°). For each noise σ (px) and seed (1..N, default 5), the corners get
-- N(0, σ²) noise on each coordinate (a Park-Miller generator: the same numbers on every VM)
-- and every row is solved four ways:
--
-- * `single`: one frame alone (the better-fitting pose);
-- * `prior`: the previous frame's pose of the same tag id as `options.prior` (what a caller
--   holding its own state does, and what `replay --track` did);
-- * `tracked`: `tagpose.tracker`, fed frame by frame, the frame's time = frame × S seconds
--   (default 0.095: the logs' frames are about 95 ms apart);
-- * `smoothed`: the same, revised by `tracker:smooth()`.
--
-- A row is wrong when its rotation is more than 30° from the clean pose's, or when no pose
-- came out (counted apart as `failed`). Run from the repository root.
--
-- `--from K` draws the noise of seeds K..K+N-1 (default 1: the figures of docs/tracking.md are
-- seeds 1..5; choose on other seeds). `--quick` leaves out `single` and `prior`. `--by-age`
-- adds a table of the tracked rows by the age of their track (frames since it started) and
-- how confident the wrong ones were. `--set NAME=VALUE` sets a `tagpose.track` constant (for
-- measuring it).

package.path = "./src/?.lua;./src/?/init.lua;./spec/?.lua;./bench/lib/?.lua;" .. package.path
local bench = require("confidence")
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")

local deg = math.deg

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua bench/real_noise.lua "
    .. "[--sigma 2,3] [--seeds N] [--from K] [--frame-time S] [--quick] [--by-age] "
    .. "[--set NAME=VALUE] [DIR ...]\n")
  os.exit(2)
end

local track = require("tagpose.track")

local opt = { sigmas = { 2, 3 }, seeds = 5, from = 1, frame_time = 0.095 }
do
  local function number(name, message)
    return function(take) opt[name] = tonumber(take()) or usage(message) end
  end
  opt.dirs = bench.arguments(arg, {
    ["--sigma"] = function(take)
      opt.sigmas = {}
      for v in (take() or usage("--sigma needs values")):gmatch("[^,]+") do
        opt.sigmas[#opt.sigmas + 1] = tonumber(v) or usage("--sigma: numbers expected")
      end
    end,
    ["--seeds"] = number("seeds", "--seeds needs a number"),
    ["--from"] = number("from", "--from needs a number"),
    ["--quick"] = function() opt.quick = true end,
    ["--by-age"] = function() opt.by_age = true end,
    ["--set"] = bench.set_constant(track, usage),
    ["--frame-time"] = number("frame_time", "--frame-time needs a number"),
  }, usage)
  if #opt.dirs == 0 then
    local p = io.popen('ls -d bench/realdata/builderbot-* 2>/dev/null')
    for d in p:lines() do opt.dirs[#opt.dirs + 1] = d end
    p:close()
    if #opt.dirs == 0 then usage("no data set found") end
  end
end

local function rotation_of(pose)
  return pose and rotation.from_nested(pose.rotation)
end

-- the rows of a data set, with the clean poses' rotations
local function load(dir)
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local rows, problems = log.read_corners(dir .. "/corners.csv")
  assert(rows, problems)
  for _, row in ipairs(rows) do
    row.clean = rotation_of(assert(tagpose.solve(row.corners, camera, info.tag_size)))
  end
  return camera, info, rows
end

local function wrong(row, pose)
  return not pose or deg(rotation.angle(row.clean, rotation_of(pose))) > 30
end

-- the tracked rows by the age of their track: {first, last, rows, wrong, confident}
local AGES = { { 1, 1 }, { 2, 3 }, { 4, 10 }, { 11, 30 }, { 31, math.huge } }
local ages = {}
for k = 1, #AGES do ages[k] = { rows = 0, wrong = 0, confident = 0 } end

local function by_age(age, is_wrong, confidence)
  for k = 1, #AGES do
    if age >= AGES[k][1] and age <= AGES[k][2] then
      local a = ages[k]
      a.rows = a.rows + 1
      if is_wrong then
        a.wrong = a.wrong + 1
        if confidence and confidence >= 0.9 then a.confident = a.confident + 1 end
      end
    end
  end
end

-- the four ways over noisy corners; returns counts {single =, prior =, tracked =, smoothed =,
-- failed =}
local function score(camera, info, rows, noisy)
  local n = { single = 0, prior = 0, tracked = 0, smoothed = 0, failed = 0 }
  local last = {} -- tag -> {frame =, pose =}
  local has_tracker = tagpose.tracker ~= nil
  local tr = has_tracker and tagpose.tracker.new(camera, info.tag_size, { smooth = true })
  local tracked, age, counts = {}, {}, {}
  local i = 1
  while i <= #rows do
    local j, frame = i, {}
    while j <= #rows and rows[j].frame == rows[i].frame do
      local r = rows[j]
      frame[#frame + 1] = { id = r.tag, corners = noisy[j] }
      if not opt.quick then
          local single = tagpose.solve(noisy[j], camera, info.tag_size)
        if not single then n.failed = n.failed + 1 end
        if wrong(r, single) then n.single = n.single + 1 end
        local prev = last[r.tag]
        local prior = prev and prev.frame == r.frame - 1 and prev.pose or nil
        local pose = tagpose.solve(noisy[j], camera, info.tag_size, { prior = prior })
        if wrong(r, pose) then n.prior = n.prior + 1 end
        last[r.tag] = { frame = r.frame, pose = pose }
      end
      j = j + 1
    end
    if tr then
      local seen = tr:update(frame, rows[i].frame * opt.frame_time)
      for k = 1, #seen do
        tracked[i + k - 1] = seen[k].pose or false
        local t = seen[k].track
        if t then counts[t] = (counts[t] or 0) + 1 end
        age[i + k - 1] = t and counts[t] or 1
      end
    end
    i = j
  end
  if tr then
    local choice = tr:smooth()
    for r = 1, #rows do
      local pose = tracked[r] or nil
      local is_wrong = wrong(rows[r], pose)
      if is_wrong then n.tracked = n.tracked + 1 end
      by_age(age[r], is_wrong, pose and pose.confidence)
      if choice[r] == 2 then pose = pose.alternative end
      if wrong(rows[r], pose) then n.smoothed = n.smoothed + 1 end
    end
  else
    n.tracked, n.smoothed = nil, nil
  end
  return n
end

local sets = {}
local total_rows = 0
for _, dir in ipairs(opt.dirs) do
  local camera, info, rows = load(dir)
  sets[#sets + 1] = { name = dir:match("([^/]+)/*$"), camera = camera, info = info,
    rows = rows }
  total_rows = total_rows + #rows
end
print(("%d rows in %d logs; noise σ %s px, seeds %d..%d, frames %g s apart [%s]"):format(
  total_rows, #sets, table.concat(opt.sigmas, ", "), opt.from, opt.from + opt.seeds - 1,
  opt.frame_time, _VERSION
  .. (rawget(_G, "jit") and " (LuaJIT)" or "")))
print("| σ px | log | rows | single % | prior % | tracked % | smoothed % | failed |")
print("|---:|---|---:|---:|---:|---:|---:|---:|")
local function pct(k, rows)
  if k == nil then return "–" end
  return ("%.2f"):format(100 * k / rows)
end
for _, sigma in ipairs(opt.sigmas) do
  local all = { single = 0, prior = 0, tracked = 0, smoothed = 0, failed = 0, rows = 0 }
  for _, set in ipairs(sets) do
    local sum = { single = 0, prior = 0, tracked = 0, smoothed = 0, failed = 0 }
    for seed = opt.from, opt.from + opt.seeds - 1 do
      local rng = geometry.rng(1000 * seed + math.floor(sigma * 100) + #set.rows)
      local noisy = {}
      for r, row in ipairs(set.rows) do
        local c = {}
        for k = 1, 4 do
          local u, v = row.corners[k][1], row.corners[k][2]
          c[k] = { u + sigma * rng.normal(), v + sigma * rng.normal() }
        end
        noisy[r] = c
      end
      local n = score(set.camera, set.info, set.rows, noisy)
      for k in pairs(sum) do
        if n[k] == nil then sum[k] = false elseif sum[k] then sum[k] = sum[k] + n[k] end
      end
    end
    local rows = #set.rows * opt.seeds
    for k, v in pairs(sum) do
      if not v then all[k] = false elseif all[k] then all[k] = all[k] + v end
    end
    all.rows = all.rows + rows
    print(("| %g | %s | %d | %s | %s | %s | %s | %d |"):format(sigma, set.name, rows,
      pct(sum.single, rows), pct(sum.prior, rows), pct(sum.tracked or nil, rows),
      pct(sum.smoothed or nil, rows), sum.failed))
  end
  print(("| %g | **all** | %d | %s | %s | %s | %s | %d |"):format(sigma, all.rows,
    pct(all.single, all.rows), pct(all.prior, all.rows), pct(all.tracked or nil, all.rows),
    pct(all.smoothed or nil, all.rows), all.failed))
end
if opt.by_age then
  print()
  print("| track age (frames) | rows | tracked wrong % | wrong with confidence >= 0.9 |")
  print("|---|---:|---:|---:|")
  for k, a in ipairs(ages) do
    local range = AGES[k][2] == math.huge and (AGES[k][1] .. "+")
      or AGES[k][1] == AGES[k][2] and tostring(AGES[k][1]) or (AGES[k][1] .. "–" .. AGES[k][2])
    print(("| %s | %d | %s | %d |"):format(range, a.rows, pct(a.wrong, math.max(a.rows, 1)),
      a.confident))
  end
end
