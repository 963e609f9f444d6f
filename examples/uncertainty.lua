-- How far to trust tagpose's poses: coverage of pose.covariance and calibration of
-- pose.confidence on a data set with ground truth (the format of bench/dev).
--
--   lua5.4 examples/uncertainty.lua DATASET_DIR [--sigma S | --default-sigma]
--     [--track | --prior] [--kappa K] [--spread S] [--spread-limit E] [--default S,DOF] [--bins]
--     [--textbook]
--
-- DATASET_DIR may also be a directory of data sets (each subdirectory with corners.csv and
-- truth.csv, or a layout set's truth_layout.csv, is scored). σ is --sigma when given, else each
-- set's meta.json noise.sigma_px (a layout set's sigma_px; passed as options.sigma; a set
-- without one, or with 0, and every set with --default-sigma, is solved without it: the
-- library's default). With --track the rows are fed frame by frame to tagpose.tracker (σ as
-- its options.sigma; frame times from the log's `time` column, else frame / 30); with --prior
-- each tag's pose of the previous frame (frame - 1) is passed as options.prior to
-- tagpose.solve instead. --kappa, --spread and --spread-limit override
-- tagpose.uncertainty.KAPPA, SPREAD and SPREAD_LIMIT (--spread-limit 1e300: no limit, the
-- confidence before it), and --default S,DOF its DEFAULT_SIGMA and DEFAULT_DOF (with
-- --default-sigma), for measuring them (the κ table is made for DEFAULT_DOF = 8: with another
-- it is exact only from 10 dof on, for blocks and layouts with a fit of several tags in view);
-- --bins prints the calibration bins; --textbook scores the textbook covariance σ² H⁻¹ at each
-- candidate instead of pose.covariance (H from tagpose.refine.normal at the candidate's pose),
-- for comparison.
--
-- Per set it prints:
--   coverage   rows whose true pose lies inside the 95 % ellipsoid of the candidate on the true
--              branch (of pose and pose.alternative, the one whose rotation is nearer the
--              truth): 6-dof Mahalanobis² < 12.59, the error as (t_true - t, r) with
--              R_true = exp([r]×) R, against pose.covariance;
--   M² mean    the mean of that Mahalanobis² (6 for a Gaussian the covariance describes);
--   x y z      the share of rows whose true position lies inside that candidate's 95 %
--              interval on each axis (|error| < 1.96 sd), and, after "returned", the same for
--              the pose returned (whichever branch it is on);
--   ECE        expected calibration error of pose.confidence (10 equal bins over [0, 1]) over
--              the rows whose two candidates differ by more than 10°, "right" meaning the
--              returned pose is the true-branch candidate;
--   wrong@.95  among those rows, the share with confidence >= 0.95 whose pose is on the wrong
--              branch (and the count);
-- for a blocks set (camera.lua with block_size, truth.csv with faces_visible): the share of
-- blocks found with two or more faces whose true centre lies inside the 95 % position
-- ellipsoid (3-dof Mahalanobis² < 7.81) of block.covariance, and whose true pose lies inside
-- its 6-dof ellipsoid (the true rotation taken as its symmetric equivalent nearest the
-- block's); the same 3-dof share for blocks seen with one face (on their true branch) and
-- their confidence's ECE and wrong@.95;
-- and for a layout set (bench/dev/layout_cube's form: truth_layout.csv, test/corners.csv,
-- test/truth_tags.csv): its test log solved with the true layout (tagpose.layout.solve), the
-- share of body poses inside their 6-dof 95 % ellipsoid, for views of two tags or more and of
-- one tag.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local uncertainty = require("tagpose.uncertainty")
local refine = require("tagpose.core.refine")
local cube = require("tagpose.rigid.cube")

local sqrt, abs, floor, deg = math.sqrt, math.abs, math.floor, math.deg
local atan2 = require("tagpose.core.compat").atan2

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua examples/uncertainty.lua "
    .. "DATASET_DIR [--sigma S | --default-sigma] [--track | --prior] [--kappa K] "
    .. "[--spread S] [--spread-limit E] [--default S,DOF] [--bins] [--textbook]\n")
  os.exit(2)
end

local opts = {}
do
  local i = 1
  while i <= #arg do
    local a = arg[i]
    if a == "--sigma" then
      i = i + 1
      opts.sigma = tonumber(arg[i] or "") or usage("--sigma needs a number")
    elseif a == "--kappa" then
      i = i + 1
      opts.kappa = tonumber(arg[i] or "") or usage("--kappa needs a number")
    elseif a == "--spread" then
      i = i + 1
      opts.spread = tonumber(arg[i] or "") or usage("--spread needs a number")
    elseif a == "--spread-limit" then
      i = i + 1
      opts.spread_limit = tonumber(arg[i] or "") or usage("--spread-limit needs a number")
    elseif a == "--default" then
      i = i + 1
      local s, dof = (arg[i] or ""):match("^([^,]+),([^,]+)$")
      opts.default = { tonumber(s or ""), tonumber(dof or "") }
      if not (opts.default[1] and opts.default[2]) then usage("--default needs S,DOF") end
      opts.default_sigma = true
    elseif a == "--default-sigma" then
      opts.default_sigma = true
    elseif a == "--track" then
      opts.track = true
    elseif a == "--prior" then
      opts.prior = true
    elseif a == "--bins" then
      opts.bins = true
    elseif a == "--textbook" then
      opts.textbook = true
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
if opts.kappa then uncertainty.KAPPA = opts.kappa end
if opts.spread then uncertainty.SPREAD = opts.spread end
if opts.spread_limit then uncertainty.SPREAD_LIMIT = opts.spread_limit end
if opts.default then
  uncertainty.DEFAULT_SIGMA, uncertainty.DEFAULT_DOF = opts.default[1], opts.default[2]
end

local function exists(path)
  local f = io.open(path, "r")
  if f then f:close() end
  return f ~= nil
end

-- the set's σ from meta.json, or nil
local function meta_sigma(dir)
  local f = io.open(dir .. "/meta.json", "r")
  if not f then return nil end
  local text = f:read("*a")
  f:close()
  -- "noise": {"sigma_px": ...} (the tag and block sets), else a "sigma_px" of its own (layouts)
  local noise = text:match('"noise"%s*:%s*(%b{})') or text
  local s = tonumber(noise:match('"sigma_px"%s*:%s*([-%d.eE+]+)') or "")
  if s and s > 0 then return s end
  return nil
end

-- Mahalanobis² of the vector e (length n) against the top-left n×n block of the nested matrix
-- C, by Gauss-Jordan with partial pivoting; nil when C is singular
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

-- the error of an estimate (pose table) against the truth: (t_true - t, r), R_true = exp(r) R
local function error_of(p, rt, tt)
  local r = rotation.from_nested(p.rotation)
  local w, x, y, z = rotation.to_quaternion(rotation.multiply_transpose(rt, r))
  local s = sqrt(x * x + y * y + z * z)
  local f = s > 1e-12 and 2 * atan2(s, w) / s or 2
  local pp = p.position
  return { tt[1] - pp.x, tt[2] - pp.y, tt[3] - pp.z, f * x, f * y, f * z }, r
end

local function rotation_angle(e) return sqrt(e[4] ^ 2 + e[5] ^ 2 + e[6] ^ 2) end

local function calibration(conf, right)
  local bins = {}
  for b = 1, 10 do bins[b] = { n = 0, c = 0, a = 0 } end
  local n, high, wrong = #conf, 0, 0
  for i = 1, n do
    local b = bins[math.min(10, floor(conf[i] * 10) + 1)]
    b.n, b.c = b.n + 1, b.c + conf[i]
    if right[i] then b.a = b.a + 1 end
    if conf[i] >= 0.95 then
      high = high + 1
      if not right[i] then wrong = wrong + 1 end
    end
  end
  local ece = 0
  for b = 1, 10 do ece = ece + abs(bins[b].a - bins[b].c) / math.max(n, 1) end
  return ece, wrong, high, bins
end

-- The poses of a tag set's rows: one solve per row; with --prior the previous frame's pose of
-- the same tag as options.prior; with --track the tracker fed frame by frame.
local function poses_of(rows, camera, tag_size, sigma)
  local poses = {}
  if opts.track then
    local tr = tagpose.tracker.new(camera, tag_size, { sigma = sigma })
    local i = 1
    while i <= #rows do
      local j, frame = i, {}
      while j <= #rows and rows[j].frame == rows[i].frame do
        frame[#frame + 1] = { id = rows[j].tag, corners = rows[j].corners }
        j = j + 1
      end
      local seen = tr:update(frame, rows[i].fields.time or rows[i].frame / 30)
      for k = 1, #seen do poses[i + k - 1] = seen[k].pose or false end
      i = j
    end
    return poses
  end
  local options = { sigma = sigma }
  local last = {}
  for i, row in ipairs(rows) do
    if opts.prior then
      local prev = last[row.tag]
      options.prior = prev and prev.frame == row.frame - 1 and prev.pose or nil
    end
    local pose = tagpose.solve(row.corners, camera, tag_size, options)
    poses[i] = pose or false
    if pose then last[row.tag] = { frame = row.frame, pose = pose } end
  end
  return poses
end

-- 1 when |e[i]| is inside the 95 % interval of C's i-th diagonal, else 0
local function in_interval(C, e, i)
  return math.abs(e[i]) < 1.96 * sqrt(C[i][i]) and 1 or 0
end

local function score_tags(dir, sigma)
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local tag_size = info.tag_size
  local rows = assert(log.read_corners(dir .. "/corners.csv"))
  local truth = assert(log.read_csv(dir .. "/truth.csv"))
  assert(#truth == #rows, "truth and corners differ in length")
  local poses = poses_of(rows, camera, tag_size, sigma)
  local n, covered, m2sum = 0, 0, 0
  local axes, returned, returned_axes = { 0, 0, 0 }, 0, { 0, 0, 0 }
  local conf, right = {}, {}
  for i, row in ipairs(rows) do
    local pose = poses[i]
    if pose then
      local tr = truth[i]
      local rt = rotation.from_quaternion(tr.qw, tr.qx, tr.qy, tr.qz)
      local tt = { tr.x, tr.y, tr.z }
      local e = error_of(pose, rt, tt)
      local best, be = pose, e
      local alt = pose.alternative
      local ea
      if alt then
        ea = error_of(alt, rt, tt)
        if rotation_angle(ea) < rotation_angle(e) then best, be = alt, ea end
      end
      local cov = best.covariance
      if opts.textbook then
        local flat, normal = {}, {}
        for k = 1, 4 do flat[2 * k - 1], flat[2 * k] = row.corners[k][1], row.corners[k][2] end
        local q = best.position
        refine.normal(camera, flat, tag_size / 2, rotation.from_nested(best.rotation), q.x,
          q.y, q.z, normal)
        cov = uncertainty.covariance({ normal = normal }, (sigma or uncertainty.DEFAULT_SIGMA) ^ 2)
      end
      local m2 = mahalanobis(cov, be, 6) or math.huge
      n = n + 1
      m2sum = m2sum + m2
      if m2 < 12.59 then covered = covered + 1 end
      local own = opts.textbook and best == pose and cov or pose.covariance
      if (mahalanobis(own, e, 6) or math.huge) < 12.59 then returned = returned + 1 end
      for k = 1, 3 do
        axes[k] = axes[k] + in_interval(cov, be, k)
        returned_axes[k] = returned_axes[k] + in_interval(own, e, k)
      end
      if alt and deg(rotation.angle(rotation.from_nested(pose.rotation),
        rotation.from_nested(alt.rotation))) > 10 then
        conf[#conf + 1] = pose.confidence
        right[#right + 1] = best == pose
      end
    end
  end
  local ece, wrong, high, bins = calibration(conf, right)
  local d = math.max(n, 1)
  return { rows = #rows, n = n, coverage = 100 * covered / d,
    m2 = m2sum / d, ece = ece, wrong = wrong, high = high, ambiguous = #conf,
    bins = bins, x = 100 * axes[1] / d, y = 100 * axes[2] / d, z = 100 * axes[3] / d,
    returned = 100 * returned / d, rx = 100 * returned_axes[1] / d,
    ry = 100 * returned_axes[2] / d, rz = 100 * returned_axes[3] / d }
end

-- the angle between two block rotations modulo the cube's 24 symmetries
local function symmetric(r, ref)
  local _, angle = cube.nearest(rotation.transpose_multiply(r, ref, {}))
  return angle
end

local function score_blocks(dir, sigma)
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local rows = assert(log.read_corners(dir .. "/corners.csv"))
  local frames, order = {}, {}
  for _, row in ipairs(rows) do
    local f = frames[row.frame]
    if not f then
      f = { detections = {}, truth = {} }
      frames[row.frame] = f
      order[#order + 1] = row.frame
    end
    f.detections[#f.detections + 1] = { id = row.tag, corners = row.corners }
  end
  for _, t in ipairs(assert(log.read_csv(dir .. "/truth.csv"))) do
    local f = frames[t.frame]
    if f then
      f.truth[#f.truth + 1] = { t.x, t.y, t.z, r = rotation.from_quaternion(t.qw, t.qx, t.qy,
        t.qz) }
    end
  end
  local half = 0.5 * info.block_size
  local n, covered, covered6, n1, covered1 = 0, 0, 0, 0, 0
  local conf, correct = {}, {}
  for _, id in ipairs(order) do
    local f = frames[id]
    local blocks = tagpose.block.solve(f.detections, camera, info.tag_size, info.block_size,
      { sigma = sigma })
    for _, b in ipairs(blocks or {}) do
      -- the true block nearest its centre, within half a block
      local p, best, bd = b.position, nil, half * half
      for _, t in ipairs(f.truth) do
        local d = (t[1] - p.x) ^ 2 + (t[2] - p.y) ^ 2 + (t[3] - p.z) ^ 2
        if d < bd then best, bd = t, d end
      end
      -- a one-face block: the candidate (of the block and its alternative) whose centre is
      -- nearer the truth, the covariance being that of a branch
      -- a one-face block: the branch (the block or its alternative) whose rotation is nearer
      -- the truth's, modulo the cube's symmetries; the confidence scored where they differ
      -- by more than 10°
      local a, faces = b.alternative, b.faces
      if best and a then
        local rb, ra = rotation.from_nested(b.rotation), rotation.from_nested(a.rotation)
        local eb, ea = symmetric(rb, best.r), symmetric(ra, best.r)
        if deg(symmetric(rb, ra)) > 10 then
          conf[#conf + 1], correct[#correct + 1] = b.confidence, eb <= ea
        end
        if ea < eb then b, p = a, a.position end
      end
      if best and b.covariance then
        local m2 = mahalanobis(b.covariance, { best[1] - p.x, best[2] - p.y, best[3] - p.z }, 3)
        local inside = m2 and m2 < 7.81
        if faces >= 2 then
          n = n + 1
          if inside then covered = covered + 1 end
          -- the whole pose, the truth's rotation taken as its symmetric equivalent nearest
          local aligned = cube.closest(best.r, rotation.from_nested(b.rotation), {})
          local m6 = mahalanobis(b.covariance, (error_of(b, aligned, best)), 6)
          if m6 and m6 < 12.59 then covered6 = covered6 + 1 end
        else
          n1 = n1 + 1
          if inside then covered1 = covered1 + 1 end
        end
      end
    end
  end
  local ece, wrong, high, bins = calibration(conf, correct)
  return { bins = bins, blocks = n, coverage = 100 * covered / math.max(n, 1),
    coverage6 = 100 * covered6 / math.max(n, 1), single = n1,
    single_coverage = 100 * covered1 / math.max(n1, 1), ece = ece, wrong = wrong, high = high,
    ambiguous = #conf }
end

-- a layout set (bench/dev/layout_cube's form): its test log solved with the true layout, the
-- body's true pose from any tag's (R_b = R Qᵀ, t_b = t - R_b p); coverage of the 95 %
-- ellipsoid of the body pose (6 dof) on its true branch, for views of one tag and of more
local function score_layout(dir, sigma)
  local camera = assert(log.read_camera(dir .. "/camera.lua"))
  local layout = assert(tagpose.layout.read(dir .. "/truth_layout.csv"))
  local frames, order = {}, {}
  for _, row in ipairs(assert(log.read_corners(dir .. "/test/corners.csv"))) do
    local f = frames[row.frame]
    if not f then
      f = {}
      frames[row.frame] = f
      order[#order + 1] = row.frame
    end
    f[#f + 1] = { id = row.tag, corners = row.corners }
  end
  local truth = {}
  for _, t in ipairs(assert(log.read_csv(dir .. "/test/truth_tags.csv"))) do
    if not truth[t.frame] then
      local q = layout.tags[t.tag].quaternion
      local rb = rotation.multiply_transpose(rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz),
        rotation.from_quaternion(q.w, q.x, q.y, q.z))
      local p = layout.tags[t.tag].position
      truth[t.frame] = { t.x - (rb[1] * p.x + rb[2] * p.y + rb[3] * p.z),
        t.y - (rb[4] * p.x + rb[5] * p.y + rb[6] * p.z),
        t.z - (rb[7] * p.x + rb[8] * p.y + rb[9] * p.z), r = rb }
    end
  end
  local n, inside = { 0, 0 }, { 0, 0 }
  for _, id in ipairs(order) do
    local body = tagpose.layout.solve(frames[id], camera, layout, { sigma = sigma })
    local tt = truth[id]
    if body and tt then
      local e, k = error_of(body, tt.r, tt), #body.tags > 1 and 2 or 1
      local alt = body.alternative
      if alt then
        local ea = error_of(alt, tt.r, tt)
        if rotation_angle(ea) < rotation_angle(e) then body, e = alt, ea end
      end
      local m2 = mahalanobis(body.covariance, e, 6)
      n[k] = n[k] + 1
      if m2 and m2 < 12.59 then inside[k] = inside[k] + 1 end
    end
  end
  return { n = n, coverage = { 100 * inside[1] / math.max(n[1], 1),
    100 * inside[2] / math.max(n[2], 1) } }
end

local print_bins

local function run(dir)
  local name = dir:match("([^/]+)/*$")
  local _, info = log.read_camera(dir .. "/camera.lua")
  local sigma = opts.sigma or not opts.default_sigma and meta_sigma(dir) or nil
  if exists(dir .. "/truth_layout.csv") then
    local s = score_layout(dir, sigma)
    print(("%-12s σ %-7s layout poses inside the 95 %% ellipsoid (6 dof): two tags or more "
      .. "%.1f %% of %d, one tag %.1f %% of %d"):format(name, sigma and ("%g"):format(sigma)
      or "default", s.coverage[2], s.n[2], s.coverage[1], s.n[1]))
    return
  end
  if type(info) == "table" and info.block_size then
    local s = score_blocks(dir, sigma)
    print(("%-12s σ %-7s blocks with 2+ faces %d: centre inside the 95 %% ellipsoid %.1f %%"
      .. " (pose, 6 dof: %.1f %%)   (one face, true branch: %d, %.1f %%; confidence ECE %.3f, "
      .. "wrong@.95 %.2f %% (%d of %d))")
      :format(name, sigma and ("%g"):format(sigma) or "frame", s.blocks, s.coverage,
      s.coverage6, s.single, s.single_coverage, s.ece, 100 * s.wrong / math.max(s.high, 1),
      s.wrong, s.high))
    return print_bins(s)
  end
  local s = score_tags(dir, sigma)
  print(("%-12s σ %-7s rows %5d  coverage %5.1f %%  M² mean %5.2f  x y z %.1f %.1f %.1f %%  "
    .. "(returned %.1f; %.1f %.1f %.1f %%)  |  %4d ambiguous rows: ECE %.3f  wrong@.95 %.2f %% "
    .. "(%d of %d)"):format(name, sigma and ("%g"):format(sigma) or "default", s.n, s.coverage,
    s.m2, s.x, s.y, s.z, s.returned, s.rx, s.ry, s.rz, s.ambiguous, s.ece,
    100 * s.wrong / math.max(s.high, 1), s.wrong, s.high))
  print_bins(s)
end

print_bins = function(s)
  if opts.bins then
    for b = 1, 10 do
      local bin = s.bins[b]
      if bin.n > 0 then
        print(("    confidence [%.1f, %.1f): %5d rows, mean %.3f, right %.3f"):format((b - 1) / 10,
          b / 10, bin.n, bin.c / bin.n, bin.a / bin.n))
      end
    end
  end
end

print(("tagpose uncertainty, %s%s, KAPPA %g%s"):format(_VERSION,
  rawget(_G, "jit") and " (LuaJIT)" or "", uncertainty.KAPPA, opts.track and ", --track"
  or opts.prior and ", --prior" or ""))
if exists(opts.dir .. "/corners.csv") or exists(opts.dir .. "/truth_layout.csv") then
  run(opts.dir)
else
  local p = io.popen('ls -1 "' .. opts.dir .. '"')
  local names = {}
  for name in p:lines() do names[#names + 1] = name end
  p:close()
  table.sort(names)
  for _, name in ipairs(names) do
    local sub = opts.dir:gsub("/*$", "") .. "/" .. name
    -- (a set of tag poses has its camera.lua; a drive log's robot poses are localization's)
    if exists(sub .. "/corners.csv") and exists(sub .. "/truth.csv")
      and exists(sub .. "/camera.lua") or exists(sub .. "/truth_layout.csv") then
      run(sub)
    end
  end
end
