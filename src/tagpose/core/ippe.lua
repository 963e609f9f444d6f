--- Both poses of a square from the local shape of its image: the starts of the refined method.
--
-- The proximate solution's corner depths `λ` (`tagpose.core.square.shape`) make the four corners a
-- parallelogram in space, `Pi = λi (xi, yi, 1)`: a map `P(X, Y) = C + X a + Y b` of the tag
-- plane whose image is the homography through the four corners. Its derivative at the tag
-- centre, `J = ∂(x, y)/∂(X, Y)`, is what the image says about the tag's axes there. For a pose
-- with the tag's axes `r1, r2` and its centre at depth `z0` seen at `m0`,
--
--     z0 J = [I | -m0] (r1 r2).
--
-- Write `(r1 r2) = Rv S`, where `Rv` turns the optical axis onto the line of sight `(m0, 1)`:
-- `[I | -m0] Rv` has a zero third column, so with `B` its first two columns,
-- `z0 B⁻¹ J = G`, the top 2×2 of `S`. The columns of `S` are orthonormal, so the larger
-- singular value of `A = B⁻¹ J` is `1 / z0` and the third row `s` of `S` satisfies
-- `s sᵀ = I - GᵀG`, which fixes `s` up to its sign: the two poses of the planar ambiguity,
-- one the other's normal reflected about the line of sight. This is the local analysis of IPPE
-- (Collins and Bartoli, "Infinitesimal Plane-Based Pose Estimation", IJCV 2014), derived here
-- in the notation of `tagpose.core.square`; both translations put the centre on its line of sight
-- at depth `z0`.
--
-- On exact corners one of the two poses is the tag's to round-off. On noisy corners both are
-- close to the least-squares poses over all four corners, which `tagpose.core.refine` reaches from
-- them in one step or two (the report's method, a three-corner solution, starts it farther
-- away).
-- @module tagpose.core.ippe

local sqrt, max, huge = math.sqrt, math.max, math.huge

local M = {}

-- Rv, the rotation taking (0, 0, 1) to the unit line of sight through (mx, my), row-major.
local function line_of_sight(mx, my)
  local n = sqrt(mx * mx + my * my + 1)
  local px, py, pz = mx / n, my / n, 1 / n
  local w = 1 / (1 + pz)
  local v12 = -px * py * w
  return 1 - px * px * w, v12, px, v12, 1 - py * py * w, py, -px, -py, pz
end

-- scratch: the local shape {mx, my, a11, a12, a21, a22}, kept in a table so that few values are
-- live where the poses branch (LuaJIT cannot compile side exits that carry many)
local shape = {}

-- The centre (mx, my) of the tag's image and A = B⁻¹ J, into `shape`.
local function local_shape(m, l1, l2, l3, l4, half)
  local x1, y1, x2, y2, x3, y3, x4, y4 = m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
  -- the parallelogram's centre, up to the depths' common factor: cz C = Σ λi (xi, yi, 1)
  local cz = l1 + l2 + l3 + l4
  local mx = (l1 * x1 + l2 * x2 + l3 * x3 + l4 * x4) / cz
  local my = (l1 * y1 + l2 * y2 + l3 * y3 + l4 * y4) / cz
  -- its half axes, 4 half a = P2 + P3 - P1 - P4 and 4 half b = P1 + P2 - P3 - P4, give
  -- J = [a - az m0, b - bz m0] / C3 (the derivative of the projection at the centre), summed
  -- from the corners' offsets xi - mx so a small tag keeps its digits
  x1, x2, x3, x4 = x1 - mx, x2 - mx, x3 - mx, x4 - mx
  y1, y2, y3, y4 = y1 - my, y2 - my, y3 - my, y4 - my
  local scale = 1 / (half * cz)
  local j11 = scale * (l2 * x2 + l3 * x3 - l1 * x1 - l4 * x4)
  local j12 = scale * (l1 * x1 + l2 * x2 - l3 * x3 - l4 * x4)
  local j21 = scale * (l2 * y2 + l3 * y3 - l1 * y1 - l4 * y4)
  local j22 = scale * (l1 * y1 + l2 * y2 - l3 * y3 - l4 * y4)
  -- B = [I | -m0] Rv (its first two columns), A = B⁻¹ J
  local v11, v12, _, v21, v22, _, v31, v32 = line_of_sight(mx, my)
  local b11, b12 = v11 - mx * v31, v12 - mx * v32
  local b21, b22 = v21 - my * v31, v22 - my * v32
  local det = b11 * b22 - b12 * b21
  shape[1], shape[2] = mx, my
  shape[3], shape[4] = (b22 * j11 - b12 * j21) / det, (b22 * j12 - b12 * j22) / det
  shape[5], shape[6] = (b11 * j21 - b21 * j11) / det, (b11 * j22 - b21 * j12) / det
end

-- The rotation Rv S into r, S's columns (g11, g21, s1) and (g12, g22, s2), the third their
-- cross product.
local function fill(r, mx, my, g11, g12, g21, g22, s1, s2)
  local v11, v12, v13, v21, v22, v23, v31, v32, v33 = line_of_sight(mx, my)
  local c1x = v11 * g11 + v12 * g21 + v13 * s1
  local c1y = v21 * g11 + v22 * g21 + v23 * s1
  local c1z = v31 * g11 + v32 * g21 + v33 * s1
  local c2x = v11 * g12 + v12 * g22 + v13 * s2
  local c2y = v21 * g12 + v22 * g22 + v23 * s2
  local c2z = v31 * g12 + v32 * g22 + v33 * s2
  r[1], r[4], r[7] = c1x, c1y, c1z
  r[2], r[5], r[8] = c2x, c2y, c2z
  r[3], r[6], r[9] = c1y * c2z - c1z * c2y, c1z * c2x - c1x * c2z, c1x * c2y - c1y * c2x
end

--- The two poses of a square from its normalised corners and their proximate depths.
-- @tparam {number,...} m flat normalised corners `{x1, y1, ..., x4, y4}`
-- @tparam number l1 proximate depth of corner 1 (`tagpose.core.square.shape`)
-- @tparam number l2
-- @tparam number l3
-- @tparam number l4
-- @tparam number half half the tag side
-- @tparam {number,...} ra flat rotation to fill: the first pose
-- @tparam {number,...} rb flat rotation to fill: the second pose
-- @treturn number tx the translation, shared by both poses
-- @treturn number ty
-- @treturn number tz
-- @return nil, string when the local shape is degenerate
function M.poses(m, l1, l2, l3, l4, half, ra, rb)
  if not (l1 + l2 + l3 + l4 > 0) then return nil, "ippe: degenerate corners" end
  local_shape(m, l1, l2, l3, l4, half)
  local a11, a12, a21, a22 = shape[3], shape[4], shape[5], shape[6]
  -- A = e·[[1, 0], [0, 1]] + h·[[0, -1], [1, 0]] + f·[[1, 0], [0, -1]] + g·[[0, 1], [1, 0]]: a
  -- scaled rotation (norm Q) plus a scaled reflection (norm R), so σmax = Q + R = 1 / z0 and
  -- AᵀA = (Q² + R²) I + 2QR·(the reflection about the angle α/2), α = angle(f, g) - angle(e, h)
  local e, f, g, h = 0.5 * (a11 + a22), 0.5 * (a11 - a22), 0.5 * (a21 + a12), 0.5 * (a21 - a12)
  local qq, rr = sqrt(e * e + h * h), sqrt(f * f + g * g)
  local sigma = qq + rr
  if not (sigma > 0 and sigma < huge) then return nil, "ippe: degenerate corners" end
  -- s sᵀ = I - GᵀG = (4QR / σ²) w wᵀ, w = (-sin(α/2), cos(α/2)) the unit vector AᵀA shrinks
  -- most; written without cancellation, so a tag nearly face-on to its line of sight (s small)
  -- keeps its precision. Either sign of w will do (the two poses take both).
  local qr = qq * rr
  local ca, sa = f * e + g * h, g * e - f * h -- QR cos α, QR sin α
  local w1, w2 = -sa, qr + ca
  if ca < 0 then w1, w2 = qr - ca, -sa end
  -- (w = 0 only where qr = 0: then s = 0)
  local k = 2 * sqrt(qr) / (sigma * max(sqrt(w1 * w1 + w2 * w2), 1e-300))
  local z0 = 1 / sigma
  local mx, my = shape[1], shape[2]
  local g11, g12, g21, g22 = z0 * a11, z0 * a12, z0 * a21, z0 * a22
  fill(ra, mx, my, g11, g12, g21, g22, k * w1, k * w2)
  fill(rb, mx, my, g11, g12, g21, g22, -k * w1, -k * w2)
  return z0 * mx, z0 * my, z0
end

return M
