-- The tracker's figures pooled over many synthetic sequence sets, by kind of trajectory: wrong
-- rows (single frame, tracked, smoothed, and an oracle that links the branches perfectly), and
-- how the tracked poses' covariances cover the truth.
--
--   luajit bench/track_pool.lua DIR ... [--sigma S | --meta-sigma] [--kinds] [--first N]
--     [--quick] [--by-set] [--set NAME=VALUE] [--dump FILE]
--
-- DIR: data sets in the format of bench/dev (camera.lua, corners.csv, truth.csv, meta.json
-- naming the sequences), or directories of them (bench/make_sequences.lua writes them). Each
-- set is fed frame by frame to `tagpose.tracker` (times from the log's `time` column, else
-- frame / 30) with `smooth = true`, and with `sigma = S` (`--sigma`) or each set's own σ
-- (`--meta-sigma`: meta.json's noise.sigma_px); without either, the tracker's default.
--
-- A row is wrong when its rotation is more than 30° from the truth. The oracle knows which of
-- a frame's two candidates is on the true branch (the one nearer the truth) and so links the
-- branches of consecutive frames perfectly; it chooses the branch that the frames' evidence
-- (`tagpose.track.evidence` at the set's σ) favours in sum, over the track so far (causal) or
-- over the whole track (smoothed), a tie counted as half wrong: the figure a filter could reach
-- if it never lost the branch through a crossing.
--
-- Coverage: the share of rows whose truth lies inside the 95 % region of the returned pose's
-- covariance: the 6-dof ellipsoid (Mahalanobis² < 12.59) and each position axis's interval
-- (|error| < 1.96 sd); printed for all rows, for rows on the right and on the wrong branch (the
-- returned pose the candidate farther from the truth), for the flipped rows (more than 30° off),
-- for the first N frames of a track (`--first`, default 5) and the others, and for the true-branch
-- candidate (of the pose and its alternative, the nearer the truth) as docs/uncertainty.md
-- scores a single frame. `--dump FILE` writes every row's pose, confidence and smoothed choice
-- with 17 digits (for checking that a change leaves them bit for bit). `--quick` leaves out the
-- single frame and the coverage; `--by-set` prints each set's tracked and smoothed figures (for
-- paired comparisons between two versions); `--set NAME=VALUE` sets a `tagpose.track` constant
-- (for measuring it).

package.path = "./src/?.lua;./src/?/init.lua;./bench/lib/?.lua;" .. package.path
local bench = require("confidence")
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local track = require("tagpose.track")
local compat = require("tagpose.core.compat")

local sqrt, abs, deg, floor = math.sqrt, math.abs, math.deg, math.floor
local atan2 = compat.atan2

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua bench/track_pool.lua DIR ... "
    .. "[--sigma S | --meta-sigma] [--kinds] [--first N] [--quick] [--by-set] [--set NAME=VALUE] "
    .. "[--dump FILE]\n")
  os.exit(2)
end

local opt = { first = 5 }
local function flag(name)
  return function() opt[name] = true end
end
opt.dirs = bench.arguments(arg, {
  ["--sigma"] = function(take)
    opt.sigma = tonumber(take() or "") or usage("--sigma needs a number")
  end,
  ["--meta-sigma"] = flag("meta_sigma"),
  ["--kinds"] = flag("kinds"),
  ["--first"] = function(take)
    opt.first = tonumber(take() or "") or usage("--first needs a number")
  end,
  ["--by-set"] = flag("by_set"),
  ["--quick"] = flag("quick"),
  ["--set"] = bench.set_constant(track, usage),
  ["--dump"] = function(take) opt.dump = take() or usage("--dump needs a file") end,
}, usage)
if #opt.dirs == 0 then usage() end

-- meta.json: σ and the kind of each sequence (by track, else by sequence number)
local function read_meta(dir)
  local f = io.open(dir .. "/meta.json", "r")
  local text = f and f:read("*a") or ""
  if f then f:close() end
  local noise = text:match('"noise"%s*:%s*(%b{})')
  local sigma = noise and tonumber(noise:match('"sigma_px"%s*:%s*([-%d.eE+]+)'))
  local by_track, by_sequence = {}, {}
  local list = text:match('"sequences"%s*:%s*(%b[])')
  for item in (list or ""):gmatch("%b{}") do
    local name = item:match('"name"%s*:%s*"([^"]*)"')
    local tr, sq = tonumber(item:match('"track"%s*:%s*(%d+)')),
      tonumber(item:match('"sequence"%s*:%s*(%d+)'))
    if tr then by_track[tr] = name elseif sq then by_sequence[sq] = name end
  end
  return sigma, by_track, by_sequence
end

-- Mahalanobis² of e against the top-left n×n block of the nested C (nil: singular)
local function mahalanobis(C, e, n)
  local a, b = {}, {}
  for i = 1, n do
    a[i] = {}
    for j = 1, n do a[i][j] = C[i][j] end
    b[i] = e[i]
  end
  for c = 1, n do
    local p = c
    for r = c + 1, n do
      if abs(a[r][c]) > abs(a[p][c]) then p = r end
    end
    if a[p][c] == 0 then return nil end
    a[c], a[p], b[c], b[p] = a[p], a[c], b[p], b[c]
    for r = c + 1, n do
      local f = a[r][c] / a[c][c]
      for j = c, n do a[r][j] = a[r][j] - f * a[c][j] end
      b[r] = b[r] - f * b[c]
    end
  end
  for r = n, 1, -1 do
    local s = b[r]
    for j = r + 1, n do s = s - a[r][j] * b[j] end
    b[r] = s / a[r][r]
  end
  local m = 0
  for i = 1, n do m = m + e[i] * b[i] end
  return m
end

-- (t_true - t, r) with R_true = exp([r]×) R, and the rotation error in degrees
local function error_of(p, rt, tt)
  local r = rotation.from_nested(p.rotation)
  local w, x, y, z = rotation.to_quaternion(rotation.multiply_transpose(rt, r))
  local s = sqrt(x * x + y * y + z * z)
  local f = s > 1e-12 and 2 * atan2(s, w) / s or 2
  local pp = p.position
  local e = { tt[1] - pp.x, tt[2] - pp.y, tt[3] - pp.z, f * x, f * y, f * z }
  return e, deg(sqrt(e[4] ^ 2 + e[5] ^ 2 + e[6] ^ 2))
end

-- coverage counters: n, 6-dof inside, per-axis inside
local function counter() return { n = 0, six = 0, x = 0, y = 0, z = 0, m2 = 0 } end
local function cover(c, cov, e)
  c.n = c.n + 1
  local m2 = mahalanobis(cov, e, 6) or math.huge
  c.m2 = c.m2 + math.min(m2, 1e3)
  if m2 < 12.59 then c.six = c.six + 1 end
  if abs(e[1]) < 1.96 * sqrt(cov[1][1]) then c.x = c.x + 1 end
  if abs(e[2]) < 1.96 * sqrt(cov[2][2]) then c.y = c.y + 1 end
  if abs(e[3]) < 1.96 * sqrt(cov[3][3]) then c.z = c.z + 1 end
end

local pooled = { rows = 0, single = 0, tracked = 0, smoothed = 0, oracle = 0, oracle_s = 0 }
local kinds, kind_order = {}, {}
local cov = { all = counter(), right = counter(), wrong = counter(), flipped = counter(),
  early = counter(), late = counter(), true_branch = counter() }
local dump = opt.dump and assert(io.open(opt.dump, "w"))

local function kind_row(name)
  local k = kinds[name]
  if not k then
    k = { rows = 0, single = 0, tracked = 0, smoothed = 0, oracle = 0, oracle_s = 0 }
    kinds[name] = k
    kind_order[#kind_order + 1] = name
  end
  return k
end

local function add(name, field, v)
  pooled[field] = pooled[field] + v
  local k = kind_row(name)
  k[field] = k[field] + v
end

-- Count one row's coverage: the returned pose p (error e), flipped or not, on the right branch
-- or not, at its track's age; and the true-branch candidate's (the alternative's, error ea).
local function cover_row(p, e, flipped, right, age, alt, ea)
  local c = p.covariance
  cover(cov.all, c, e)
  cover(right and cov.right or cov.wrong, c, e)
  if flipped then cover(cov.flipped, c, e) end
  cover(age <= opt.first and cov.early or cov.late, c, e)
  if right then
    cover(cov.true_branch, c, e)
  else
    cover(cov.true_branch, alt.covariance, ea)
  end
end

-- The rows fed frame by frame to a tracker: per row {pose =, track =, new =}, and the
-- smoothed choices.
local function tracked(camera, size, sigma, rows)
  local tr = tagpose.tracker.new(camera, size, { smooth = true, sigma = sigma })
  local rec = {}
  local i = 1
  while i <= #rows do
    local j, frame = i, {}
    while j <= #rows and rows[j].frame == rows[i].frame do
      frame[#frame + 1] = { id = rows[j].tag, corners = rows[j].corners }
      j = j + 1
    end
    local seen = tr:update(frame, rows[i].fields.time or rows[i].frame / 30)
    for k = 1, #seen do
      rec[i + k - 1] = { pose = seen[k].pose, track = seen[k].track, new = seen[k].new }
    end
    i = j
  end
  return rec, tr:smooth()
end

-- The smoothed oracle: the whole track's evidence decides its rows at stake.
local function smoothed_oracle(rec, rows_of, evid)
  for key, list in pairs(rows_of) do
    local total = evid[key]
    for _, r in ipairs(list) do
      local x = rec[r]
      local w = x.wrong_o
      if x.stake then w = total > 0 and 0 or (total == 0 and 0.5 or 1) end
      add(x.name, "oracle_s", w)
    end
  end
  for r = 1, #rec do
    if not rec[r].pose then add(rec[r].name, "oracle_s", 1) end
  end
end

local function run(dir)
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local rows = assert(log.read_corners(dir .. "/corners.csv"))
  local truth = assert(log.read_csv(dir .. "/truth.csv"))
  assert(#truth == #rows, dir .. ": truth and corners differ in length")
  local sigma, by_track, by_sequence = read_meta(dir)
  local given = opt.sigma or (opt.meta_sigma and sigma) or nil
  local s2 = (sigma or 0.5) ^ 2
  local single_opts = { sigma = given }
  local rec, choice = tracked(camera, info.tag_size, given, rows)
  local age, evid = {}, {} -- per track: frames so far, the oracle's evidence so far
  local rows_of = {} -- per track: its rows
  for r = 1, #rows do
    local row, t, x = rows[r], truth[r], rec[r]
    local key = t.track or floor(row.frame / 1000)
    local name = (t.track and by_track[t.track]) or by_sequence[floor(row.frame / 1000)] or "?"
    x.name = name
    add(name, "rows", 1)
    local rt = rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz)
    local tt = { t.x, t.y, t.z }
    if not opt.quick then
      local single = tagpose.solve(row.corners, camera, info.tag_size, single_opts)
      local es = single and select(2, error_of(single, rt, tt)) or 180
      if es > 30 then add(name, "single", 1) end
    end
    local p = x.pose
    if not p then
      add(name, "tracked", 1)
      add(name, "smoothed", 1)
      x.wrong_o = 1
    else
      local e, ep = error_of(p, rt, tt)
      local alt = p.alternative
      local ea, eaa
      if alt then ea, eaa = error_of(alt, rt, tt) end
      if ep > 30 then add(name, "tracked", 1) end
      local sp = choice[r] == 2 and eaa or ep
      if sp > 30 then add(name, "smoothed", 1) end
      -- coverage of the returned pose
      local right = not alt or ep <= eaa
      if not opt.quick then
        age[key] = (age[key] or 0) + 1
        cover_row(p, e, ep > 30, right, age[key], alt, ea)
      end
      -- the oracle: this frame's evidence for the true branch
      local llr = 0
      if alt then
        local sse_p, sse_a = 4 * p.error ^ 2, 4 * alt.error ^ 2
        local first_is_p = sse_p <= sse_a
        local a1 = first_is_p and p or alt
        local q, pp = a1.quaternion, a1.position
        local tx, ty = track.tilt(q.w, q.x, q.y, q.z, pp.x, pp.y, pp.z)
        local c, side = row.corners, 0
        for k = 1, 4 do
          local k2 = k % 4 + 1
          side = side + sqrt((c[k2][1] - c[k][1]) ^ 2 + (c[k2][2] - c[k][2]) ^ 2) / 4
        end
        local _, _, xm = track.measurement(sqrt(tx * tx + ty * ty), side, s2)
        local ev = track.evidence(math.min(sse_p, sse_a), math.max(sse_p, sse_a), s2, xm)
        -- evidence for the first candidate: for the true branch when the first is it
        local true_is_p = right
        llr = (first_is_p == true_is_p) and ev or -ev
      end
      evid[key] = (evid[key] or 0) + llr
      -- wrong for the oracle: both candidates off, or the true branch not favoured
      local best = alt and math.min(ep, eaa) or ep
      local worst = alt and math.max(ep, eaa) or ep
      if best > 30 then
        x.wrong_o = 1
      elseif worst <= 30 then
        x.wrong_o = 0
      else
        x.wrong_o = evid[key] > 0 and 0 or (evid[key] == 0 and 0.5 or 1)
        x.stake = true
      end
      add(name, "oracle", x.wrong_o)
      x.key = key
      local list = rows_of[key]
      if not list then
        list = {}
        rows_of[key] = list
      end
      list[#list + 1] = r
      if dump then
        local q, pp = p.quaternion, p.position
        dump:write(("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %d %d\n"):format(pp.x, pp.y,
          pp.z, q.w, q.x, q.y, q.z, p.confidence, choice[r], x.track))
      end
    end
  end
  smoothed_oracle(rec, rows_of, evid)
end

local sets = bench.sets(opt.dirs)
for _, dir in ipairs(sets) do
  local before = { rows = pooled.rows, tracked = pooled.tracked, smoothed = pooled.smoothed }
  run(dir)
  if opt.by_set then
    local n = pooled.rows - before.rows
    print(("set %s rows %d tracked %.3f smoothed %.3f"):format(dir, n,
      100 * (pooled.tracked - before.tracked) / n, 100 * (pooled.smoothed - before.smoothed) / n))
  end
end
if dump then dump:close() end

local function pct(a, n) return n > 0 and ("%.2f"):format(100 * a / n) or "–" end
print(("%d sets, %d rows; σ %s [%s]"):format(#sets, pooled.rows, opt.sigma and tostring(opt.sigma)
  or opt.meta_sigma and "of each set" or "default", _VERSION
  .. (rawget(_G, "jit") and " (LuaJIT)" or "")))
print("| kind | rows | single % | tracked % | smoothed % | oracle % | oracle smoothed % |")
print("|---|---:|---:|---:|---:|---:|---:|")
local function line(name, k)
  print(("| %s | %d | %s | %s | %s | %s | %s |"):format(name, k.rows, pct(k.single, k.rows),
    pct(k.tracked, k.rows), pct(k.smoothed, k.rows), pct(k.oracle, k.rows),
    pct(k.oracle_s, k.rows)))
end
if opt.kinds then
  table.sort(kind_order)
  for _, name in ipairs(kind_order) do line(name, kinds[name]) end
end
line("**all**", pooled)
if opt.quick then return end
print()
print("| coverage of | rows | 6-dof % | x % | y % | z % | M² mean |")
print("|---|---:|---:|---:|---:|---:|---:|")
for _, c in ipairs({ { "returned pose", cov.all }, { "right branch", cov.right },
  { "wrong branch", cov.wrong }, { "flipped (> 30° off)", cov.flipped },
  { ("first %d frames"):format(opt.first), cov.early },
  { "later frames", cov.late }, { "true-branch candidate", cov.true_branch } }) do
  local k = c[2]
  print(("| %s | %d | %s | %s | %s | %s | %.2f |"):format(c[1], k.n, pct(k.six, k.n),
    pct(k.x, k.n), pct(k.y, k.n), pct(k.z, k.n), k.n > 0 and k.m2 / k.n or 0))
end
