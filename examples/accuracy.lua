-- Score tagpose on a data set in the format of shared/bench/dev (camera.lua, corners.csv,
-- truth.csv), with the metrics of its PEERS.md, and print the peers' rows beside ours.
--
--   lua5.4 examples/accuracy.lua DATASET_DIR [--method refined|seed] [--track | --smooth]
--     [--fps F] [--peers FILE]
--
-- DATASET_DIR may also be a directory of data sets (every subdirectory with a corners.csv is
-- scored). PEERS.md is looked for beside the data sets unless --peers names it.
-- With --track, the rows are fed frame by frame to tagpose.tracker (causal: each tag's track
-- carries the branch from frame to frame); with --smooth, the tracker's choices are then
-- revised with the later frames (tracker:smooth()). A frame's time is the corner log's `time`
-- column when it has one, else frame / F (default 30 frames per second). With either, the
-- calibration of pose.confidence is printed too: expected calibration error (10 equal bins)
-- over the rows whose two candidates differ by more than 10°, and the share of wrong branches
-- among the rows with confidence >= 0.95.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")

local sqrt, abs, floor, deg = math.sqrt, math.abs, math.floor, math.deg

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua examples/accuracy.lua DATASET_DIR "
    .. "[--method refined|seed] [--track | --smooth] [--fps F] [--peers PEERS.md]\n")
  os.exit(2)
end

local args = { method = nil, track = false, smooth = false, fps = 30 }
do
  local i = 1
  while i <= #arg do
    local a = arg[i]
    if a == "--method" then
      i = i + 1
      args.method = arg[i] or usage("--method needs a value")
    elseif a == "--track" then
      args.track = true
    elseif a == "--smooth" then
      args.track, args.smooth = true, true
    elseif a == "--fps" then
      i = i + 1
      args.fps = tonumber(arg[i]) or usage("--fps needs a number")
    elseif a == "--peers" then
      i = i + 1
      args.peers = arg[i] or usage("--peers needs a value")
    elseif a:sub(1, 2) == "--" then
      usage("unknown option " .. a)
    elseif not args.dir then
      args.dir = a
    else
      usage("one data set directory expected")
    end
    i = i + 1
  end
  if not args.dir then usage() end
end

local function exists(path)
  local f = io.open(path, "r")
  if f then f:close() end
  return f ~= nil
end

-- linear-interpolated percentile (numpy's default)
local function percentile(sorted, p)
  local n = #sorted
  if n == 0 then return 0 / 0 end
  local pos = p * (n - 1) + 1
  local lo = floor(pos)
  local frac = pos - lo
  if lo >= n then return sorted[n] end
  return sorted[lo] + frac * (sorted[lo + 1] - sorted[lo])
end

local function sorted_copy(t)
  local c = {}
  for i = 1, #t do c[i] = t[i] end
  table.sort(c)
  return c
end

local function quat_matrix(w, x, y, z)
  return rotation.from_quaternion(w, x, y, z)
end

local function fmt(v)
  if v ~= v then return "nan" end
  if v == 0 then return "0" end
  local a = abs(v)
  if a >= 1e5 or a < 1e-3 then return ("%.1e"):format(v) end
  if a >= 100 then return ("%.0f"):format(v) end
  if a >= 10 then return ("%.1f"):format(v) end
  if a >= 1 then return ("%.2f"):format(v) end
  return ("%.3g"):format(v)
end

-- score one data set; returns the metrics table
local function score(dir)
  local camera, info = log.read_camera(dir .. "/camera.lua")
  assert(camera, info)
  local rows, problems = log.read_corners(dir .. "/corners.csv")
  assert(rows, problems)
  assert(#problems == 0, "malformed corner rows in " .. dir)
  local truth_file = exists(dir .. "/truth_tags.csv") and "/truth_tags.csv" or "/truth.csv"
  local truth = assert(log.read_csv(dir .. truth_file))
  assert(#truth == #rows, "truth and corners differ in length")
  -- sequences (frame = sequence * 1000 + k) are named in meta.json
  local meta = io.open(dir .. "/meta.json", "r")
  local sequences = meta and meta:read("*a"):find('"sequences"%s*:%s*%[') ~= nil
  if meta then meta:close() end
  -- the poses: one solve per row, or the tracker fed frame by frame
  local t0 = os.clock()
  local poses, confidences = {}, {}
  if args.track then
    local tr = tagpose.tracker.new(camera, info.tag_size, { method = args.method,
      smooth = args.smooth })
    local i = 1
    while i <= #rows do
      local j, frame = i, {}
      while j <= #rows and rows[j].frame == rows[i].frame do
        frame[#frame + 1] = { id = rows[j].tag, corners = rows[j].corners }
        j = j + 1
      end
      local time = rows[i].fields.time or rows[i].frame / args.fps
      local seen = tr:update(frame, time)
      for k = 1, #seen do
        poses[i + k - 1] = seen[k].pose or false
        confidences[i + k - 1] = seen[k].pose and seen[k].pose.confidence
      end
      i = j
    end
    if args.smooth then
      local choice, confidence = tr:smooth()
      for r = 1, #rows do
        if choice[r] == 2 then poses[r] = poses[r].alternative end
        if choice[r] > 0 then confidences[r] = confidence[r] end
      end
    end
  else
    local options = { method = args.method }
    for i, row in ipairs(rows) do
      poses[i] = tagpose.solve(row.corners, camera, info.tag_size, options) or false
      confidences[i] = poses[i] and poses[i].confidence
    end
  end
  local solve_seconds = os.clock() - t0
  local ok, nan, iters, iters_n = 0, 0, 0, 0
  local te, tp, re, flips, mirrors, tilted = {}, {}, {}, 0, 0, 0
  local est = {} -- per row: {r =, t =, flip =} or false
  -- calibration: 10 equal bins of confidence, over rows with two candidates > 10° apart
  local bins, amb, sure, sure_wrong, stake = {}, 0, 0, 0, 0
  for b = 1, 10 do bins[b] = { n = 0, right = 0, conf = 0 } end
  for i, row in ipairs(rows) do
    local pose = poses[i]
    est[i] = false
    if pose then
      local p = pose.position
      local finite = p.x == p.x and p.y == p.y and p.z == p.z
      if not finite then nan = nan + 1 end
      ok = ok + 1
      local tr = truth[i]
      local rt = quat_matrix(tr.qw, tr.qx, tr.qy, tr.qz)
      local r = rotation.from_nested(pose.rotation)
      local dx, dy, dz = p.x - tr.x, p.y - tr.y, p.z - tr.z
      local dist = sqrt(tr.x ^ 2 + tr.y ^ 2 + tr.z ^ 2)
      local terr = sqrt(dx * dx + dy * dy + dz * dz)
      te[#te + 1] = terr * 1000
      tp[#tp + 1] = terr / dist * 100
      local rerr = deg(rotation.angle(rt, r))
      re[#re + 1] = rerr
      local flip = rerr > 30
      if flip then flips = flips + 1 end
      -- mirror: estimated normal nearer the true normal mirrored about the line of sight
      local lx, ly, lz = tr.x / dist, tr.y / dist, tr.z / dist
      local nx, ny, nz = rt[3], rt[6], rt[9]
      local c = nx * lx + ny * ly + nz * lz
      if deg(math.acos(math.min(1, abs(c)))) >= 10 then
        tilted = tilted + 1
        local mx, my, mz = 2 * c * lx - nx, 2 * c * ly - ny, 2 * c * lz - nz
        local ex, ey, ez = r[3], r[6], r[9]
        local dn = (ex - nx) ^ 2 + (ey - ny) ^ 2 + (ez - nz) ^ 2
        local dm = (ex - mx) ^ 2 + (ey - my) ^ 2 + (ez - mz) ^ 2
        if dm < dn then mirrors = mirrors + 1 end
      end
      iters = iters + pose.iterations
      iters_n = iters_n + 1
      est[i] = { r = r, t = { p.x, p.y, p.z }, rt = rt, tt = { tr.x, tr.y, tr.z }, flip = flip,
        key = tr.track or row.tag }
      local alt, conf = pose.alternative, confidences[i]
      if alt then
        -- at stake: one candidate within 30° of the truth and the other not, so that the
        -- choice decides a flip (a coin toss flips half of these rows)
        local ea = deg(rotation.angle(rt, rotation.from_nested(alt.rotation)))
        if (rerr > 30) ~= (ea > 30) then stake = stake + 1 end
      end
      if alt and conf then
        local ra = rotation.from_nested(alt.rotation)
        if deg(rotation.angle(r, ra)) > 10 then
          -- the returned pose is on the true branch when it is the nearer to the truth
          local right = rerr <= deg(rotation.angle(rt, ra))
          amb = amb + 1
          local b = bins[conf >= 1 and 10 or floor(conf * 10) + 1]
          b.n, b.conf = b.n + 1, b.conf + conf
          if right then b.right = b.right + 1 end
          if conf >= 0.95 then
            sure = sure + 1
            if not right then sure_wrong = sure_wrong + 1 end
          end
        end
      end
    end
  end
  local seconds = solve_seconds
  local ece = 0
  for b = 1, 10 do
    local B = bins[b]
    if B.n > 0 then ece = ece + B.n / amb * abs(B.right / B.n - B.conf / B.n) end
  end
  local m = {
    name = dir:match("([^/]+)/*$"),
    rows = #rows,
    ok = 100 * ok / #rows,
    nan = nan,
    t_med = percentile(sorted_copy(te), 0.5),
    t_p95 = percentile(sorted_copy(te), 0.95),
    tp_med = percentile(sorted_copy(tp), 0.5),
    tp_p95 = percentile(sorted_copy(tp), 0.95),
    r_med = percentile(sorted_copy(re), 0.5),
    r_p95 = percentile(sorted_copy(re), 0.95),
    flip = ok > 0 and 100 * flips / ok or 0 / 0,
    mirror = tilted > 0 and 100 * mirrors / tilted or 0 / 0,
    iters = iters_n > 0 and iters / iters_n or 0 / 0,
    us = seconds / #rows * 1e6,
    ece = amb > 0 and ece or 0 / 0,
    ambiguous = amb,
    sure = sure,
    sure_wrong = sure > 0 and 100 * sure_wrong / sure or 0 / 0,
    stake = ok > 0 and 100 * stake / ok or 0 / 0,
  }
  if sequences then
    local jt, jr, sw = {}, {}, 0
    local last = {} -- key (the truth's track, else the tag) -> row
    for i = 1, #rows do
      local b = est[i]
      local key = b and b.key
      local h = key ~= nil and last[key]
      local a = h and est[h]
      local consecutive = h and rows[i].frame == rows[h].frame + 1
      if key ~= nil then last[key] = i end
      if a and b and consecutive then
        local d = 0
        for k = 1, 3 do
          d = d + ((b.t[k] - a.t[k]) - (b.tt[k] - a.tt[k])) ^ 2
        end
        jt[#jt + 1] = sqrt(d) * 1000
        local de = rotation.multiply(b.r, rotation.transpose(a.r))
        local dt = rotation.multiply(b.rt, rotation.transpose(a.rt))
        jr[#jr + 1] = deg(rotation.angle(de, dt))
        if a.flip ~= b.flip then sw = sw + 1 end
      end
    end
    m.jit_t_med = percentile(sorted_copy(jt), 0.5)
    m.jit_t_p95 = percentile(sorted_copy(jt), 0.95)
    m.jit_r_med = percentile(sorted_copy(jr), 0.5)
    m.jit_r_p95 = percentile(sorted_copy(jr), 0.95)
    m.flip_sw = sw
  end
  return m
end

local COLUMNS = { "ok", "nan", "t_med", "t_p95", "tp_med", "tp_p95", "r_med", "r_p95", "flip",
  "mirror", "iters" }
local SEQ_COLUMNS = { "jit_t_med", "jit_t_p95", "jit_r_med", "jit_r_p95", "flip_sw" }
local HEADER = "| solver | ok % | NaN | t med mm | t p95 mm | t med % | t p95 % "
  .. "| R med ° | R p95 ° | flip % | mirror % | iters |"
local SEQ_HEADER = " jit t med mm | jit t p95 mm | jit R med ° | jit R p95 ° | flip sw |"

-- the peers' rows of PEERS.md for one data set: name -> metrics
local function read_peers(path, set)
  local f = path and io.open(path, "r")
  if not f then return nil end
  local peers, order, inside, seen = {}, {}, false, false
  for line in f:lines() do
    local title = line:match("^### (%S+)")
    if title then
      inside = title == set and not line:find(":")
    elseif inside and seen and not line:match("^|") then
      inside = false -- only the first table of the section
    elseif inside and line:match("^| [%w_]+ |") and not line:match("^| solver") then
      seen = true
      local cells = {}
      for c in line:gmatch("([^|]+)") do cells[#cells + 1] = c:match("^%s*(.-)%s*$") end
      local name = cells[1]
      if name and name ~= "" then
        local m = { name = name }
        local cols = {}
        for _, c in ipairs(COLUMNS) do cols[#cols + 1] = c end
        for _, c in ipairs(SEQ_COLUMNS) do cols[#cols + 1] = c end
        for k, c in ipairs(cols) do
          m[c] = tonumber(cells[k + 1])
        end
        peers[name] = m
        order[#order + 1] = name
      end
    end
  end
  f:close()
  return peers, order
end

local function print_row(label, m, seq)
  local cells = { label }
  for _, c in ipairs(COLUMNS) do
    cells[#cells + 1] = m[c] and (c == "ok" or c == "flip" or c == "mirror")
      and ("%.2f"):format(m[c]) or (m[c] and fmt(m[c]) or "–")
  end
  if seq then
    for _, c in ipairs(SEQ_COLUMNS) do cells[#cells + 1] = m[c] and fmt(m[c]) or "–" end
  end
  print("| " .. table.concat(cells, " | ") .. " |")
end

-- the issue's bar: each metric within tolerance of the best peer
local function check(m, peers, order)
  local lower = { "t_med", "t_p95", "tp_med", "tp_p95", "r_med", "r_p95", "flip" }
  local slack = { t_med = 1.05, t_p95 = 1.05, tp_med = 1.05, tp_p95 = 1.05, r_med = 1.05,
    r_p95 = 1.10 }
  local verdicts = {}
  for _, c in ipairs(lower) do
    local best, who = math.huge, nil
    for _, name in ipairs(order) do
      local v = peers[name][c]
      if v and v < best and name ~= "seed_ref" then best, who = v, name end
    end
    if who and best < 1e-6 and c ~= "flip" then
      -- exact data: both at round-off
      verdicts[#verdicts + 1] = ("%s %s (round-off)"):format(c, m[c] < 1e-6 and "ok" or "MISS")
    elseif who then
      local bar = c == "flip" and best + 1 or best * slack[c]
      verdicts[#verdicts + 1] = ("%s %s (best %s %s, bar %s)"):format(c, m[c] <= bar and "ok"
        or "MISS", fmt(best), who, fmt(bar))
    end
  end
  print("  vs best peer: " .. table.concat(verdicts, "; "))
end

local function run(dir)
  local m = score(dir)
  local seq = m.jit_t_med ~= nil
  local label = "tagpose " .. (args.method or "default")
    .. (args.smooth and " --smooth" or args.track and " --track" or "")
  print(("### %s (%d rows)  [%s, %s, %.1f µs/row]"):format(m.name, m.rows,
    _VERSION .. (rawget(_G, "jit") and " (LuaJIT)" or ""), label, m.us))
  print(HEADER .. (seq and SEQ_HEADER or ""))
  print("|---|" .. ("---:|"):rep(#COLUMNS + (seq and #SEQ_COLUMNS or 0)))
  print_row(label, m, seq)
  local peers_path = args.peers or (dir:gsub("/*$", "") .. "/../PEERS.md")
  local peers, order = read_peers(peers_path, m.name)
  if peers and #order > 0 then
    for _, name in ipairs(order) do print_row(name, peers[name], seq) end
    check(m, peers, order)
  end
  print(("  at stake: %.2f %% of the rows (one candidate within 30° of the truth, the other"
    .. " not: a coin toss flips half of them)"):format(m.stake))
  if args.track then
    print(("  confidence: ECE %.3f over %d rows with candidates > 10° apart; confidence >= 0.95"
      .. " on %d rows, wrong branch on %s of them"):format(m.ece, m.ambiguous, m.sure,
      m.sure > 0 and ("%.2f %%"):format(m.sure_wrong) or "–"))
  end
  print()
end

if exists(args.dir .. "/corners.csv") then
  run(args.dir)
else
  local p = io.popen('ls -1 "' .. args.dir .. '"')
  local names = {}
  for name in p:lines() do names[#names + 1] = name end
  p:close()
  table.sort(names)
  for _, name in ipairs(names) do
    local sub = args.dir:gsub("/*$", "") .. "/" .. name
    -- (a set of tag poses has its camera.lua; a drive log's robot poses are localization's)
    if exists(sub .. "/corners.csv") and exists(sub .. "/truth.csv")
      and exists(sub .. "/camera.lua") then
      run(sub)
    end
  end
end
