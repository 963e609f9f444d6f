--- The axes of a plot: nice tick values, their labels, and the ranges of the data (finite
-- values only) padded for the plot area.
-- @module tagpose.tools.plot.scale

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")

local floor, ceil, abs, log, max = math.floor, math.ceil, math.abs, math.log, math.max
local is_finite = compat.is_finite

local M = {}

local function raise(n, fname, message)
  args.raise(n, fname, message, 3)
end

local LOG10 = log(10)

local function log10(v)
  return log(v) / LOG10
end

-- the next smaller nice step: 10 -> 5 -> 2 -> 1 -> 0.5 (mantissa, magnitude)
local function smaller(mantissa, magnitude)
  if mantissa == 10 then return 5, magnitude end
  if mantissa == 5 then return 2, magnitude end
  if mantissa == 2 then return 1, magnitude end
  return 5, magnitude / 10
end

-- the multiples of step in [lo, hi] (a value within round-off of zero is exactly 0)
local function multiples(lo, hi, step)
  local ticks = {}
  local k = ceil(lo / step - 1e-9)
  local v = k * step
  while v <= hi + step * 1e-9 do
    if abs(v) < step * 1e-9 then v = 0 end
    ticks[#ticks + 1] = v
    k = k + 1
    v = k * step
  end
  return ticks
end

--- `tagpose.tools.plot.ticks` (documented there).
-- @tparam number lo
-- @tparam number hi
-- @tparam[opt=5] int count
-- @treturn {number,...} ticks
-- @treturn number step
-- @treturn int decimals
function M.ticks(lo, hi, count)
  if not is_finite(lo) then
    raise(1, "ticks", "finite number expected, got " .. args.describe(lo))
  end
  if not is_finite(hi) or hi < lo then
    raise(2, "ticks", "finite number >= lo expected, got " .. args.describe(hi))
  end
  if count == nil then count = 5 end
  if not (is_finite(count) and count >= 1) then
    raise(3, "ticks", "number >= 1 expected, got " .. args.describe(count))
  end
  if hi == lo then
    local pad = abs(lo) > 0 and 0.1 * abs(lo) or 1
    lo, hi = lo - pad, hi + pad
  end
  local raw = (hi - lo) / count
  local magnitude = 10 ^ floor(log10(raw) + 1e-9)
  local f = raw / magnitude
  local mantissa = f < 1.5 and 1 or f < 3 and 2 or f < 7 and 5 or 10
  local ticks, step
  for _ = 1, 64 do
    step = mantissa * magnitude
    ticks = multiples(lo, hi, step)
    if #ticks >= 3 then break end
    -- too few labels for the axis to be read: the next smaller nice step
    mantissa, magnitude = smaller(mantissa, magnitude)
  end
  local decimals = -floor(log10(step) + 1e-9)
  if decimals < 1 then decimals = 0 end -- and never -0, which would print as "-0"
  return ticks, step, decimals
end

--- A tick's label with `decimals` decimals (never `-0`).
-- @tparam number v
-- @tparam int decimals
-- @treturn string
function M.label(v, decimals)
  local s = ("%." .. decimals .. "f"):format(v)
  if s:match("^%-0%.?0*$") then s = s:sub(2) end
  return s
end

--- The range of the finite values of an array, widening `[lo, hi]`.
-- @tparam {number,...} values
-- @tparam number lo
-- @tparam number hi
-- @treturn number lo
-- @treturn number hi
function M.range_of(values, lo, hi)
  for i = 1, #values do
    local v = values[i]
    if is_finite(v) then
      if v < lo then lo = v end
      if v > hi then hi = v end
    end
  end
  return lo, hi
end

--- A data range padded for the plot area (by 5 %, or around a single value; `0, 1` for an
-- empty range), or the `fixed` range `{lo, hi}`.
-- @tparam number lo
-- @tparam number hi
-- @tparam[opt] {number,number} fixed
-- @treturn number lo
-- @treturn number hi
function M.padded(lo, hi, fixed)
  if fixed then return fixed[1], fixed[2] end
  if lo > hi then return 0, 1 end
  local span = hi - lo
  if span <= 1e-12 * max(1, abs(hi)) then
    local pad = abs(hi) > 0 and 0.1 * abs(hi) or 1
    return lo - pad, hi + pad
  end
  return lo - 0.05 * span, hi + 0.05 * span
end

--- The vertical range of a panel and its ticks: its series' finite y values, padded (or its
-- `range`).
-- @tparam table p the panel
-- @tparam number height the plot area's height, px
-- @treturn number y0
-- @treturn number y1
-- @treturn {number,...} ticks
-- @treturn int the ticks' decimals
-- @treturn boolean whether the panel has a finite value
function M.panel_range(p, height)
  local ylo, yhi = math.huge, -math.huge
  for _, s in ipairs(p.series) do ylo, yhi = M.range_of(s.y, ylo, yhi) end
  local y0, y1 = M.padded(ylo, yhi, p.range)
  local ticks, _, decimals = M.ticks(y0, y1, max(2, floor(height / 38)))
  return y0, y1, ticks, decimals, ylo <= yhi
end

return M
