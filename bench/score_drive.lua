-- Score robot-pose logs on a drive log (bench/dev/drive, bench/dev/drive_hard) against its
-- truth, with the benchmark's score_drive.py metrics and its printed table, figure for figure.
--
--   lua5.4 bench/score_drive.lua DIR CSV [CSV ...]
--
-- DIR holds truth.csv (time,x,y,z,qw,qx,qy,qz, robot -> field) and corners.csv
-- (time,camera,tag,u1..v4). Each CSV has the columns time,camera,x,y,z,qw,qx,qy,qz (robot ->
-- field) and optionally sx,sy,syaw (1-sigma in m, m, rad) or a covariance c11..c66; other
-- columns are ignored. A row whose camera is "front" or "back" stands for that camera's frame;
-- any other camera value ("fused", ...) for the time alone. Per file, one table row:
-- * rows: rows read; "unmatched" rows (a cell of time, x, y, qw..qz missing or not a finite
--   number, or no truth time within 1 ms; the nearest truth time, the earlier on a tie) are not
--   scored;
-- * pos: planar error |(x, y) - truth| in m: median, p95, max, rows > 0.5 m, rows > 1 m;
-- * yaw: |wrap(yaw - yaw_true)| in degrees, yaw = atan2(2(wz + xy), 1 - 2(y^2 + z^2)) of the
--   quaternion: median, p95;
-- * cov95 pos: over rows with a position uncertainty, the share with e^T C^-1 e <= 5.991
--   (chi-square, 2 dof, 95 %), e = (ex, ey);
-- * cov95 yaw: over rows with a heading sigma, the share with |e_yaw| <= 1.96 sigma;
-- * complete: the camera frames (time rounded to 1 us, camera) with >= 1 row in corners.csv
--   that have a row: matched by (truth time, camera) for camera rows, by truth time for others;
-- * by tags: the pos median / p95 of camera rows of frames with 1 and with >= 2 corner rows.
-- Uncertainty, a row's first complete form: c11, c22, c66 all numbers give C = [[c11, c12],
-- [c12, c22]] (c21 when c12 is missing, 0 when both are), used when c11 > 0, c22 > 0 and
-- det C > 0, and sigma_yaw = sqrt(c66) when c66 > 0; otherwise sx, sy > 0 give C = diag(sx^2,
-- sy^2) and syaw > 0 sigma_yaw. Rows without one count in neither coverage.
-- Medians and percentiles as numpy's (linear interpolation between the sorted values).
--
-- The CSVs are read as Python's csv.DictReader reads them (fields not trimmed, '#' lines are
-- rows, a short row's missing cells empty, a quoted field may span lines), not with
-- tagpose.tools.csv, which trims fields and refuses short rows: the same rows, the same scores.
-- Numbers are read as Python's float() reads them (hexadecimal refused, '_' between digits
-- allowed; infinities and NaN count as missing).
--
-- Loaded with dofile (not run as bench/score_drive.lua), it returns its functions: `score(dir,
-- csvs)` the figures, `table(dir, csvs)` the printed table's lines.

-- the checkout holding this file (dofile'd from elsewhere, arg[0] is not it)
local here = debug.getinfo(1, "S").source:match("^@(.*)$") or ""
local root = here:match("^(.-)/?bench/[^/]*$")
root = (root == nil or root == "") and "." or root
package.path = root .. "/src/?.lua;" .. root .. "/src/?/init.lua;" .. package.path

local compat = require("tagpose.core.compat")

local atan2, sqrt, abs, floor, fmod, log, exp = compat.atan2, math.sqrt, math.abs, math.floor,
  math.fmod, math.log, math.exp
local huge, pi = math.huge, math.pi
local find, sub, gmatch, format, concat = string.find, string.sub, string.gmatch, string.format,
  table.concat

local M = {}

local CAMERAS = { front = true, back = true }
local CHI2_2DOF_95 = 5.991
local MATCH_TOL = 0.001
local RAD_TO_DEG = 180 / pi -- Python's math.degrees multiplies by this
local QUOTE = '"'

-- reading CSV as Python's csv module does (excel dialect, strict off)

local function read_text(path)
  local f, err = io.open(path, "rb")
  if not f then error("score_drive: " .. tostring(err), 0) end
  local text = f:read("*a")
  f:close()
  -- Python opens text files with universal newlines
  text = text:gsub("\r\n", "\n")
  text = text:gsub("\r", "\n")
  return text
end

-- the record starting at line `line` (without its "\n") that has a quote, with the lines after
-- it when a quoted field goes on; its fields and the position after its last line
local function quoted_record(text, line, after)
  local fields, field, state = {}, {}, "start"
  while true do
    for i = 1, #line do
      local c = sub(line, i, i)
      if state == "start" then
        if c == QUOTE then
          state = "quoted"
        elseif c == "," then
          fields[#fields + 1] = ""
        else
          field[#field + 1] = c
          state = "field"
        end
      elseif state == "field" then
        if c == "," then
          fields[#fields + 1] = concat(field)
          field, state = {}, "start"
        else
          field[#field + 1] = c
        end
      elseif state == "quoted" then
        if c == QUOTE then state = "quote" else field[#field + 1] = c end
      else -- a quote inside a quoted field
        if c == QUOTE then
          field[#field + 1] = c
          state = "quoted"
        elseif c == "," then
          fields[#fields + 1] = concat(field)
          field, state = {}, "start"
        else
          field[#field + 1] = c
          state = "field"
        end
      end
    end
    if state ~= "quoted" or after > #text then break end
    -- the quoted field goes on in the next line
    field[#field + 1] = "\n"
    local e = find(text, "\n", after, true) or #text + 1
    line, after = sub(text, after, e - 1), e + 1
  end
  fields[#fields + 1] = concat(field)
  return fields, after
end

-- every record of a CSV text as arrays of strings, blank lines skipped (csv.reader gives [],
-- which DictReader skips)
local function records(text)
  local out, pos, n = {}, 1, #text
  while pos <= n do
    local e = find(text, "\n", pos, true) or n + 1
    local line = sub(text, pos, e - 1)
    pos = e + 1
    if line ~= "" then
      local fields
      if find(line, QUOTE, 1, true) then
        fields, pos = quoted_record(text, line, pos)
      else
        fields = {}
        for field in gmatch(line .. ",", "([^,]*),") do fields[#fields + 1] = field end
      end
      out[#out + 1] = fields
    end
  end
  return out
end

-- DictReader's rows: {name = string or false (a short row's missing cell)}, the last column of
-- a name winning, as dict(zip(...)) does
local function dict_rows(path)
  local recs = records(read_text(path))
  local header, rows = recs[1] or {}, {}
  for k = 2, #recs do
    local fields, row = recs[k], {}
    for i = 1, #header do
      local v = fields[i]
      if v == nil then v = false end
      row[header[i]] = v
    end
    rows[#rows + 1] = row
  end
  return rows, header
end

-- Python's float(s), or nil where it raises; then nil unless finite
local function py_float(s)
  if type(s) ~= "string" or find(s, "[xX]") then return nil end
  local t = s
  while true do -- '_' is allowed between two digits
    local u = t:gsub("(%d)_(%d)", "%1%2")
    if u == t then break end
    t = u
  end
  local v = tonumber(t)
  if v == nil then return nil end
  return v * 1.0
end

local function num(row, key)
  local v = row[key]
  if not v or not find(v, "%S") then return nil end
  v = py_float(v)
  if v == nil or v ~= v or v == huge or v == -huge then return nil end
  return v
end

-- Python's float(s) of a truth or corners cell (those must be numbers)
local function must_float(s, path, key)
  local v = py_float(s)
  if v == nil then
    error(format("score_drive: %s: column '%s' has %q, not a number", path, key,
      tostring(s)), 0)
  end
  return v
end

-- round(t, 6) as a key: the correctly rounded decimal, as Python rounds
local function time_key(t)
  local s = format("%.6f", t)
  if s == "-0.000000" then s = "0.000000" end
  return s
end

local function yaw_of_quat(w, x, y, z)
  return atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
end

-- Python's (a + pi) % (2 pi) - pi (the sign of the modulus follows the divisor)
local function wrap(a)
  local m = fmod(a + pi, 2 * pi)
  if m ~= 0 and m < 0 then m = m + 2 * pi end
  return m - pi
end

-- Python's math.hypot (CPython's vector_norm, not C's hypot, so the last bit agrees): a
-- lossless scaling by a power of two, exact squares (Dekker's product, the exact error that
-- CPython's fma gives), compensated sums and a correction of the square root
local VELTKAMP = 134217729.0 -- 2^27 + 1
local DBL_MIN = 2.2250738585072014e-308

local function exact_product(x, y)
  local p = x * y
  local t = x * VELTKAMP
  local xh = t - (t - x)
  local xl = x - xh
  t = y * VELTKAMP
  local yh = t - (t - y)
  local yl = y - yh
  return p, xl * yl - (((p - xh * yh) - xl * yh) - xh * yl)
end

local function hypot(a, b)
  a, b = abs(a), abs(b)
  local max = a > b and a or b
  if max == 0 then return max end
  if max < DBL_MIN then return DBL_MIN * hypot(a / DBL_MIN, b / DBL_MIN) end
  -- scale = 2^-e with max * scale in [0.5, 1), as frexp gives e
  local e = floor(log(max) / log(2)) + 1
  local scale = 2 ^ -e
  while max * scale >= 1 do
    e = e + 1
    scale = 2 ^ -e
  end
  while max * scale < 0.5 do
    e = e - 1
    scale = 2 ^ -e
  end
  local csum, frac1, frac2 = 1.0, 0.0, 0.0
  local x = a * scale
  local hi, lo = exact_product(x, x)
  local sum = csum + hi
  frac1, frac2, csum = frac1 + lo, frac2 + ((csum - sum) + hi), sum
  x = b * scale
  hi, lo = exact_product(x, x)
  sum = csum + hi
  frac1, frac2, csum = frac1 + lo, frac2 + ((csum - sum) + hi), sum
  local h = sqrt(csum - 1.0 + (frac1 + frac2))
  hi, lo = exact_product(-h, h)
  sum = csum + hi
  frac1, frac2, csum = frac1 + lo, frac2 + ((csum - sum) + hi), sum
  x = csum - 1.0 + (frac1 + frac2)
  h = h + x / (2.0 * h)
  return h / scale
end

local function load_truth(path)
  local rows = dict_rows(path)
  local order, t, x, y, yaw = {}, {}, {}, {}, {}
  for i, r in ipairs(rows) do
    t[i] = must_float(r.time, path, "time")
    x[i] = must_float(r.x, path, "x")
    y[i] = must_float(r.y, path, "y")
    yaw[i] = yaw_of_quat(must_float(r.qw, path, "qw"), must_float(r.qx, path, "qx"),
      must_float(r.qy, path, "qy"), must_float(r.qz, path, "qz"))
    order[i] = i
  end
  table.sort(order, function(a, b)
    if t[a] ~= t[b] then return t[a] < t[b] end
    return a < b
  end)
  local truth = { t = {}, x = {}, y = {}, yaw = {} }
  for k, i in ipairs(order) do
    truth.t[k], truth.x[k], truth.y[k], truth.yaw[k] = t[i], x[i], y[i], yaw[i]
  end
  return truth
end

-- {time key = {camera = detection rows}} of corners.csv, and the frames in file order
local function load_frames(path)
  local frames, list = {}, {}
  for _, r in ipairs(dict_rows(path)) do
    local tk = time_key(must_float(r.time, path, "time"))
    local cam = r.camera
    if cam == false or cam == nil then cam = "\0none" end -- Python's None
    local at = frames[tk]
    if not at then
      at = {}
      frames[tk] = at
    end
    if not at[cam] then list[#list + 1] = { tk, cam } end
    at[cam] = (at[cam] or 0) + 1
  end
  return frames, list
end

-- LAPACK's LU (partial pivoting, the multiplier by the pivot's reciprocal) of [[a, b], [c, d]]:
-- whether the rows swap, the multiplier, the pivots
local function lu(a, b, c, d)
  if abs(c) > abs(a) then
    local l = a * (1 / c)
    return true, l, c, b - l * d
  end
  local l = c * (1 / a)
  return false, l, a, d - l * b
end

-- numpy's det(C) > 0: the sign and log |det| of the LU, det = sign exp(log |det|)
local function det_positive(a, b, c, d)
  local swap, _, p, q = lu(a, b, c, d)
  if p == 0 or q == 0 or p ~= p or q ~= q then return false end
  local sign = swap and -1 or 1
  if p < 0 then sign = -sign end
  if q < 0 then sign = -sign end
  return sign > 0 and exp(log(abs(p)) + log(abs(q))) > 0
end

-- (c11, c12, c22) of the position covariance or nil, and the heading sigma or nil
local function uncertainty(r)
  local c11, c22, c66 = num(r, "c11"), num(r, "c22"), num(r, "c66")
  if c11 ~= nil and c22 ~= nil and c66 ~= nil then
    local c12 = num(r, "c12")
    if c12 == nil then c12 = num(r, "c21") end
    c12 = c12 or 0.0
    local ok = c11 > 0 and c22 > 0 and det_positive(c11, c12, c12, c22)
    local s_yaw = c66 > 0 and sqrt(c66) or nil
    if ok then return c11, c12, c22, s_yaw end
    return nil, nil, nil, s_yaw
  end
  local sx, sy, syaw = num(r, "sx"), num(r, "sy"), num(r, "syaw")
  local s_yaw = (syaw and syaw > 0) and syaw or nil
  if sx and sy and sx > 0 and sy > 0 then return sx * sx, 0.0, sy * sy, s_yaw end
  return nil, nil, nil, s_yaw
end

-- e . solve(C, e) for C = [[a, b], [b, d]], solved as LAPACK's gesv does (LU, then the
-- two triangular solves)
local function chi2(ex, ey, a, b, d)
  local swap, l, p, q = lu(a, b, b, d)
  local y1, y2, u12 = ex, ey, b
  if swap then y1, y2, u12 = ey, ex, d end
  y2 = y2 - y1 * l
  local x2 = y2 / q
  local x1 = (y1 - x2 * u12) / p
  return ex * x1 + ey * x2
end

--- Python's math.hypot(a, b), to the last bit.
M.hypot = hypot

--- numpy's median of a list (nil when empty); sorts it.
function M.median(v)
  local n = #v
  if n == 0 then return nil end
  table.sort(v)
  if n % 2 == 1 then return v[(n + 1) / 2] end
  return (v[n / 2] + v[n / 2 + 1]) / 2
end

--- numpy's percentile (method "linear") of a list (nil when empty); sorts it.
function M.percentile(v, q)
  local n = #v
  if n == 0 then return nil end
  table.sort(v)
  local virtual = (n - 1) * (q / 100)
  local prev = floor(virtual)
  local a, b, gamma
  if virtual >= n - 1 then
    a, b, gamma = v[n], v[n], virtual + 1 -- numpy takes the last element twice (index -1)
  else
    a, b, gamma = v[prev + 1], v[prev + 2], virtual - prev
  end
  local diff = b - a
  if gamma >= 0.5 then return b - diff * (1 - gamma) end
  return a + diff * gamma
end

local function stats(v)
  local n = #v
  if n == 0 then return { n = 0 } end
  local sorted = {}
  for i = 1, n do sorted[i] = v[i] end
  table.sort(sorted)
  return { n = n, median = M.median(sorted), p95 = M.percentile(sorted, 95), max = sorted[n] }
end

-- the nearest truth index to t (the earlier on a tie), as searchsorted and min do
local function nearest(tt, t)
  local lo, hi = 1, #tt + 1 -- the first index with tt[i] >= t
  while lo < hi do
    local mid = floor((lo + hi) / 2)
    if tt[mid] < t then lo = mid + 1 else hi = mid end
  end
  local best
  for j = lo - 1, lo do
    if j >= 1 and j <= #tt and (best == nil or abs(tt[j] - t) < abs(tt[best] - t)) then
      best = j
    end
  end
  return best
end

local function score_file(path, truth, frames, frame_list)
  local tt, tx, ty, tyaw = truth.t, truth.x, truth.y, truth.yaw
  local s = { rows = 0, unmatched = 0 }
  local pos, yaw, one, more = {}, {}, {}, {}
  local cov_pos, cov_pos_n, cov_yaw, cov_yaw_n = 0, 0, 0, 0
  local covered_keys, covered_times = {}, {}
  for _, r in ipairs((dict_rows(path))) do
    s.rows = s.rows + 1
    local t, x, y = num(r, "time"), num(r, "x"), num(r, "y")
    local qw, qx, qy, qz = num(r, "qw"), num(r, "qx"), num(r, "qy"), num(r, "qz")
    local j = t and x and y and qw and qx and qy and qz and nearest(tt, t)
    if not j or abs(tt[j] - t) > MATCH_TOL then
      s.unmatched = s.unmatched + 1
    else
      local ex, ey = x - tx[j], y - ty[j]
      local e_pos = hypot(ex, ey)
      local e_yaw = wrap(yaw_of_quat(qw, qx, qy, qz) - tyaw[j])
      pos[#pos + 1] = e_pos
      yaw[#yaw + 1] = abs(e_yaw * RAD_TO_DEG)
      local a, b, d, s_yaw = uncertainty(r)
      if a then
        cov_pos_n = cov_pos_n + 1
        if chi2(ex, ey, a, b, d) <= CHI2_2DOF_95 then cov_pos = cov_pos + 1 end
      end
      if s_yaw then
        cov_yaw_n = cov_yaw_n + 1
        if abs(e_yaw) <= 1.96 * s_yaw then cov_yaw = cov_yaw + 1 end
      end
      local cam, tk = r.camera, time_key(tt[j])
      if cam and CAMERAS[cam] then
        covered_keys[tk .. "\0" .. cam] = true
        local n = frames[tk] and frames[tk][cam]
        if n then
          local list = n == 1 and one or more
          list[#list + 1] = e_pos
        end
      else
        covered_times[tk] = true
      end
    end
  end
  local have = 0
  for _, k in ipairs(frame_list) do
    if covered_keys[k[1] .. "\0" .. k[2]] or covered_times[k[1]] then have = have + 1 end
  end
  s.scored = #pos
  s.pos = stats(pos)
  s.over_half, s.over_one = 0, 0
  for _, e in ipairs(pos) do
    if e > 0.5 then s.over_half = s.over_half + 1 end
    if e > 1.0 then s.over_one = s.over_one + 1 end
  end
  s.yaw = stats(yaw)
  s.cov95_pos = cov_pos_n > 0 and cov_pos / cov_pos_n or nil
  s.cov95_pos_rows = cov_pos_n
  s.cov95_yaw = cov_yaw_n > 0 and cov_yaw / cov_yaw_n or nil
  s.cov95_yaw_rows = cov_yaw_n
  s.frames_with_tags = #frame_list
  s.completeness = #frame_list > 0 and have / #frame_list or nil
  s.one_tag, s.more_tags = stats(one), stats(more)
  return s
end

--- The figures of each pose CSV against the drive log in `dir`.
-- @tparam string dir the drive log (truth.csv, corners.csv)
-- @tparam {string,...} csvs pose CSVs
-- @treturn {table,...} per CSV: `rows`, `unmatched`, `scored`, `pos` and `yaw` ({n, median,
--   p95, max}), `over_half`, `over_one`, `cov95_pos`, `cov95_yaw` (shares, or nil) and their
--   `_rows`, `completeness` (share, or nil), `frames_with_tags`, `one_tag`, `more_tags`
-- @raise when a file cannot be read or truth.csv / corners.csv has a cell that is not a number
function M.score(dir, csvs)
  local truth = load_truth(dir .. "/truth.csv")
  local frames, frame_list = load_frames(dir .. "/corners.csv")
  local out = {}
  for i, path in ipairs(csvs) do out[i] = score_file(path, truth, frames, frame_list) end
  return out
end

local function f3(v, fmt)
  if v == nil then return "-" end
  return format(fmt or "%.3f", v)
end

local function pct(v)
  return f3(v and 100 * v, "%.1f %%")
end

local function split(st)
  if st.n == 0 then return "-" end
  return format("%.3f/%.3f", st.median, st.p95)
end

--- The printed table: its lines, a header and one row per CSV.
-- @tparam string dir
-- @tparam {string,...} csvs
-- @treturn {string,...}
function M.table(dir, csvs)
  local lines = {
    "| file | rows | pos med | p95 | max | >0.5 m | >1 m | yaw med | yaw p95 | cov95 pos"
      .. " | cov95 yaw | complete | 1 tag med/p95 | 2+ tags med/p95 |",
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
  }
  for i, s in ipairs(M.score(dir, csvs)) do
    lines[#lines + 1] = format("| %s | %d%s | %s | %s | %s | %d | %d | %s | %s | %s | %s | %s"
      .. " | %s | %s |", csvs[i]:match("[^/]*$"), s.rows,
      s.unmatched > 0 and format(" (%d unmatched)", s.unmatched) or "",
      f3(s.pos.median), f3(s.pos.p95), f3(s.pos.max), s.over_half, s.over_one,
      f3(s.yaw.median, "%.2f"), f3(s.yaw.p95, "%.2f"), pct(s.cov95_pos), pct(s.cov95_yaw),
      pct(s.completeness), split(s.one_tag), split(s.more_tags))
  end
  return lines
end

local function main(args)
  if args[1] == "-h" or args[1] == "--help" or not args[2] then
    io.stderr:write("usage: lua5.4 bench/score_drive.lua DIR CSV [CSV ...]\n")
    return (args[1] == "-h" or args[1] == "--help") and 0 or 2
  end
  local csvs = {}
  for i = 2, #args do csvs[#csvs + 1] = args[i] end
  local ok, lines = pcall(M.table, args[1], csvs)
  if not ok then
    io.stderr:write(tostring(lines), "\n")
    return 1
  end
  io.write(concat(lines, "\n"), "\n")
  return 0
end

if arg and arg[0] and arg[0]:match("score_drive%.lua$") then os.exit(main(arg)) end

return M
