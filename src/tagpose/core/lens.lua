--- Lens models: the maps from undistorted to distorted normalised coordinates (with their
-- Jacobians), their coefficients as a camera gives them, and the inverse where the map is
-- one-to-one.
--
-- As OpenCV defines them:
--
-- * Brown-Conrady (`model = "pinhole"` or none, with `distortion`): `k1, k2, p1, p2, k3` and the
--   rational `k4, k5, k6` (missing ones are 0):
--   `xd = x·R + 2·p1·x·y + p2·(r² + 2x²)`, `yd = y·R + p1·(r² + 2y²) + 2·p2·x·y`,
--   `R = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)`, `r² = x² + y²`;
-- * fisheye (`model = "fisheye"`, equidistant Kannala-Brandt, `cv::fisheye`): `k1..k4`,
--   `θ = atan(r)`, `θd = θ·(1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`, `(xd, yd) = (θd / r)·(x, y)`.
--
-- `camera.distortion` names the coefficients (`{k1 =, k2 =, ...}`) or lists them in OpenCV's
-- `distCoeffs` order (`{k1, k2, p1, p2[, k3[, k4, k5, k6]]}`; fisheye `{k1, k2, k3, k4}`).
--
-- The inverse (`undistort`) is Newton's method on the 2×2 map, to a residual of
-- `UNDISTORT_TOLERANCE`, and it answers only inside the region, around the centre, where the
-- map is one-to-one: a radial map `r ↦ r·R(r²)` folds back where its derivative vanishes, and
-- past a second fold a point has an inverse again that is not the camera's. That region is
-- found exactly for the radial part — the first positive root of `R`'s numerator and
-- denominator and of the derivative `d(r·R)/dr` (polynomials in r², `tagpose.core.poly`), or of
-- `dθd/dθ` for the fisheye — and the Jacobian is required positive along the ray to the point
-- for the tangential part.
-- @module tagpose.core.lens

local compat = require("tagpose.core.compat")
local poly = require("tagpose.core.poly")

local sqrt, abs, huge = math.sqrt, math.abs, math.huge
local atan = compat.atan

local M = {}

--- Lens kinds, as `coefficients` returns them: none (a pinhole).
M.NONE = 0
--- Brown-Conrady.
M.BROWN = 1
--- Fisheye (Kannala-Brandt).
M.FISHEYE = 2

--- Residual (normalised units, relative to `1 + |xd| + |yd|`) at which the inverse of the lens
-- map has converged: about 1e-11 px for focal lengths under 10 000 px, a few units of
-- round-off. A Newton step below a tenth of it also ends the iteration (round-off reached).
M.UNDISTORT_TOLERANCE = 1e-15
--- Bound on the Newton steps of one inversion.
M.UNDISTORT_ITERATIONS = 50

--- The lens model of a checked camera and its coefficients, in the order its map takes them:
-- `NONE`; `BROWN, k1, k2, p1, p2, k3, k4, k5, k6`; `FISHEYE, k1, k2, k3, k4`. A fisheye
-- without coefficients is the plain equidistant fisheye, not a pinhole.
-- @tparam table camera a checked camera
-- @treturn int kind
-- @treturn number,... the coefficients
function M.coefficients(camera)
  local d = camera.distortion
  if camera.model == "fisheye" then
    if d == nil then return 2, 0, 0, 0, 0 end
    if d[1] ~= nil then return 2, d[1], d[2] or 0, d[3] or 0, d[4] or 0 end
    return 2, d.k1 or 0, d.k2 or 0, d.k3 or 0, d.k4 or 0
  end
  if d == nil then return 0 end
  if d[1] ~= nil then
    return 1, d[1], d[2] or 0, d[3] or 0, d[4] or 0, d[5] or 0, d[6] or 0, d[7] or 0, d[8] or 0
  end
  return 1, d.k1 or 0, d.k2 or 0, d.p1 or 0, d.p2 or 0, d.k3 or 0, d.k4 or 0, d.k5 or 0,
    d.k6 or 0
end

local coefficients = M.coefficients

--- Brown-Conrady map on explicit coefficients: the distorted point and its Jacobian
-- (`d xd/d x, d xd/d y, d yd/d x, d yd/d y`).
-- @treturn number xd, yd, and the Jacobian's four entries
local function brown(x, y, k1, k2, p1, p2, k3, k4, k5, k6)
  local r2 = x * x + y * y
  local num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
  local den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
  local radial = num / den
  local dnum = k1 + r2 * (2 * k2 + r2 * 3 * k3)
  local dden = k4 + r2 * (2 * k5 + r2 * 3 * k6)
  local dr = (dnum * den - num * dden) / (den * den) -- d radial / d r²
  local xy = x * y
  local xd = x * radial + 2 * p1 * xy + p2 * (r2 + 2 * x * x)
  local yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * xy
  local cross = 2 * xy * dr + 2 * p1 * x + 2 * p2 * y
  return xd, yd,
    radial + 2 * x * x * dr + 2 * p1 * y + 6 * p2 * x, cross,
    cross, radial + 2 * y * y * dr + 6 * p1 * y + 2 * p2 * x
end

--- Kannala-Brandt fisheye map on explicit coefficients: the distorted point and its Jacobian.
-- @treturn number xd, yd, and the Jacobian's four entries
local function fisheye(x, y, k1, k2, k3, k4)
  local r2 = x * x + y * y
  local scale, dscale -- θd / r and (d scale / d r) / r
  if r2 < 1e-16 then
    scale, dscale = 1, 2 * (k1 - 1 / 3)
  else
    local r = sqrt(r2)
    local t = atan(r)
    local t2 = t * t
    local td = t * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    local dtd = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
    scale = td / r
    dscale = (dtd / (1 + r2) - scale) / r2
  end
  return scale * x, scale * y,
    scale + dscale * x * x, dscale * x * y,
    dscale * x * y, scale + dscale * y * y
end

M.brown, M.fisheye = brown, fisheye

--- Distorted normalised coordinates of an undistorted point, and the Jacobian of the map.
-- @tparam table camera a checked camera
-- @tparam number x
-- @tparam number y
-- @treturn number xd
-- @treturn number yd
-- @treturn number d xd / d x
-- @treturn number d xd / d y
-- @treturn number d yd / d x
-- @treturn number d yd / d y
function M.distort(camera, x, y)
  local kind, a, b, c, d, e, f, g, h = coefficients(camera)
  if kind == 0 then return x, y, 1, 0, 0, 1 end
  if kind == 1 then return brown(x, y, a, b, c, d, e, f, g, h) end
  return fisheye(x, y, a, b, c, d)
end

local distort = M.distort

-- The one-to-one region of the radial part: the smallest positive root of the polynomials
-- (constant first, degree n each) that must stay positive from the centre, or math.huge.
local roots = {}
local function first_root(c, n, limit)
  local k = poly.roots(c, n, roots)
  for i = 1, k do
    if roots[i] > 0 and roots[i] < limit then limit = roots[i] end
  end
  return limit
end

local num, den, dr, dt = {}, {}, {}, {} -- scratch polynomials
local memo = { kind = -1 } -- the last lens's coefficients and its region
-- the radial margins' grid: MARGIN_STEPS radii up to MARGIN_RADIUS (x / z, 63° off axis)
local MARGIN_STEPS, MARGIN_RADIUS = 32, 2

--- The one-to-one region of a lens's radial part: points with `r² < limit` (Brown-Conrady;
-- `r² = x² + y²` undistorted) or `θ² < limit` (fisheye, `θ = atan(r)`) are in it.
-- @tparam int kind `BROWN` or `FISHEYE`
-- @tparam number c1 the coefficients, in `coefficients`' order
-- @tparam number c2
-- @tparam number c3
-- @tparam number c4
-- @tparam[opt] number c5
-- @tparam[opt] number c6
-- @tparam[opt] number c7
-- @tparam[opt] number c8
-- @treturn number limit (`math.huge` when the radial map never folds)
function M.radial_limit(kind, c1, c2, c3, c4, c5, c6, c7, c8)
  local m = memo
  if m.kind == kind and m[1] == c1 and m[2] == c2 and m[3] == c3 and m[4] == c4 and m[5] == c5
    and m[6] == c6 and m[7] == c7 and m[8] == c8 then
    return m.limit
  end
  local limit = huge
  if kind == 2 then
    -- dθd/dθ = 1 + 3 k1 u + 5 k2 u² + 7 k3 u³ + 9 k4 u⁴, u = θ²
    dt[1], dt[2], dt[3], dt[4], dt[5] = 1, 3 * c1, 5 * c2, 7 * c3, 9 * c4
    limit = first_root(dt, 4, limit)
  else
    -- R = N / D in s = r²; d(r R)/dr = P / D², P = N D + 2 s (N' D - N D')
    local k1, k2, k3, k4, k5, k6 = c1, c2, c5, c6, c7, c8
    num[1], num[2], num[3], num[4] = 1, k1, k2, k3
    den[1], den[2], den[3], den[4] = 1, k4, k5, k6
    for i = 1, 7 do dr[i] = 0 end
    for i = 1, 4 do
      for j = 1, 4 do
        -- N D, and 2 s (N' D - N D') with N' = Σ (i-1) n_i s^(i-2): term s^(i+j-2) of each
        dr[i + j - 1] = dr[i + j - 1] + num[i] * den[j] * (1 + 2 * (i - 1) - 2 * (j - 1))
      end
    end
    limit = first_root(num, 3, limit)
    limit = first_root(den, 3, limit)
    limit = first_root(dr, 6, limit)
  end
  m.kind, m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m.limit = kind, c1, c2, c3, c4, c5,
    c6, c7, c8, limit
  if kind == 1 then
    -- the smallest of the radial map's two singular values, R and d(rR)/dr, from the centre
    -- out to each radius of a grid (r up to MARGIN_RADIUS, sampled 4 times per step): the
    -- tangential terms' margin (see `inside`)
    local margins, low = m.margins or {}, huge
    m.margins = margins
    for k = 1, 4 * MARGIN_STEPS do
      local r = MARGIN_RADIUS * k / (4 * MARGIN_STEPS)
      local q = r * r
      local n = 1 + q * (c1 + q * (c2 + q * c5))
      local d = 1 + q * (c6 + q * (c7 + q * c8))
      local dn, dd = c1 + q * (2 * c2 + q * 3 * c5), c6 + q * (2 * c7 + q * 3 * c8)
      local radial, slope = n / d, (n * d + 2 * q * (dn * d - n * dd)) / (d * d)
      if radial < low then low = radial end
      if slope < low then low = slope end
      if k % 4 == 0 then margins[k / 4] = low end
    end
  end
  return limit
end

-- det J of the lens map at s·(x, y)
local function det_at(camera, x, y, s)
  local _, _, a, b, c, d = distort(camera, s * x, s * y)
  return a * d - b * c
end

-- The smallest det J along the ray from the centre to (x, y), searched: 64 samples, and around
-- each sampled local minimum a golden-section search.
local function min_det_along(camera, x, y)
  local low, prev, cur = 1, 1, det_at(camera, x, y, 1 / 64)
  for k = 1, 64 do
    local nxt = k < 64 and det_at(camera, x, y, (k + 1) / 64) or huge
    if cur < low then low = cur end
    if cur <= prev and cur <= nxt and k < 64 then
      local a, b = (k - 1) / 64, (k + 1) / 64
      for _ = 1, 16 do
        local m1, m2 = b - 0.618034 * (b - a), a + 0.618034 * (b - a)
        if det_at(camera, x, y, m1) < det_at(camera, x, y, m2) then b = m2 else a = m1 end
      end
      local v = det_at(camera, x, y, 0.5 * (a + b))
      if v < low then low = v end
    end
    prev, cur = cur, nxt
  end
  return low
end

-- Is the undistorted point (x, y) inside the region where the lens map is one-to-one?
local function inside(camera, x, y)
  local kind, c1, c2, c3, c4, c5, c6, c7, c8 = coefficients(camera)
  local limit = M.radial_limit(kind, c1, c2, c3, c4, c5, c6, c7, c8)
  local r2 = x * x + y * y
  if kind == 2 then
    local t = atan(sqrt(r2))
    return t * t < limit
  end
  if not (r2 < limit) then return false end
  if c3 == 0 and c4 == 0 then return true end
  -- the tangential part adds a matrix of norm at most 12 r (|p1| + |p2|) to the radial map's
  -- Jacobian, whose singular values are R and d(rR)/dr: while they stay above it, det J > 0
  -- (Weyl); they were sampled along the ray (`radial_limit`; a factor 2 for what lies between
  -- samples)
  local r = sqrt(r2)
  local k = math.floor(r / MARGIN_RADIUS * MARGIN_STEPS) + 1
  if k <= MARGIN_STEPS and memo.margins[k] > 24 * r * (abs(c3) + abs(c4)) then return true end
  -- close to a fold: the Jacobian itself, searched along the ray
  return min_det_along(camera, x, y) > 0
end

--- Undistorted normalised coordinates of a distorted normalised point.
-- @tparam table camera a checked camera
-- @tparam number xd
-- @tparam number yd
-- @treturn number x
-- @treturn number y
-- @return nil, string when the point lies where the lens map cannot be inverted
function M.undistort(camera, xd, yd)
  local kind, k1, k2, k3, k4 = coefficients(camera)
  if kind == 0 then return xd, yd end
  if kind == 2 then
    -- θd is (nearly) the angle off the optical axis; at 90 degrees x / z is infinite
    local t = 0.5 * math.pi
    local t2 = t * t
    local limit = t * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    if xd * xd + yd * yd >= limit * limit then
      return nil, "camera: the point is 90 degrees or more from the optical axis"
    end
  end
  local x, y = xd, yd
  local tol = M.UNDISTORT_TOLERANCE * (1 + abs(xd) + abs(yd))
  local converged = false
  for _ = 1, M.UNDISTORT_ITERATIONS do
    local fx, fy, a, b, c, d = distort(camera, x, y)
    local ex, ey = fx - xd, fy - yd
    if ex * ex + ey * ey <= tol * tol then
      converged = true
      break
    end
    local det = a * d - b * c
    if not (det > 0) then break end -- folded: no inverse here
    local sx, sy = (d * ex - b * ey) / det, (a * ey - c * ex) / det
    if sx * sx + sy * sy <= 0.01 * tol * tol then
      converged = true
      break
    end
    -- damp a step that would more than double the radius (the map is steep there)
    local n2, s2 = x * x + y * y, sx * sx + sy * sy
    if s2 > 4 * n2 + 1 then
      local k = sqrt((4 * n2 + 1) / s2)
      sx, sy = sx * k, sy * k
    end
    x, y = x - sx, y - sy
    if not (abs(x) + abs(y) < 1e150) then break end
  end
  if not converged then
    return nil, "camera: the lens model cannot be inverted at this point"
  end
  -- the solution must lie in the region, around the centre, where the map is one-to-one
  if not inside(camera, x, y) then
    return nil, "camera: the point is outside the region where the lens model is one-to-one"
  end
  return x, y
end

return M
