--- What tagpose-replay's summary counts, in memory bounded whatever the length of the log:
-- quantiles from a histogram, failures listed up to `LISTED` and counted by reason, and the
-- way the summary prints a number.
-- @module tagpose.tools.replay.stats

local compat = require("tagpose.core.compat")

local floor, ceil, max, mlog = math.floor, math.ceil, math.max, math.log
local is_finite = compat.is_finite

local M = {}

--- Most failures and malformed rows listed one by one (the rest are counted by reason).
M.LISTED = 20
--- Most distinct reasons counted.
M.REASONS = 50

--- A number as the summary writes it: whole numbers without a point, others to 6
-- significant digits (or `digits`).
-- @tparam number v
-- @tparam[opt=6] int digits
-- @treturn string
function M.number(v, digits)
  if v == floor(v) and v > -1e15 and v < 1e15 then return ("%.0f"):format(v) end
  return (digits and "%." .. digits .. "g" or "%.6g"):format(v)
end

-- quantiles in bounded memory: counts in bins of 1/1000 of a decade (0.23 %) from 1e-12 to
-- 1e12, whole decades beyond (at most 24 000 fine bins and 600 coarse ones, whatever the
-- values: a hostile log cannot grow them)
local BINS = 1000
local FINE = 12 * BINS
local LOG10 = mlog(10)

--- An empty histogram of values >= 0.
-- @treturn table
function M.histogram()
  return { n = 0, zero = 0, bins = {} }
end

--- Count a value (one that is not a finite number >= 0 is left out).
-- @tparam table h
-- @tparam number v
function M.add(h, v)
  if not is_finite(v) or v < 0 then return end
  h.n = h.n + 1
  if v < 1e-300 then
    h.zero = h.zero + 1
    return
  end
  local e = mlog(v) / LOG10
  local k = floor(e * BINS)
  if k >= FINE or k < -FINE then k = floor(e) * BINS end
  h.bins[k] = (h.bins[k] or 0) + 1
end

--- The value of nearest rank `ceil(q n)` (the lower median for q = 0.5), to its bin's centre
-- (0.23 % wide from 1e-12 to 1e12, a decade beyond).
-- @tparam table h
-- @tparam number q
-- @treturn number|nil nil when nothing was counted
function M.quantile(h, q)
  if h.n == 0 then return nil end
  local rank = max(1, ceil(q * h.n - 1e-9))
  if rank <= h.zero then return 0 end
  local keys = {}
  for k in pairs(h.bins) do keys[#keys + 1] = k end
  table.sort(keys)
  local acc = h.zero
  for _, k in ipairs(keys) do
    acc = acc + h.bins[k]
    if acc >= rank then
      if k >= FINE or k < -FINE then return 10 ^ (k / BINS + 0.5) end
      return 10 ^ ((k + 0.5) / BINS)
    end
  end
  return nil
end

--- An empty tally: a list of at most `LISTED` entries, and counts by reason.
-- @treturn table `{n =, listed = {...}, counts = {[reason] = n}, order = {reason, ...},
--   other = n}`
function M.tally()
  return { n = 0, listed = {}, counts = {}, order = {}, other = 0 }
end

--- Note an entry `{reason =, ...}` in a tally.
-- @tparam table t
-- @tparam table entry
function M.note(t, entry)
  t.n = t.n + 1
  if #t.listed < M.LISTED then t.listed[#t.listed + 1] = entry end
  local r = entry.reason
  if t.counts[r] then
    t.counts[r] = t.counts[r] + 1
  elseif #t.order < M.REASONS then
    t.order[#t.order + 1] = r
    t.counts[r] = 1
  else
    t.other = t.other + 1
  end
end

return M
