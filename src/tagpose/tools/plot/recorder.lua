--- What a pose figure draws, kept compact as it comes (see `tagpose.tools.plot.recorder`,
-- which this is): one series per source and track of a tag, exact up to `max_points` points,
-- then the minimum and maximum of each value over buckets of the horizontal axis (at most
-- `max_points` buckets, their width doubling as the log goes on).
--
-- The horizontal axis is the frame number, or the time (s) for a recorder of `x = "time"`.
-- A series is `{source =, tag =, slot =, n =, x = {frame or time, ...}, names =, nc =, drawn =,
-- last_q =}` with, while exact, `v[c]` the values of column c, `f` the frames (time axis only:
-- where the lines break), and once bucketed `origin`, `width`, `index[i]` (bucket numbers)
-- and `mn[c]`, `mx[c]` (the extremes). The columns: the pose's values (`x, y, z`, then the
-- rotation's: `nv` of them), then, once a point has one (`nc` grows from `nv` to `2 nv + 1`),
-- the confidence and the standard deviation of each value (from the pose's covariance: the
-- rotation's propagated to the quaternion's components or to roll, pitch and yaw). A
-- deviation's column holds, once bucketed, the band's extremes: the minimum of `v - 2σ` in
-- `mn`, the maximum of `v + 2σ` in `mx`. Values that are missing are NaN.
-- @module tagpose.tools.plot.recorder

local compat = require("tagpose.core.compat")

local floor, deg, asin, sqrt, huge = math.floor, math.deg, math.asin, math.sqrt, math.huge
local cos, sin, abs = math.cos, math.sin, math.abs
local atan2, is_finite = compat.atan2, compat.is_finite

local NAN = 0 / 0

local M = {}

--- The rotation panels of each kind: their names, titles, units and wraps.
M.ROTATION = {
  quaternion = {
    { name = "qw", title = "qw" }, { name = "qx", title = "qx" },
    { name = "qy", title = "qy" }, { name = "qz", title = "qz" },
  },
  rpy = {
    { name = "roll", title = "roll", unit = "deg", wrap = 180 },
    { name = "pitch", title = "pitch", unit = "deg", wrap = 180 },
    { name = "yaw", title = "yaw", unit = "deg", wrap = 180 },
  },
}

local ROTATION = M.ROTATION

--- `tagpose.tools.plot.roll_pitch_yaw` (documented there).
-- @tparam number w
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @treturn number roll
-- @treturn number pitch
-- @treturn number yaw
function M.roll_pitch_yaw(w, x, y, z)
  local n = sqrt(w * w + x * x + y * y + z * z)
  w, x, y, z = w / n, x / n, y / n, z / n
  local s = 2 * (w * y - z * x)
  if s >= 1 - 1e-12 or s <= -1 + 1e-12 then
    -- gimbal lock: R = Rz(yaw) Ry(±π/2); read yaw from the first two rows of the 2nd column
    local r12 = 2 * (x * y - w * z)
    local r22 = 1 - 2 * (x * x + z * z)
    return 0, s > 0 and math.pi / 2 or -math.pi / 2, atan2(-r12, r22)
  end
  return atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)), asin(s),
    atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
end

local Recorder = {}
Recorder.__index = Recorder

--- A recorder (its rotation checked by the caller).
-- @tparam string rotation `"quaternion"` or `"rpy"`
-- @tparam int max_points
-- @tparam table settings where `MAX_SERIES` and `DASHES` are read when they are needed (the
--   `tagpose.tools.plot` module)
-- @tparam[opt="frame"] string x the horizontal axis: `"frame"` or `"time"`
-- @treturn table the recorder
function M.new(rotation, max_points, settings, x)
  local names = { "x", "y", "z" }
  for _, r in ipairs(ROTATION[rotation]) do names[#names + 1] = r.name end
  return setmetatable({ rotation = rotation, names = names, nv = #names, sources = {},
    series = {}, order = {}, max_points = max_points, dropped = 0, skipped = 0,
    settings = settings, x = x or "frame" }, Recorder)
end

--- True for a recorder of `new`.
-- @param v
-- @treturn boolean
function M.is_recorder(v)
  return getmetatable(v) == Recorder
end

function Recorder:source(name, dash)
  local n = #self.sources + 1
  local dashes = self.settings.DASHES
  if dash == nil then dash = dashes[(n - 1) % #dashes + 1] end
  self.sources[n] = { label = tostring(name or n), dash = dash or nil }
  return n
end

local function series_key(source, tag, slot)
  return tostring(source) .. "\0" .. type(tag) .. ":" .. tostring(tag) .. "\0" .. tostring(slot)
end

-- merge bucket b into bucket a of series s (a, b indices), for every value
local function merge_bucket(s, a, b)
  for c = 1, #s.mn do
    local mn, mx = s.mn[c], s.mx[c]
    local u, v = mn[b], mx[b]
    if u == u and (mn[a] ~= mn[a] or u < mn[a]) then mn[a] = u end
    if v == v and (mx[a] ~= mx[a] or v > mx[a]) then mx[a] = v end
  end
end

-- an exact series as buckets of one point each, of the width that halves max_points over
-- its frames (a deviation's column made the band's extremes)
local function start_buckets(s)
  local nv, nc = s.recorder.nv, s.nc
  local lo, hi = huge, -huge
  for i = 1, s.n do
    local x = s.x[i]
    if x < lo then lo = x end
    if x > hi then hi = x end
  end
  s.origin = lo
  local w = (hi - lo) / (s.max_points / 2)
  if not (w > 0) then w = 1 end
  s.mn, s.mx, s.index = {}, {}, {}
  for c = 1, nc do s.mn[c], s.mx[c] = s.v[c], {} end
  for c = 1, nc do
    local src, mx = s.v[c], s.mx[c]
    for i = 1, s.n do mx[i] = src[i] end
  end
  for k = 1, nc - nv - 1 do
    local v, mn, mx = s.mn[k], s.mn[nv + 1 + k], s.mx[nv + 1 + k]
    for i = 1, s.n do
      local two = 2 * mn[i]
      mn[i], mx[i] = v[i] - two, v[i] + two
    end
  end
  s.v, s.f = nil, nil
  return w
end

-- the first n values of an array, in a new one
local function copy(a, n)
  local b = {}
  for i = 1, n do b[i] = a[i] end
  return b
end

-- turn an exact series into buckets (w nil), or double their width (w the new width)
local function rebucket(s, w)
  local nv = s.nc
  if not s.width then w = start_buckets(s) end
  s.width = w
  local index, x, n = s.index, s.x, 0
  local last = nil
  for i = 1, s.n do
    local k = floor((x[i] - s.origin) / w)
    if last ~= nil and k <= last then
      if k < last then s.recorder.dropped = s.recorder.dropped + 1 end
      merge_bucket(s, n, i)
    else
      n = n + 1
      last = k
      index[n] = k
      if n ~= i then
        x[n] = x[i]
        for c = 1, nv do s.mn[c][n], s.mx[c][n] = s.mn[c][i], s.mx[c][i] end
      end
    end
  end
  -- the arrays copied at their new length: emptied in place they would keep the room of
  -- max_points + 1 values (a table's array part does not shrink), twice what they fill
  s.x, s.index = copy(x, n), copy(index, n)
  for c = 1, nv do s.mn[c], s.mx[c] = copy(s.mn[c], n), copy(s.mx[c], n) end
  s.n = n
end

-- the series of (source, tag, slot), created if there is room (nil when there is not)
function Recorder:series_of(source, tag, slot)
  local key = series_key(source, tag, slot)
  local s = self.series[key]
  if s then return s end
  if #self.order >= self.settings.MAX_SERIES then
    self.skipped = self.skipped + 1
    return nil
  end
  s = { source = source, tag = tag, slot = slot, n = 0, x = {}, v = {}, names = self.names,
    nc = self.nv, max_points = self.max_points, recorder = self, drawn = false,
    f = self.x == "time" and {} or nil }
  for c = 1, self.nv do s.v[c] = {} end
  self.series[key] = s
  self.order[#self.order + 1] = s
  return s
end

-- a variance as a standard deviation (NaN for one that is not a finite number >= 0)
local function deviation(v)
  if type(v) ~= "number" or not (v >= 0) or not is_finite(v) then return NAN end
  return sqrt(v)
end

-- the deviations of the rotation's values (vals[4...]) into vals[at...], from those of the
-- rotation vector r (camera frame, R_true = exp([r]x) R) taken as independent, through the
-- derivatives of the quaternion q (continuous along the series) or of roll, pitch and yaw
local function rotation_deviations(self, vals, at, w, x, y, z, r1, r2, r3)
  local a, b, c = r1 * r1, r2 * r2, r3 * r3
  if self.rotation == "quaternion" then
    -- dq = (0, r/2) q: dw = -(r . v)/2, dv = (w r + r x v)/2
    vals[at] = 0.5 * sqrt(x * x * a + y * y * b + z * z * c)
    vals[at + 1] = 0.5 * sqrt(w * w * a + z * z * b + y * y * c)
    vals[at + 2] = 0.5 * sqrt(z * z * a + w * w * b + x * x * c)
    vals[at + 3] = 0.5 * sqrt(y * y * a + x * x * b + w * w * c)
    return
  end
  -- R = Rz(yaw) Ry(pitch) Rx(roll) turned by r on the left: d(roll) = (cy r1 + sy r2) / cp,
  -- d(pitch) = -sy r1 + cy r2, d(yaw) = r3 + tan(pitch) (cy r1 + sy r2)
  local pitch, yaw = vals[5] * math.pi / 180, vals[6] * math.pi / 180
  local cy, sy, cp = cos(yaw), sin(yaw), cos(pitch)
  local across = cy * cy * a + sy * sy * b
  local k = deg(1)
  if abs(cp) < 1e-9 then
    vals[at], vals[at + 2] = NAN, NAN
  else
    vals[at] = k * sqrt(across) / abs(cp)
    vals[at + 2] = k * sqrt(c + across * (sin(pitch) / cp) ^ 2)
  end
  vals[at + 1] = k * sqrt(sy * sy * a + cy * cy * b)
end

-- the confidence and the deviations of a pose into vals[nv + 1...] (NaN for what it has
-- not); true when it has any
function Recorder:extras(pose, vals, confidence)
  local nv = self.nv
  for c = nv + 1, 2 * nv + 1 do vals[c] = NAN end
  if type(pose) ~= "table" then return false end
  if confidence == nil then confidence = pose.confidence end
  local any = false
  if type(confidence) == "number" and confidence >= 0 and confidence <= 1 then
    vals[nv + 1], any = confidence, true
  end
  local cov = pose.covariance
  if type(cov) ~= "table" then return any end
  local d = {}
  for i = 1, 6 do
    local row = cov[i]
    d[i] = deviation(type(row) == "table" and row[i])
  end
  vals[nv + 2], vals[nv + 3], vals[nv + 4] = d[1], d[2], d[3]
  local q = self.scratch_q
  if q and vals[4] == vals[4] then
    rotation_deviations(self, vals, nv + 5, q[1], q[2], q[3], q[4], d[4], d[5], d[6])
  end
  for c = nv + 2, 2 * nv + 1 do
    if vals[c] == vals[c] and is_finite(vals[c]) and is_finite(vals[c - nv - 1]) then
      any = true
    else
      vals[c] = NAN
    end
  end
  return any
end

-- the values of a pose for series s into vals: position, then the rotation, its quaternion
-- continuous along the series (NaN for what is missing or not finite)
function Recorder:values(s, pose, vals)
  local nv = self.nv
  self.scratch_q = nil
  for c = 1, nv do vals[c] = 0 / 0 end
  if type(pose) == "table" then
    local p, q = pose.position, pose.quaternion
    if type(p) == "table" then vals[1], vals[2], vals[3] = p.x, p.y, p.z end
    if type(q) == "table" and is_finite(q.w) and is_finite(q.x) and is_finite(q.y)
      and is_finite(q.z) and q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z > 0 then
      local w, x, y, z = q.w, q.x, q.y, q.z
      local lq = s.last_q
      if lq and lq[1] * w + lq[2] * x + lq[3] * y + lq[4] * z < 0 then
        w, x, y, z = -w, -x, -y, -z
      end
      s.last_q = lq or {}
      s.last_q[1], s.last_q[2], s.last_q[3], s.last_q[4] = w, x, y, z
      self.scratch_q = s.last_q
      if self.rotation == "quaternion" then
        vals[4], vals[5], vals[6], vals[7] = w, x, y, z
      else
        local roll, pitch, yaw = M.roll_pitch_yaw(w, x, y, z)
        vals[4], vals[5], vals[6] = deg(roll), deg(pitch), deg(yaw)
      end
    end
  end
  for c = 1, nv do
    local v = vals[c]
    if type(v) ~= "number" or not is_finite(v) then vals[c] = 0 / 0 else s.drawn = true end
  end
end

-- add a frame's values to a bucketed series (a deviation as the band's extremes)
local function add_bucketed(recorder, s, frame, vals)
  local nv, nc = recorder.nv, s.nc
  for c = nv + 2, nc do
    local v, two = vals[c - nv - 1], 2 * vals[c]
    vals[c], vals[nc + c] = v - two, v + two
  end
  local k = floor((frame - s.origin) / s.width)
  local n = s.n
  local last = s.index[n]
  if k < last then
    recorder.dropped = recorder.dropped + 1
    return
  end
  if k > last then
    n = n + 1
    s.n = n
    s.index[n], s.x[n] = k, frame
    for c = 1, nc do s.mn[c][n], s.mx[c][n] = 0 / 0, 0 / 0 end
  end
  for c = 1, nc do
    local u, v, mn, mx = vals[c], vals[c], s.mn[c], s.mx[c]
    if c > nv + 1 then v = vals[nc + c] end
    if u == u and (mn[n] ~= mn[n] or u < mn[n]) then mn[n] = u end
    if v == v and (mx[n] ~= mx[n] or v > mx[n]) then mx[n] = v end
  end
  if n > s.max_points then rebucket(s, 2 * s.width) end
end

-- give series s the columns of the confidence and the deviations, NaN so far
local function extend(recorder, s)
  local nv = recorder.nv
  local cols = s.width and { s.mn, s.mx } or { s.v }
  for _, t in ipairs(cols) do
    for c = nv + 1, 2 * nv + 1 do
      local a = {}
      for i = 1, s.n do a[i] = NAN end
      t[c] = a
    end
  end
  s.nc = 2 * nv + 1
end

function Recorder:add(source, tag, slot, frame, pose, confidence, time)
  local x = frame
  if self.x == "time" then x = time end
  if not is_finite(x) then return end
  local s = self:series_of(source, tag, slot)
  if not s then return end
  local vals = self.scratch or {}
  self.scratch = vals
  self:values(s, pose, vals)
  if self:extras(pose, vals, confidence) and s.nc == self.nv then extend(self, s) end
  if s.width then return add_bucketed(self, s, x, vals) end
  local n = s.n + 1
  s.n = n
  s.x[n] = x
  if s.f then s.f[n] = frame end
  for c = 1, s.nc do s.v[c][n] = vals[c] end
  if n > s.max_points then rebucket(s) end
end

-- the centres of a bucketed series' buckets, and the same twice each if made already: made
-- once for every panel that draws the series (until it changes)
local function centres_of(s)
  local c = s.centres
  if c and c.n == s.n and c.width == s.width and c.origin == s.origin then
    return c.twice, c.x
  end
  local x = {}
  for i = 1, s.n do x[i] = s.origin + (s.index[i] + 0.5) * s.width end
  s.centres = { n = s.n, width = s.width, origin = s.origin, x = x }
  return nil, x
end

--- The x and y arrays a panel draws of a series, value c (a bucket as its minimum and
-- maximum at its centre, in alternating order so that the line fills the envelope).
-- @tparam table s
-- @tparam int c
-- @treturn {number,...} x
-- @treturn {number,...} y
function M.series_xy(s, c)
  if not s.width then return s.x, s.v[c] end
  local xs, centres = centres_of(s)
  local ys = {}
  local mn, mx = s.mn[c], s.mx[c]
  for i = 1, s.n do
    local a, b = mn[i], mx[i]
    if i % 2 == 0 then a, b = b, a end
    ys[2 * i - 1], ys[2 * i] = a, b
  end
  if not xs then
    xs = {}
    for i = 1, s.n do xs[2 * i - 1], xs[2 * i] = centres[i], centres[i] end
    s.centres.twice = xs
  end
  return xs, ys
end

--- The band a panel draws of a series around value c, ±2 standard deviations: x, its low
-- and its high ends (one point a bucket), or nil when the series has no deviations.
-- @tparam table s
-- @tparam int c
-- @treturn {number,...} x
-- @treturn {number,...} low
-- @treturn {number,...} high
function M.band_xy(s, c)
  local nv = s.recorder.nv
  local b = nv + 1 + c
  if s.nc < b then return nil end
  if s.width then
    local _, centres = centres_of(s)
    return centres, s.mn[b], s.mx[b]
  end
  local lo, hi = {}, {}
  local v, d = s.v[c], s.v[b]
  for i = 1, s.n do lo[i], hi[i] = v[i] - 2 * d[i], v[i] + 2 * d[i] end
  return s.x, lo, hi
end

return M
