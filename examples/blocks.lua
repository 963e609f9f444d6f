-- Block poses from a corner log, and (given the truth) the block-level figures of
-- bench/dev/PEERS.md.
--
--   lua5.4 examples/blocks.lua DATASET_DIR [--auto | --auto-floor | --up | --floor] [--track]
--     [--out FILE]
--     [--passes N] [--peers PEERS.md]
--
-- DATASET_DIR holds camera.lua (with tag_size and block_size), corners.csv (a corner log:
-- frame,tag,u1,v1,...,u4,v4, every visible tag of a frame, any order) and optionally truth.csv
-- (frame,block,x,y,z,qw,qx,qy,qz,faces_visible: block centre and block -> camera rotation)
-- and truth_tags.csv (frame,block,face,x,y,z,qw,qx,qy,qz, one row per corner row).
--
-- Without truth it prints the block poses as a CSV (frame,block,x,y,z,qw,qx,qy,qz,faces,error).
-- With truth it scores tagpose.block.solve five times - with nothing but the corners, with
-- up = "auto" (up from the frame's blocks seen with two or more faces), with up = "auto" and
-- floor = "auto" (the floor from them too), with an up vector, with an up vector and the floor
-- - and prints the table of bench/dev/PEERS.md beside the baseline's rows read from it (or from
-- the page --peers names; by default PEERS.md in the folder above DATASET_DIR). --auto,
-- --auto-floor, --up and --floor score only the run with up = "auto", with both "auto", with
-- up, with up and the floor (without truth --auto and --auto-floor run with those options
-- instead of none); --track passes each frame's
-- blocks to the next (for sequences, frames numbered consecutively); --out writes the block
-- poses of the (last) run; --passes sets the timing passes (median).
--
-- The up vector comes from the truth, as a robot's IMU would give it: the camera looks forward
-- and down by less than 45 degrees, and every block rests on a face, so in each frame the face
-- axis of a true block that is nearest the camera's -y is gravity's; up is the mean of those
-- axes over the frame's true blocks. The floor, as a robot that knows its camera's height
-- would give it: half a block below the lowest true centre along up (a stacked block whose
-- support is hidden would put it a block too high, which the solver's levels absorb). Nothing
-- else of the truth reaches the solver.
--
-- Scoring, as bench/dev/PEERS.md describes the benchmark's (its scorer is not part of this
-- repository; this file scores the same way): per frame, predicted blocks are matched to true
-- ones by the most matches, then the least total centre distance, within half a block; rotation
-- error is the least over the cube's 24 symmetries, a flip is an error over
-- 30 degrees. An unmatched true block is "merged" when a prediction matched to another block
-- lies within one block of it, else "missed". An unmatched prediction is a "split" of a found
-- block within half a block of it, or within 1.25 blocks when the prediction is not between
-- two true blocks (within half a block of the segment joining them), else "spurious".

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")

local sqrt, floor, deg, huge = math.sqrt, math.floor, math.deg, math.huge

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua examples/blocks.lua DATASET_DIR "
    .. "[--auto | --auto-floor | --up | --floor] [--track] [--out FILE] [--passes N] "
    .. "[--peers PEERS.md]\n")
  os.exit(2)
end

local opts = { passes = 5 }
do
  local i = 1
  while i <= #arg do
    local a = arg[i]
    if a == "--up" then
      opts.up = true
    elseif a == "--auto" then
      opts.auto = true
    elseif a == "--auto-floor" then
      opts.auto = "floor"
    elseif a == "--floor" then
      opts.up, opts.floor = true, true
    elseif a == "--track" then
      opts.track = true
    elseif a == "--out" then
      i = i + 1
      opts.out = arg[i] or usage("--out needs a file")
    elseif a == "--passes" then
      i = i + 1
      opts.passes = tonumber(arg[i]) or usage("--passes needs a number")
    elseif a == "--peers" then
      i = i + 1
      opts.peers = arg[i] or usage("--peers needs a file")
    elseif a:sub(1, 2) == "--" then
      usage("unknown option " .. a)
    elseif not opts.dir then
      opts.dir = a
    else
      usage("one data set directory expected")
    end
    i = i + 1
  end
  if not opts.dir then usage() end
end
local dir = opts.dir

local function exists(path)
  local f = io.open(path, "r")
  if f then f:close() end
  return f ~= nil
end

local camera, info = log.read_camera(dir .. "/camera.lua")
assert(camera, info)
local tag_size = assert(info.tag_size, "camera.lua has no tag_size")
local block_size = assert(info.block_size, "camera.lua has no block_size")
local rows, problems = log.read_corners(dir .. "/corners.csv")
assert(rows, problems)
for _, p in ipairs(problems) do
  io.stderr:write(("corners.csv line %d: %s\n"):format(p.line, p.reason))
end

-- frames in order of first appearance, each with its detections and corner rows
local frames, by_frame = {}, {}
local function frame_of(id)
  local f = by_frame[id]
  if not f then
    f = { frame = id, detections = {}, rows = {} }
    by_frame[id] = f
    frames[#frames + 1] = f
  end
  return f
end
for i, row in ipairs(rows) do
  local f = frame_of(row.frame)
  f.detections[#f.detections + 1] = { id = row.tag, corners = row.corners }
  f.rows[#f.rows + 1] = i
end

local truth
if exists(dir .. "/truth.csv") then
  truth = {}
  for _, t in ipairs(assert(log.read_csv(dir .. "/truth.csv"))) do
    local f = frame_of(t.frame) -- (new for a frame whose blocks show no tag)
    f.truth = f.truth or {}
    f.truth[#f.truth + 1] = { x = t.x, y = t.y, z = t.z, faces = t.faces_visible or 0,
      r = rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz) }
    truth[#truth + 1] = t
  end
  table.sort(frames, function(a, b) return a.frame < b.frame end)
  -- up, per frame: the mean of the true blocks' face axes nearest the camera's -y
  for _, f in ipairs(frames) do
    if f.truth then
      local ux, uy, uz = 0, 0, 0
      for _, t in ipairs(f.truth) do
        local r, best, bx, by, bz = t.r, -huge, 0, 0, 0
        for k = 1, 3 do
          for s = -1, 1, 2 do
            local x, y, z = s * r[k], s * r[3 + k], s * r[6 + k]
            if -y > best then best, bx, by, bz = -y, x, y, z end
          end
        end
        ux, uy, uz = ux + bx, uy + by, uz + bz
      end
      local n = sqrt(ux * ux + uy * uy + uz * uz)
      ux, uy, uz = ux / n, uy / n, uz / n
      f.up = { x = ux, y = uy, z = uz }
      -- the floor: half a block below the lowest true centre
      local low = huge
      for _, t in ipairs(f.truth) do
        local h = ux * t.x + uy * t.y + uz * t.z
        if h < low then low = h end
      end
      f.floor = 0.5 * block_size - low
    end
  end
end

-- one run over every frame; returns the predictions per frame and µs per frame
local function run(with_up, with_floor, auto)
  local results, times = {}, {}
  for pass = 1, opts.passes do
    local previous, last_frame = nil, nil
    local t0 = os.clock()
    for k, f in ipairs(frames) do
      local options = {}
      if with_up then options.up = f.up end
      if auto then options.up = "auto" end
      if auto == "floor" then options.floor = "auto" end
      if with_floor then options.floor = f.floor end
      if opts.track and last_frame == f.frame - 1 then options.previous = previous end
      local blocks, err = tagpose.block.solve(f.detections, camera, tag_size, block_size, options)
      if pass == 1 then results[k] = blocks or {} end
      if not blocks and pass == 1 and #f.detections > 0 then
        io.stderr:write(("frame %s: %s\n"):format(tostring(f.frame), err))
      end
      previous, last_frame = blocks, f.frame
    end
    times[pass] = os.clock() - t0
  end
  table.sort(times)
  return results, times[floor((#times + 1) / 2)] / #frames * 1e6
end

local function write_poses(path, results)
  local out = path == "-" and io.stdout or assert(io.open(path, "w"))
  out:write("frame,block,x,y,z,qw,qx,qy,qz,faces,error\n")
  for k, f in ipairs(frames) do
    for _, b in ipairs(results[k]) do
      local p, q = b.position, b.quaternion
      out:write(("%s,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%.6g\n"):format(
        tostring(f.frame), b.id, p.x, p.y, p.z, q.w, q.x, q.y, q.z, b.faces, b.error))
    end
  end
  if out ~= io.stdout then out:close() end
end

if not truth then
  local results, us = run(false, false, opts.auto)
  write_poses(opts.out or "-", results)
  io.stderr:write(("%d frames, %.0f µs per frame (%s)\n"):format(#frames, us, _VERSION))
  return
end

---------------------------------------------------------------------------------------------
-- scoring

local function percentile(sorted, p)
  local n = #sorted
  if n == 0 then return 0 / 0 end
  local pos = p * (n - 1) + 1
  local lo = floor(pos)
  if lo >= n then return sorted[n] end
  return sorted[lo] + (pos - lo) * (sorted[lo + 1] - sorted[lo])
end

local function dist(a, b)
  return sqrt((a.x - b.x) ^ 2 + (a.y - b.y) ^ 2 + (a.z - b.z) ^ 2)
end

-- the most matches, then the least total distance, within the gate (exhaustive: a frame has
-- a few blocks)
local function match(T, P, gate)
  local best_n, best_d, best = -1, huge, {}
  local cur, used = {}, {}
  local function search(i, n, d)
    if i > #T then
      if n > best_n or (n == best_n and d < best_d) then
        best_n, best_d = n, d
        for k = 1, #T do best[k] = cur[k] end
      end
      return
    end
    if n + (#T - i + 1) < best_n then return end
    for j = 1, #P do
      if not used[j] then
        local dj = dist(T[i], P[j])
        if dj < gate then
          used[j], cur[i] = true, j
          search(i + 1, n + 1, d + dj)
          used[j], cur[i] = false, nil
        end
      end
    end
    cur[i] = false
    search(i + 1, n, d)
  end
  search(1, 0, 0)
  return best
end

local function rotation_error(rt, re)
  local best = huge
  local m = {}
  for _, g in ipairs(cube.ROTATIONS) do
    rotation.multiply(rt, g, m)
    local a = rotation.angle(m, re)
    if a < best then best = a end
  end
  return deg(best)
end

-- distance from p to the segment ab, and whether its projection falls inside
local function segment_distance(p, a, b)
  local ux, uy, uz = b.x - a.x, b.y - a.y, b.z - a.z
  local l2 = ux * ux + uy * uy + uz * uz
  local s = ((p.x - a.x) * ux + (p.y - a.y) * uy + (p.z - a.z) * uz) / l2
  if s < 0 or s > 1 then return huge end
  local qx, qy, qz = a.x + s * ux, a.y + s * uy, a.z + s * uz
  return sqrt((p.x - qx) ^ 2 + (p.y - qy) ^ 2 + (p.z - qz) ^ 2)
end

local function score(results)
  local classes = { all = {}, one = {}, more = {} }
  for _, c in pairs(classes) do
    c.true_n, c.found, c.missed, c.merged, c.split, c.ce, c.re, c.flips = 0, 0, 0, 0, 0, {}, {},
      0
  end
  local preds, matched_preds, spurious = 0, 0, 0
  for k, f in ipairs(frames) do
    local T = f.truth or {}
    local P = {}
    for j, b in ipairs(results[k]) do
      P[j] = { x = b.position.x, y = b.position.y, z = b.position.z,
        r = rotation.from_nested(b.rotation) }
    end
    preds = preds + #P
    local m = match(T, P, 0.5 * block_size)
    local claimed = {}
    for i = 1, #T do
      if m[i] then claimed[m[i]] = i end
    end
    local split_of = {}
    for j = 1, #P do
      if not claimed[j] then
        local near, nd = nil, huge
        for i = 1, #T do
          if m[i] then
            local d = dist(P[j], T[i])
            if d < nd then near, nd = i, d end
          end
        end
        local between = false
        for a = 1, #T do
          for b = a + 1, #T do
            if segment_distance(P[j], T[a], T[b]) < 0.5 * block_size then between = true end
          end
        end
        if near and (nd < 0.5 * block_size or (nd < 1.25 * block_size and not between)) then
          split_of[near] = true
        else
          spurious = spurious + 1
        end
      end
    end
    for i, t in ipairs(T) do
      local cls = t.faces <= 1 and classes.one or classes.more
      for _, c in ipairs({ classes.all, cls }) do
        c.true_n = c.true_n + 1
        if m[i] then
          local p = P[m[i]]
          c.found = c.found + 1
          c.ce[#c.ce + 1] = dist(p, t) * 1000
          local e = rotation_error(t.r, p.r)
          c.re[#c.re + 1] = e
          if e > 30 then c.flips = c.flips + 1 end
          if split_of[i] then c.split = c.split + 1 end
        else
          local merged = false
          for j = 1, #P do
            if claimed[j] and claimed[j] ~= i and dist(P[j], t) < block_size then merged = true end
          end
          if merged then c.merged = c.merged + 1 else c.missed = c.missed + 1 end
        end
      end
    end
    for j = 1, #P do
      if claimed[j] then matched_preds = matched_preds + 1 end
    end
  end
  for _, c in pairs(classes) do
    table.sort(c.ce)
    table.sort(c.re)
  end
  classes.all.precision = preds > 0 and 100 * matched_preds / preds or 0 / 0
  classes.all.spurious = spurious
  return classes
end

-- the single-tag solve's flips on the tags of blocks seen with one face (truth_tags.csv)
local function single_tag_flips()
  if not exists(dir .. "/truth_tags.csv") then return nil end
  local tt = assert(log.read_csv(dir .. "/truth_tags.csv"))
  if #tt ~= #rows then return nil end
  local faces_of = {}
  for _, t in ipairs(truth) do faces_of[t.frame .. ":" .. t.block] = t.faces_visible end
  local n, flips = 0, 0
  for i, row in ipairs(rows) do
    local t = tt[i]
    if faces_of[t.frame .. ":" .. t.block] == 1 then
      local pose = tagpose.solve(row.corners, camera, tag_size)
      n = n + 1
      if pose then
        local e = deg(rotation.angle(rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz),
          rotation.from_nested(pose.rotation)))
        if e > 30 then flips = flips + 1 end
      else
        flips = flips + 1
      end
    end
  end
  return n > 0 and 100 * flips / n or nil, n
end

local function fmt(v, digits)
  if v == nil then return "–" end
  if v ~= v then return "nan" end
  return ("%." .. (digits or 2) .. "f"):format(v)
end

local function rows_of(name, c, us)
  local out = {}
  local order = { { "all", c.all }, { "1 face", c.one }, { "2+ faces", c.more } }
  for k, item in ipairs(order) do
    local label, s = item[1], item[2]
    out[#out + 1] = ("| %s | %s | %d | %s | %s | %d | %d | %d | %s | %s | %s | %s | %s | %s | %s |")
      :format(name, label, s.true_n, fmt(100 * s.found / s.true_n), k == 1 and fmt(s.precision)
        or "–", s.missed, s.merged, s.split, k == 1 and tostring(s.spurious) or "–",
        fmt(percentile(s.ce, 0.5)), fmt(percentile(s.ce, 0.95), 1), fmt(percentile(s.re, 0.5)),
        fmt(percentile(s.re, 0.95), 1), fmt(100 * s.flips / math.max(#s.re, 1)),
        k == 1 and ("%.0f"):format(us) or "")
  end
  return out
end

local function peer_rows()
  local path = opts.peers or (dir .. "/../PEERS.md")
  local f = io.open(path, "r")
  if not f then return {} end
  local out = {}
  for line in f:lines() do
    if line:match("^| baseline_ippe_push |") then out[#out + 1] = line end
  end
  f:close()
  return out
end

local header = "| solver | blocks seen with | true | recall % | precision % | missed | merged | "
  .. "split | spurious | c med mm | c p95 mm | R med ° | R p95 ° | flip % | µs/frame |\n"
  .. "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"

local lines = {}
local runs = { { false, false }, { false, false, true }, { false, false, "floor" },
  { true, false }, { true, true } }
if opts.floor then
  runs = { { true, true } }
elseif opts.up then
  runs = { { true, false } }
elseif opts.auto then
  runs = { { false, false, opts.auto } }
end
for _, mode in ipairs(runs) do
  local with_up, with_floor, auto = mode[1], mode[2], mode[3]
  local results, us = run(with_up, with_floor, auto)
  if opts.out then write_poses(opts.out, results) end
  local name = "tagpose.block" .. (with_floor and " (up, floor)" or with_up and " (up)"
    or auto == "floor" and " (up auto, floor auto)" or auto and " (up auto)" or "")
    .. (opts.track and " (track)" or "")
  for _, l in ipairs(rows_of(name, score(results), us)) do lines[#lines + 1] = l end
end
for _, l in ipairs(peer_rows()) do lines[#lines + 1] = l end

print(("%s: %d frames, %d true blocks; %s, median of %d passes"):format(dir, #frames, #truth,
  rawget(_G, "jit") and rawget(_G, "jit").version or _VERSION, opts.passes))
print(header)
for _, l in ipairs(lines) do print(l) end
local flips, n = single_tag_flips()
if flips then
  print(("\nsingle-tag tagpose.solve on the %d tags of blocks seen with one face: %.2f %% flips")
    :format(n, flips))
end
