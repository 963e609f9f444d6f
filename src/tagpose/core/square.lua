--- The camera equations of a square and the report's reduction of them.
--
-- Input everywhere is the flat array `m` of the four corners in normalised, undistorted image
-- coordinates, `{x1, y1, x2, y2, x3, y3, x4, y4}` with `xi = (ui - cx) / fx`,
-- `yi = (vi - cy) / fy`, corners in the detection order (c1..c4, docs/conventions.md).
--
-- The report's nine unknowns are the tag centre `C = (x, y, z)` and the half-side vectors
-- `A = (a, b, c)`, `P = (p, q, r)`, with corners `P1 = C + A + P`, `P2 = C + A - P`,
-- `P3 = C - A - P`, `P4 = C - A + P`. In the tag frame (docs/conventions.md),
-- `A = +y_tag * s/2` and `P = -x_tag * s/2`.
--
-- Every corner lies on its ray: `Pi = λi * (xi, yi, 1)`, where `λi` is the corner's depth. The
-- report's linear systems (its equations 9, 13 and 16) are solved here in that form, in closed
-- form, instead of by elimination:
--
-- * eight equations, base `z` (the proximate solution): the four corners form a parallelogram,
--   `λ1 m1 - λ2 m2 + λ3 m3 - λ4 m4 = 0`, so `λ` is the null vector of the 3×4 matrix
--   `[m1, -m2, m3, -m4]`: `λ = (o234, o134, o124, o123)`, where `oijk = -det(mi, mj, mk)` is
--   twice the signed area of the image triangle `i, j, k` (positive for the detection order);
-- * six equations, base `c, r, z` (corners 1-3): `λ1 = z + c + r`, `λ2 = z + c - r`,
--   `λ3 = z - c - r`, since `c, r, z` are the depth parts of `A`, `P`, `C`.
--
-- Both give exactly the solution of the report's elimination (the specs check it against a
-- generic Gaussian elimination of the report's matrix), with less work and no pivoting.
-- @module tagpose.core.square

local rotation = require("tagpose.core.rotation")

local sqrt, abs, max = math.sqrt, math.abs, math.max
local huge = math.huge

local M = {}

--- Relative size below which a corner distance counts as zero (corners coincide).
M.COINCIDENT = 1e-9
--- Relative size below which a corner triangle's area counts as zero (corners collinear).
M.COLLINEAR = 1e-9

--- Check that the corners can be a square seen from the front, and return the corner depths
-- of the proximate solution (up to a common positive factor).
--
-- Rejected: corners that coincide, three corners on a line, a quadrilateral that is not convex
-- (including a self-intersecting "bow-tie"), and corners that wind the other way round (a
-- mirrored corner order, or a tag seen from behind).
-- @tparam {number,...} m flat corners (normalised)
-- @treturn number λ1 = o234
-- @treturn number λ2 = o134
-- @treturn number λ3 = o124
-- @treturn number λ4 = o123
-- @return nil, string when the corners are not a usable square
function M.shape(m)
  local x1, y1, x2, y2, x3, y3, x4, y4 = m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
  -- twice the signed areas of the four corner triangles, positive for the detection order
  local o234 = (x4 - x2) * (y3 - y2) - (x3 - x2) * (y4 - y2)
  local o134 = (x4 - x1) * (y3 - y1) - (x3 - x1) * (y4 - y1)
  local o124 = (x4 - x1) * (y2 - y1) - (x2 - x1) * (y4 - y1)
  local o123 = (x3 - x1) * (y2 - y1) - (x2 - x1) * (y3 - y1)
  -- the size of the quadrilateral: its longer diagonal, squared
  local d13 = (x3 - x1) * (x3 - x1) + (y3 - y1) * (y3 - y1)
  local d24 = (x4 - x2) * (x4 - x2) + (y4 - y2) * (y4 - y2)
  local size = max(d13, d24)
  local limit = M.COLLINEAR * size
  if o234 > limit and o134 > limit and o124 > limit and o123 > limit and size < huge then
    return o234, o134, o124, o123
  end
  -- not a usable square: find out why
  if not (size < huge) then return nil, "square: corners are not finite" end
  size = 0
  for i = 1, 3 do
    for j = i + 1, 4 do
      local dx, dy = m[2 * j - 1] - m[2 * i - 1], m[2 * j] - m[2 * i]
      local d = dx * dx + dy * dy
      if d > size then size = d end
    end
  end
  local near = M.COINCIDENT * M.COINCIDENT * size
  for i = 1, 3 do
    for j = i + 1, 4 do
      local dx, dy = m[2 * j - 1] - m[2 * i - 1], m[2 * j] - m[2 * i]
      if not (dx * dx + dy * dy > near) then
        return nil, "square: corners " .. i .. " and " .. j .. " coincide"
      end
    end
  end
  limit = M.COLLINEAR * size
  if abs(o234) <= limit or abs(o134) <= limit or abs(o124) <= limit or abs(o123) <= limit then
    return nil, "square: corners are collinear"
  end
  if o234 < 0 and o134 < 0 and o124 < 0 and o123 < 0 then
    return nil, "square: corners wind the wrong way round (mirrored order, or tag seen from "
      .. "behind; OpenCV's and ArUco's detectors give them top-left first: options.order = "
      .. "'opencv')"
  end
  return nil, "square: corners are not a convex quadrilateral"
end

--- The report's proximate solution (all eight equations, base `z`): its ratios
-- `c_z = c / z` and `r_z = r / z`, the start point of solveQuad.
-- @tparam number l1 corner depths from `shape`
-- @tparam number l2
-- @tparam number l3
-- @tparam number l4
-- @treturn number c_z
-- @treturn number r_z
function M.proximate(l1, l2, l3, l4)
  local s = l1 + l2 + l3 + l4
  return (l1 + l2 - l3 - l4) / s, (l1 - l2 - l3 + l4) / s
end

--- The report's reduction (six equations of corners 1-3 and the two square constraints) to
-- two quadratics in `X = c / z`, `Y = r / z` (its equation 19):
-- `G1 = (A·P) / z²` and `G2 = (|A|² - |P|²) / z²`, each
-- `A·X² + B·Y² + C·X·Y + D·X + E·Y + F`.
-- @tparam {number,...} m flat corners (normalised)
-- @tparam[opt] {number,...} q array to fill with `A1, B1, C1, D1, E1, F1, A2, ..., F2`
-- @treturn {number,...} q
function M.quadratics(m, q)
  q = q or {}
  local x1, y1, x2, y2, x3, y3 = m[1], m[2], m[3], m[4], m[5], m[6]
  -- with λ1 = 1+X+Y, λ2 = 1+X-Y, λ3 = 1-X-Y:
  --   2A = λ2 m2 - λ3 m3 = e0 (1 - Y) + e1 X,   e0 = m2 - m3, e1 = m2 + m3
  --   2P = λ1 m1 - λ2 m2 = f0 (1 + X) + f2 Y,   f0 = m1 - m2, f2 = m1 + m2
  local e0x, e0y = x2 - x3, y2 - y3             -- z component 0
  local e1x, e1y = x2 + x3, y2 + y3             -- z component 2
  local f0x, f0y = x1 - x2, y1 - y2             -- z component 0
  local f2x, f2y = x1 + x2, y1 + y2             -- z component 2
  local e0f0 = e0x * f0x + e0y * f0y
  local e0f2 = e0x * f2x + e0y * f2y
  local e1f0 = e1x * f0x + e1y * f0y
  local e1f2 = e1x * f2x + e1y * f2y + 4
  local e0e0 = e0x * e0x + e0y * e0y
  local e0e1 = e0x * e1x + e0y * e1y
  local e1e1 = e1x * e1x + e1y * e1y + 4
  local f0f0 = f0x * f0x + f0y * f0y
  local f0f2 = f0x * f2x + f0y * f2y
  local f2f2 = f2x * f2x + f2y * f2y + 4
  -- G1 = A·P
  q[1] = 0.25 * e1f0
  q[2] = -0.25 * e0f2
  q[3] = 0.25 * (e1f2 - e0f0)
  q[4] = 0.25 * (e0f0 + e1f0)
  q[5] = 0.25 * (e0f2 - e0f0)
  q[6] = 0.25 * e0f0
  -- G2 = |A|² - |P|²
  q[7] = 0.25 * (e1e1 - f0f0)
  q[8] = 0.25 * (e0e0 - f2f2)
  q[9] = -0.5 * (e0e1 + f0f2)
  q[10] = 0.5 * (e0e1 - f0f0)
  q[11] = -0.5 * (e0e0 + f0f2)
  q[12] = 0.25 * (e0e0 - f0f0)
  return q
end

--- The pose of the square from a root `(X, Y)` of the quadratics (the report's step 4): the
-- size constraint `|A| = s/2` gives `z`, the centre is the midpoint of corners 1 and 3, and the
-- rotation's columns are the tag's axes `x = -P/|P|`, `y = A/|A|` (orthonormalised) and their
-- cross product.
-- @tparam {number,...} m flat corners (normalised)
-- @tparam number X root `c / z`
-- @tparam number Y root `r / z`
-- @tparam number half half the tag's side, `s / 2`
-- @tparam {number,...} r flat 3×3 array to fill with the rotation (tag → camera)
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @return nil, string when a corner of the solution is behind the camera
function M.pose(m, X, Y, half, r)
  local l1, l2, l3 = 1 + X + Y, 1 + X - Y, 1 - X - Y
  if not (l1 > 0 and l2 > 0 and l3 > 0) then
    return nil, "square: the solution puts a corner behind the camera"
  end
  local x1, y1, x2, y2, x3, y3 = m[1], m[2], m[3], m[4], m[5], m[6]
  local ax, ay, az = 0.5 * (l2 * x2 - l3 * x3), 0.5 * (l2 * y2 - l3 * y3), 0.5 * (l2 - l3)
  local px, py, pz = 0.5 * (l1 * x1 - l2 * x2), 0.5 * (l1 * y1 - l2 * y2), 0.5 * (l1 - l2)
  local na = sqrt(ax * ax + ay * ay + az * az)
  if not (na > 0) then return nil, "square: degenerate solution" end
  local z = half / na
  -- columns: x_tag = -P, y_tag = A (normalised by orthonormalise)
  r[1], r[4], r[7] = -px, -py, -pz
  r[2], r[5], r[8] = ax, ay, az
  local ok, err = rotation.orthonormalise(r, r)
  if not ok then return nil, "square: degenerate solution (" .. err .. ")" end
  local s = 0.5 * z
  return s * (l1 * x1 + l3 * x3), s * (l1 * y1 + l3 * y3), s * (l1 + l3)
end

--- The pose of the proximate (parallelogram) solution, for a start when the quadratics have no
-- root: all four corners at the depths `λ`, `A` and `P` from the parallelogram, the scale from
-- the mean of `|A|` and `|P|`.
-- @tparam {number,...} m flat corners (normalised)
-- @tparam number l1 corner depths from `shape`
-- @tparam number l2
-- @tparam number l3
-- @tparam number l4
-- @tparam number half half the tag's side
-- @tparam {number,...} r flat 3×3 array to fill with the rotation
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @return nil, string when the parallelogram is degenerate
function M.proximate_pose(m, l1, l2, l3, l4, half, r)
  local x1, y1, x2, y2, x3, y3, x4, y4 = m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
  -- 4A = P1 + P2 - P3 - P4, 4P = P1 - P2 - P3 + P4, 4C = P1 + P2 + P3 + P4
  local ax = l1 * x1 + l2 * x2 - l3 * x3 - l4 * x4
  local ay = l1 * y1 + l2 * y2 - l3 * y3 - l4 * y4
  local az = l1 + l2 - l3 - l4
  local px = l1 * x1 - l2 * x2 - l3 * x3 + l4 * x4
  local py = l1 * y1 - l2 * y2 - l3 * y3 + l4 * y4
  local pz = l1 - l2 - l3 + l4
  local na = sqrt(ax * ax + ay * ay + az * az)
  local np = sqrt(px * px + py * py + pz * pz)
  if not (na > 0 and np > 0) then return nil, "square: degenerate solution" end
  local s = 2 * half / (na + np)
  r[1], r[4], r[7] = -px, -py, -pz
  r[2], r[5], r[8] = ax, ay, az
  local ok, err = rotation.orthonormalise(r, r)
  if not ok then return nil, "square: degenerate solution (" .. err .. ")" end
  return s * (l1 * x1 + l2 * x2 + l3 * x3 + l4 * x4), s * (l1 * y1 + l2 * y2 + l3 * y3 + l4 * y4),
    s * (l1 + l2 + l3 + l4)
end

return M
