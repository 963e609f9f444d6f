--- The arithmetic under `tagpose.tools.localize_plot`'s drawing: the 95 % position ellipse of
-- a covariance, the rigid motion that lays the odometry onto the estimated path, and the bounds
-- and scale of the field's plot. Pure: numbers in, numbers out, no text and no I/O.
--
-- Frames and units: the field's (the map's: x, y on the floor, z up), metres, angles in
-- radians; only `frame`'s scale and sizes are in CSS pixels.
--
-- Inputs:
--
-- - `tags`: the localizer's read map (`loc.tags`, `tagpose.rigid.model.read`'s): `{ids =
--   {id, ...}, [id] = {x =, y =, r = {9}, size =, ...}}`, `r` the flat, row-major tag → field
--   rotation, 1-based (`r[1]`, `r[4]`: the tag's x axis on the floor).
-- - `rows`: the localizer's results, of which only `time`, `position.x`, `position.y` and (for
--   `align` on still pairs) `yaw` are read. A row counts only when its time and position are
--   finite (`has_position`).
-- - `odometry`: samples `{t, x, y, yaw}` in time order, in the odometry's own frame, read
--   linearly interpolated between samples (the yaw along the shorter way round) and not at all
--   outside their span.
-- @module tagpose.tools.localize_geometry

local compat = require("tagpose.core.compat")

local sqrt, cos, sin, log = math.sqrt, math.cos, math.sin, math.log
local floor, ceil, min, max, huge, pi = math.floor, math.ceil, math.min, math.max, math.huge,
  math.pi
local atan2, is_finite = compat.atan2, compat.is_finite

local M = {}

--- χ² of 2 degrees of freedom below which 95 % of the mass lies: `-2 ln 0.05` (5.991).
M.CHI2_95 = -2 * log(0.05)

--- Whether a row can be placed in the field: its time and position x, y all finite.
-- @tparam table row a localizer's result (see the module's header)
-- @treturn boolean
function M.has_position(row)
  local p = row.position
  return p and is_finite(p.x) and is_finite(p.y) and is_finite(row.time)
end

local has_position = M.has_position

--- The 95 % ellipse of a 2×2 position covariance `[[c11, c12], [c12, c22]]`.
-- @tparam number c11 m²
-- @tparam number c12
-- @tparam number c22
-- @treturn number the semi-major axis, m: `sqrt(CHI2_95 · λ1)`
-- @treturn number the semi-minor axis, m: `sqrt(CHI2_95 · λ2)` (a negative eigenvalue from
--   round-off counts as 0)
-- @treturn number the major axis's angle from x, radians in (-π/2, π/2]
-- @usage local a, b, angle = localize_geometry.ellipse(0.04, 0.01, 0.02)
function M.ellipse(c11, c12, c22)
  local m, d = 0.5 * (c11 + c22), 0.5 * (c11 - c22)
  local r = sqrt(d * d + c12 * c12)
  local l1, l2 = max(m + r, 0), max(m - r, 0)
  local angle = 0.5 * atan2(2 * c12, c11 - c22)
  if angle <= -0.5 * pi then angle = angle + pi end
  return sqrt(M.CHI2_95 * l1), sqrt(M.CHI2_95 * l2), angle
end

-- The index k of the last sample with time <= t (0 before the first).
local function bracket(odometry, t)
  local lo, hi = 0, #odometry
  while lo < hi do
    local mid = ceil(0.5 * (lo + hi))
    if odometry[mid][1] <= t then lo = mid else hi = mid - 1 end
  end
  return lo
end

-- The odometry at time t within its span, interpolated: x, y, yaw (nil outside the span).
local function odometry_at(odometry, t)
  local n = #odometry
  if n == 0 or t < odometry[1][1] or t > odometry[n][1] then return nil end
  local k = bracket(odometry, t)
  local a, b = odometry[k], odometry[k + 1]
  if not b or b[1] <= a[1] then return a[2], a[3], a[4] end
  local f = (t - a[1]) / (b[1] - a[1])
  local dyaw = b[4] - a[4]
  dyaw = dyaw - 2 * pi * floor((dyaw + pi) / (2 * pi))
  return a[2] + f * (b[2] - a[2]), a[3] + f * (b[3] - a[3]), a[4] + f * dyaw
end

--- The rigid motion of the plane that best aligns the odometry with the path: `R(θ)·o + t`
-- nearest the rows' positions in least squares over the rows' times within the odometry's span
-- (the odometry interpolated linearly), in closed form: θ = atan2(Σ o'×p', Σ o'·p') of the
-- centred pairs, t = p̄ − R(θ)·ō. When the pairs do not spread (the robot stood still: their
-- spread below 1 mm) θ is the mean difference of the headings instead. Reached as
-- `localize_plot.align` too, whose name its failure message keeps.
-- @tparam {table,...} rows the rows (see the module's header), in any order
-- @tparam {table,...} odometry the samples `{t, x, y, yaw}` in time order
-- @treturn table `{theta =, x =, y =, pairs =, rms =}`: θ (radians), t (m), the number of
--   times matched, the root mean square distance of the aligned pairs (m)
-- @return nil, string when no row's time falls within the odometry's span
-- @usage local al = assert(localize_geometry.align(rows, odometry))
function M.align(rows, odometry)
  local n, ox, oy, px, py = 0, 0, 0, 0, 0
  for _, r in ipairs(rows) do
    if has_position(r) then
      local x, y = odometry_at(odometry, r.time)
      if x then
        n = n + 1
        ox, oy, px, py = ox + x, oy + y, px + r.position.x, py + r.position.y
      end
    end
  end
  if n == 0 then return nil, "localize_plot: no row within the odometry's times" end
  ox, oy, px, py = ox / n, oy / n, px / n, py / n
  local dot, cross, oo, pp, ys, yc = 0, 0, 0, 0, 0, 0
  for _, r in ipairs(rows) do
    if has_position(r) then
      local x, y, yaw = odometry_at(odometry, r.time)
      if x then
        local ax, ay = x - ox, y - oy
        local bx, by = r.position.x - px, r.position.y - py
        dot = dot + ax * bx + ay * by
        cross = cross + ax * by - ay * bx
        oo, pp = oo + ax * ax + ay * ay, pp + bx * bx + by * by
        if is_finite(r.yaw) and is_finite(yaw) then
          ys, yc = ys + sin(r.yaw - yaw), yc + cos(r.yaw - yaw)
        end
      end
    end
  end
  local theta
  if oo > n * 1e-6 and pp > n * 1e-6 then
    theta = atan2(cross, dot)
  else
    theta = (ys ~= 0 or yc ~= 0) and atan2(ys, yc) or 0
  end
  local c, s = cos(theta), sin(theta)
  local tx, ty = px - (c * ox - s * oy), py - (s * ox + c * oy)
  local sq = 0 -- summed directly: oo + pp − 2(c·dot + s·cross) would lose its digits near 0
  for _, r in ipairs(rows) do
    if has_position(r) then
      local x, y = odometry_at(odometry, r.time)
      if x then
        local ex, ey = c * x - s * y + tx - r.position.x, s * x + c * y + ty - r.position.y
        sq = sq + ex * ex + ey * ey
      end
    end
  end
  return { theta = theta, x = tx, y = ty, pairs = n, rms = sqrt(sq / n) }
end

--- The field's extent to draw: the tags' faces (each its size along its x axis on the floor)
-- and the rows' positions, padded by a margin; the unit square padded when there is neither.
-- @tparam table tags the map's read tags (see the module's header)
-- @tparam {table,...} rows the rows (see the module's header)
-- @tparam number margin m
-- @treturn number x0, m
-- @treturn number x1, m
-- @treturn number y0, m
-- @treturn number y1, m
function M.bounds(tags, rows, margin)
  local x0, x1, y0, y1 = huge, -huge, huge, -huge
  local function add(x, y)
    if is_finite(x) and is_finite(y) then
      x0, x1, y0, y1 = min(x0, x), max(x1, x), min(y0, y), max(y1, y)
    end
  end
  for _, id in ipairs(tags.ids) do
    local t = tags[id]
    local h = 0.5 * (t.size or 0)
    add(t.x - h * t.r[1], t.y - h * t.r[4])
    add(t.x + h * t.r[1], t.y + h * t.r[4])
  end
  for _, r in ipairs(rows) do
    if has_position(r) then add(r.position.x, r.position.y) end
  end
  if x0 > x1 then x0, x1, y0, y1 = 0, 1, 0, 1 end
  return x0 - margin, x1 + margin, y0 - margin, y1 + margin
end

--- The plot area of a field's extent: one scale for x and y, the largest that fits it into
-- `max_width` × `max_height`.
-- @tparam number x0 m
-- @tparam number x1 m, > x0
-- @tparam number y0 m
-- @tparam number y1 m, > y0
-- @tparam number max_width px
-- @tparam number max_height px
-- @treturn table `{x0 =, x1 =, y0 =, y1 =, s =, width =, height =}`: the extent (m), the scale
--   (px per m), the plot area's size (px)
function M.frame(x0, x1, y0, y1, max_width, max_height)
  local s = min(max_width / (x1 - x0), max_height / (y1 - y0))
  return { x0 = x0, x1 = x1, y0 = y0, y1 = y1, s = s, width = s * (x1 - x0),
    height = s * (y1 - y0) }
end

return M
