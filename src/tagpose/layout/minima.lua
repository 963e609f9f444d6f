--- The minima of a layout's joint fit, from the starts each tag gives alone
-- (`tagpose.layout.solve`): where the tags are in one plane the fit runs from several starts
-- (two distant tags on one wall have several minima, and the best start alone often leads to a
-- worse one), else from the one that fits all the corners best; the fits that end in one basin
-- are one minimum.
--
-- A minimum is a record `{r = flat rotation, x =, y =, z =, sse =, k =}` (body → camera, the
-- sum of squared pixel residuals, the linearisations); a list of them is kept best first.
-- `points` and `pixels` are the joint fit's (`tagpose.layout.fit`); `get_start(k, r)` puts
-- start k's rotation into r and returns its translation.
-- @module tagpose.layout.minima

local rotation = require("tagpose.core.rotation")
local fit = require("tagpose.layout.fit")
local compat = require("tagpose.core.compat")

local huge = math.huge
local is_finite = compat.is_finite

local M = {}

--- Fits from different starts that end closer than this angle (radians) are in one basin (a
-- fit stops within its tolerance of the minimum, not at it).
M.SAME_MINIMUM = 1e-3

--- True when a fitted pose and its squared error are finite (tested on their sum, which an
-- infinity or a NaN anywhere makes not finite).
-- @tparam {number,...} r flat rotation
-- @tparam number x translation
-- @tparam number y
-- @tparam number z
-- @tparam number sse squared pixel error
-- @treturn boolean
function M.finite(r, x, y, z, sse)
  local s = x + y + z + sse
  for i = 1, 9 do s = s + r[i] end
  return is_finite(s)
end
local finite = M.finite

local r_k = {} -- one start's fit

--- Fit from (r, tx, ty, tz) and keep the minimum in the list found (sorted by their squared
-- pixel errors), merged with one already there in the same basin (`SAME_MINIMUM`).
-- @tparam {table,...} found the minima so far (see the module's header)
-- @tparam table camera a checked camera
-- @tparam {number,...} points the joint fit's body points
-- @tparam {number,...} pixels their pixels
-- @tparam int npts how many points
-- @tparam {number,...} r the start's flat rotation (overwritten by the fit's)
-- @tparam number tx the start's translation
-- @tparam number ty
-- @tparam number tz
-- @tparam int max_it bound on the fit's linearisations
function M.keep(found, camera, points, pixels, npts, r, tx, ty, tz, max_it)
  local cost, k, sse
  tx, ty, tz, cost, k, sse = fit.fit(camera, points, pixels, npts, r, tx, ty, tz, max_it)
  if not (cost < huge and finite(r, tx, ty, tz, sse)) then return end
  local m
  for i = 1, #found do
    if rotation.angle(found[i].r, r) < M.SAME_MINIMUM then
      m = found[i]
      break
    end
  end
  if not m then
    m = { r = {}, sse = huge }
    found[#found + 1] = m
  end
  if sse < m.sse then
    for i = 1, 9 do m.r[i] = r[i] end
    m.x, m.y, m.z, m.sse, m.k = tx, ty, tz, sse, k
  end
  -- by squared error (a list of a few: insertion)
  for i = #found, 2, -1 do
    if found[i].sse < found[i - 1].sse then found[i], found[i - 1] = found[i - 1], found[i] end
  end
end

--- Most starts fit where the tags are in one plane (those of least cost): up to eight tags, all.
M.PLANE_STARTS = 16
--- Starts closer than this (radians, and as a part of the distance) to one fitted are not.
M.SAME_START = 0.02

local chosen, chosen_cost = {}, {} -- the starts of least cost, by cost
local tried = {} -- the starts fitted: {r =, x =, y =, z =}

-- The `count` starts of least cost over all the corners, in the order of their index: a
-- start's cost is summed a few tags at a time and dropped once it passes the count-th best so
-- far (so costing the starts is about linear in the corners, not in corners times starts).
local function cheapest(camera, points, pixels, npts, starts, get_start, count)
  local m = 0
  for k = 1, starts do
    local tx, ty, tz = get_start(k, r_k)
    local bound = m == count and chosen_cost[m] or huge
    local c = 0
    for first = 1, npts, 16 do
      c = c + fit.cost(camera, points, pixels, first, first + 15 < npts and first + 15 or npts,
        r_k, tx, ty, tz)
      if not (c < bound) then break end
    end
    if c < bound then
      if m < count then m = m + 1 end
      local j = m - 1
      while j >= 1 and chosen_cost[j] > c do
        chosen[j + 1], chosen_cost[j + 1] = chosen[j], chosen_cost[j]
        j = j - 1
      end
      chosen[j + 1], chosen_cost[j + 1] = k, c
    end
  end
  for i = m + 1, #chosen do chosen[i], chosen_cost[i] = nil, nil end
  table.sort(chosen)
  return m
end

--- The minima of the joint fit: from every start (each tag's poses; the `PLANE_STARTS` of least
-- cost, a start next to one fitted skipped) where the tags are in one plane — there the best
-- start alone can lead to the wrong one of several minima, as it does for two distant tags on
-- one wall — else from the start that fits all the corners best.
-- @tparam table camera a checked camera
-- @tparam {number,...} points the joint fit's body points
-- @tparam {number,...} pixels their pixels
-- @tparam int npts how many points
-- @tparam int starts how many starts
-- @tparam function get_start `get_start(k, r)`: start k's rotation into r, its translation
--   returned
-- @tparam int max_it bound on a fit's linearisations
-- @tparam boolean plane the tags are in one plane
-- @treturn {table,...} the minima, best first
function M.find(camera, points, pixels, npts, starts, get_start, max_it, plane)
  local found = {}
  local m = starts
  if not plane or starts > M.PLANE_STARTS then
    m = cheapest(camera, points, pixels, npts, starts, get_start, plane and M.PLANE_STARTS or 1)
  else
    for k = 1, starts do chosen[k] = k end
  end
  local fitted = 0
  for i = 1, m do
    local tx, ty, tz = get_start(chosen[i], r_k)
    -- a start next to one fitted already (the tags of one board agree) leads where it led
    local near = false
    for j = 1, fitted do
      local f = tried[j]
      local d2 = ((f.x - tx) * (f.x - tx)) + ((f.y - ty) * (f.y - ty)) + ((f.z - tz) * (f.z - tz))
      if d2 < (M.SAME_START * M.SAME_START) * (tx * tx + ty * ty + tz * tz)
        and rotation.angle(f.r, r_k) < M.SAME_START then
        near = true
        break
      end
    end
    if not near then
      fitted = fitted + 1
      local f = tried[fitted] or { r = {} }
      tried[fitted] = f
      for q = 1, 9 do f.r[q] = r_k[q] end
      f.x, f.y, f.z = tx, ty, tz
      M.keep(found, camera, points, pixels, npts, r_k, tx, ty, tz, max_it)
    end
  end
  return found
end

return M
