--- The least-squares kernels under every pose fit: a camera packed for them, one point's
-- squared reprojection residual and its share of the normal equations, the damped
-- Gauss-Newton step, and the Cayley rotation update.
--
-- A fit moves a pose `X = R·P + t` (rotation R, translation t, camera frame) by a step
-- `δ = (δω, δt)`: the rotation on the left by a rotation vector, `R ← exp([δω]×) R`, the
-- translation additively. For a point whose offset from the body origin is `Y = R·P`, seen at
-- pixel `(u, v)`, the residual is `(u(X) − u, v(X) − v)` and its Jacobian rows are
--
--     ∂r/∂δt = e,   ∂r/∂δω = Y × e,   e = ∂pixel/∂X at X,
--
-- accumulated point by point into the normal equations `H δ = −g`, `H = Σ jᵀj`, `g = Σ jᵀr`.
-- The normal equations are a flat array of 27 numbers: the upper triangle of H row by row
-- (`h11, h12, ..., h16, h22, ..., h66`: 21 numbers, over `(δω1, δω2, δω3, δt1, δt2, δt3)`),
-- then g (6 numbers). Units are pixels; rotations are flat row-major 3×3 (see
-- `tagpose.rotation`).
--
-- A packed camera (`pack`) is a record of the intrinsics and the lens model with named fields:
-- `fx, fy, cx, cy`, `lens` (`NONE`, `BROWN` or `FISHEYE`) and the lens coefficients
-- (`k1, k2, p1, p2, k3, k4, k5, k6` for Brown-Conrady; `k1, k2, k3, k4` for fisheye; 0 where
-- not given).
-- @module tagpose.core.lsq

local lens_model = require("tagpose.core.lens")

local huge = math.huge
local brown, fisheye, coefficients = lens_model.brown, lens_model.fisheye,
  lens_model.coefficients

local M = {}

--- The (row, col) of the 21 numbers of a packed upper triangle (the order of H above), as
-- `{a, b}` pairs.
M.UPPER = {}
do
  local k = 0
  for a = 1, 6 do
    for b = a, 6 do
      k = k + 1
      M.UPPER[k] = { a, b }
    end
  end
end

--- The normal equations of a rigid set of points under the pose `(r, t)` into N (zeroed
-- first), and their sum of squared residuals: `accumulate` over the points `P` (`points`,
-- flat `x, y, z` each) seen at `px` (flat `u, v` each).
-- @tparam {number,...} N the 27 numbers to fill
-- @tparam table C a packed camera
-- @tparam {number,...} r flat rotation (its first nine entries are read)
-- @tparam number tx the translation
-- @tparam number ty
-- @tparam number tz
-- @tparam {number,...} points
-- @tparam {number,...} px
-- @tparam int n the number of points
-- @treturn number the sum of squared residuals (px²), or `math.huge` (N incomplete) when a
--   point is not in front of the camera
function M.points(N, C, r, tx, ty, tz, points, px, n)
  local r1, r2, r3, r4, r5, r6, r7, r8, r9 = r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9]
  for k = 1, 27 do N[k] = 0 end
  local s = 0
  local accumulate = M.accumulate
  for k = 1, n do
    local b = 3 * k
    local a1, a2, a3 = points[b - 2], points[b - 1], points[b]
    -- the point relative to the body origin (Y = R P), in the camera frame
    s = s + accumulate(N, C, r1 * a1 + r2 * a2 + r3 * a3, r4 * a1 + r5 * a2 + r6 * a3,
      r7 * a1 + r8 * a2 + r9 * a3, tx, ty, tz, px[2 * k - 1], px[2 * k])
    if not (s < huge) then return huge end
  end
  return s
end

--- Lens kind of a packed camera: none (pinhole).
M.NONE = 0
--- Lens kind: Brown-Conrady.
M.BROWN = 1
--- Lens kind: fisheye (Kannala-Brandt).
M.FISHEYE = 2

--- A pivot of the 6×6 LDLᵀ below this times its own diagonal entry is singular.
M.SINGULAR = 1e-13

--- Pack a checked camera for the kernels.
-- @tparam table camera a checked camera (`tagpose.camera.check`)
-- @tparam[opt] table out the record to fill
-- @treturn table out `{fx, fy, cx, cy, lens, k1, k2, p1, p2, k3, k4, k5, k6}`
function M.pack(camera, out)
  out = out or {}
  out.fx, out.fy, out.cx, out.cy = camera.fx, camera.fy, camera.cx, camera.cy
  -- the model's coefficients in the order its maps take them
  local lens, c1, c2, c3, c4, c5, c6, c7, c8 = coefficients(camera)
  out.lens = lens
  if lens == M.FISHEYE then
    out.k1, out.k2, out.k3, out.k4, out.p1, out.p2, out.k5, out.k6 = c1, c2, c3, c4, 0, 0, 0, 0
  else
    out.k1, out.k2, out.p1, out.p2 = c1 or 0, c2 or 0, c3 or 0, c4 or 0
    out.k3, out.k4, out.k5, out.k6 = c5 or 0, c6 or 0, c7 or 0, c8 or 0
  end
  return out
end

--- The pixel of a point in the camera frame, through the lens.
-- @tparam table C a packed camera
-- @tparam number x
-- @tparam number y
-- @tparam number z (> 0)
-- @treturn number u
-- @treturn number v
function M.project(C, x, y, z)
  local pu, pv = x / z, y / z
  local lens = C.lens
  if lens == 1 then
    pu, pv = brown(pu, pv, C.k1, C.k2, C.p1, C.p2, C.k3, C.k4, C.k5, C.k6)
  elseif lens == 2 then
    pu, pv = fisheye(pu, pv, C.k1, C.k2, C.k3, C.k4)
  end
  return C.fx * pu + C.cx, C.fy * pv + C.cy
end

local project = M.project

--- The pixel residual of a point in the camera frame observed at (u, v): its projection minus
-- the observation, so that a sum of squares reads `s = s + du * du + dv * dv`.
-- @tparam table C a packed camera
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @tparam number u observed pixel
-- @tparam number v
-- @treturn number du
-- @treturn number dv (`math.huge, 0` when the point is not in front of the camera, so that the
--   sum of squares is `math.huge`)
function M.residual(C, x, y, z, u, v)
  if not (z > 0) then return huge, 0 end
  local pu, pv = project(C, x, y, z)
  return pu - u, pv - v
end

--- One point's share of the normal equations, added into N (the module's layout), for any lens.
-- The point is `X = Y + t` in the camera frame, `Y` its offset from the body origin, observed
-- at pixel (u, v). For a pinhole, `e_u = (fx/z)·(1, 0, −pu)` and `e_v = (fy/z)·(0, 1, −pv)`
-- give the rows written out below; through a lens, per residual,
-- `e = f·(j_1 ∂pu/∂X + j_2 ∂pv/∂X)`, `∂p/∂X = (1, 0, −p) / z`, j the lens map's Jacobian.
-- @tparam {number,...} N normal equations to add into
-- @tparam table C a packed camera
-- @tparam number y1 the offset Y
-- @tparam number y2
-- @tparam number y3
-- @tparam number tx the translation t
-- @tparam number ty
-- @tparam number tz
-- @tparam number u observed pixel
-- @tparam number v
-- @treturn number the point's squared residual (px²), or `math.huge` (N untouched) when the
--   point is not in front of the camera
function M.accumulate(N, C, y1, y2, y3, tx, ty, tz, u, v)
  local z = y3 + tz
  if not (z > 0) then return huge end
  local fx, fy, lens = C.fx, C.fy, C.lens
  local iz = 1 / z
  local pu, pv = (y1 + tx) * iz, (y2 + ty) * iz
  if lens == 0 then
    -- pinhole: the Jacobian rows are u = (fx/z)·(-pu·Y2, Y3 + pu·Y1, -Y2, 1, 0, -pu) and
    -- v = (fy/z)·(-pv·Y2 - Y3, pv·Y1, Y1, 0, 1, -pv); H += u uᵀ + v vᵀ, g += u ru + v rv
    local ru, rv = fx * pu + C.cx - u, fy * pv + C.cy - v
    local fa, fb = fx * iz, fy * iz
    local u1, u2, u3, u6 = -fa * pu * y2, fa * (y3 + pu * y1), -fa * y2, -fa * pu
    local v1, v2, v3, v6 = -fb * (pv * y2 + y3), fb * pv * y1, fb * y1, -fb * pv
    N[1], N[2] = N[1] + u1 * u1 + v1 * v1, N[2] + u1 * u2 + v1 * v2
    N[3], N[4], N[5] = N[3] + u1 * u3 + v1 * v3, N[4] + u1 * fa, N[5] + v1 * fb
    N[6], N[7] = N[6] + u1 * u6 + v1 * v6, N[7] + u2 * u2 + v2 * v2
    N[8], N[9], N[10] = N[8] + u2 * u3 + v2 * v3, N[9] + u2 * fa, N[10] + v2 * fb
    N[11], N[12] = N[11] + u2 * u6 + v2 * v6, N[12] + u3 * u3 + v3 * v3
    N[13], N[14], N[15] = N[13] + u3 * fa, N[14] + v3 * fb, N[15] + u3 * u6 + v3 * v6
    N[16], N[18], N[19] = N[16] + fa * fa, N[18] + fa * u6, N[19] + fb * fb
    N[20], N[21] = N[20] + fb * v6, N[21] + u6 * u6 + v6 * v6
    N[22], N[23] = N[22] + u1 * ru + v1 * rv, N[23] + u2 * ru + v2 * rv
    N[24], N[25] = N[24] + u3 * ru + v3 * rv, N[25] + fa * ru
    N[26], N[27] = N[26] + fb * rv, N[27] + u6 * ru + v6 * rv
    return ru * ru + rv * rv
  end
  local xd, yd, j11, j12, j21, j22
  if lens == 1 then
    xd, yd, j11, j12, j21, j22 = brown(pu, pv, C.k1, C.k2, C.p1, C.p2, C.k3, C.k4, C.k5, C.k6)
  else
    xd, yd, j11, j12, j21, j22 = fisheye(pu, pv, C.k1, C.k2, C.k3, C.k4)
  end
  local ru, rv = fx * xd + C.cx - u, fy * yd + C.cy - v
  for row = 1, 2 do
    local e1, e2, res = fx * j11 * iz, fx * j12 * iz, ru
    if row == 2 then e1, e2, res = fy * j21 * iz, fy * j22 * iz, rv end
    local e3 = -(e1 * pu + e2 * pv)
    local w1, w2, w3 = y2 * e3 - y3 * e2, y3 * e1 - y1 * e3, y1 * e2 - y2 * e1
    N[1], N[2], N[3] = N[1] + w1 * w1, N[2] + w1 * w2, N[3] + w1 * w3
    N[4], N[5], N[6] = N[4] + w1 * e1, N[5] + w1 * e2, N[6] + w1 * e3
    N[7], N[8], N[9] = N[7] + w2 * w2, N[8] + w2 * w3, N[9] + w2 * e1
    N[10], N[11], N[12] = N[10] + w2 * e2, N[11] + w2 * e3, N[12] + w3 * w3
    N[13], N[14], N[15] = N[13] + w3 * e1, N[14] + w3 * e2, N[15] + w3 * e3
    N[16], N[17], N[18] = N[16] + e1 * e1, N[17] + e1 * e2, N[18] + e1 * e3
    N[19], N[20], N[21] = N[19] + e2 * e2, N[20] + e2 * e3, N[21] + e3 * e3
    N[22], N[23], N[24] = N[22] + w1 * res, N[23] + w2 * res, N[24] + w3 * res
    N[25], N[26], N[27] = N[25] + e1 * res, N[26] + e2 * res, N[27] + e3 * res
  end
  return ru * ru + rv * rv
end

--- Solve a 6×6 symmetric positive definite system by an unrolled LDLᵀ factorisation (no square
-- roots), on scalars, so nothing is allocated: the upper triangle `a11, a12, ..., a16, a22, ...,
-- a66` row by row, then the right-hand side `b1..b6`. `e_ij = l_ij · d_j` are kept so each
-- product is formed once.
-- @treturn number x1 .. x6, the solution
-- @return nil when the matrix is not positive definite to working precision (a pivot falls
--   below `SINGULAR` times its own diagonal entry, a test that does not depend on the units of
--   the unknowns)
function M.spd6(a11, a12, a13, a14, a15, a16, a22, a23, a24, a25, a26,
    a33, a34, a35, a36, a44, a45, a46, a55, a56, a66,
    b1, b2, b3, b4, b5, b6)
  local singular = M.SINGULAR
  local d1 = a11
  if not (d1 > singular * a11) then return nil end
  local e21, e31, e41, e51, e61 = a12, a13, a14, a15, a16
  local l21, l31, l41, l51, l61 = e21 / d1, e31 / d1, e41 / d1, e51 / d1, e61 / d1
  local d2 = a22 - l21 * e21
  if not (d2 > singular * a22) then return nil end
  local e32 = a23 - l31 * e21
  local l32 = e32 / d2
  local e42 = a24 - l41 * e21
  local l42 = e42 / d2
  local e52 = a25 - l51 * e21
  local l52 = e52 / d2
  local e62 = a26 - l61 * e21
  local l62 = e62 / d2
  local d3 = a33 - l31 * e31 - l32 * e32
  if not (d3 > singular * a33) then return nil end
  local e43 = a34 - l41 * e31 - l42 * e32
  local l43 = e43 / d3
  local e53 = a35 - l51 * e31 - l52 * e32
  local l53 = e53 / d3
  local e63 = a36 - l61 * e31 - l62 * e32
  local l63 = e63 / d3
  local d4 = a44 - l41 * e41 - l42 * e42 - l43 * e43
  if not (d4 > singular * a44) then return nil end
  local e54 = a45 - l51 * e41 - l52 * e42 - l53 * e43
  local l54 = e54 / d4
  local e64 = a46 - l61 * e41 - l62 * e42 - l63 * e43
  local l64 = e64 / d4
  local d5 = a55 - l51 * e51 - l52 * e52 - l53 * e53 - l54 * e54
  if not (d5 > singular * a55) then return nil end
  local e65 = a56 - l61 * e51 - l62 * e52 - l63 * e53 - l64 * e54
  local l65 = e65 / d5
  local d6 = a66 - l61 * e61 - l62 * e62 - l63 * e63 - l64 * e64 - l65 * e65
  if not (d6 > singular * a66) then return nil end
  local y1 = b1
  local y2 = b2 - l21 * y1
  local y3 = b3 - l31 * y1 - l32 * y2
  local y4 = b4 - l41 * y1 - l42 * y2 - l43 * y3
  local y5 = b5 - l51 * y1 - l52 * y2 - l53 * y3 - l54 * y4
  local y6 = b6 - l61 * y1 - l62 * y2 - l63 * y3 - l64 * y4 - l65 * y5
  local x6 = y6 / d6
  local x5 = y5 / d5 - l65 * x6
  local x4 = y4 / d4 - l54 * x5 - l64 * x6
  local x3 = y3 / d3 - l43 * x4 - l53 * x5 - l63 * x6
  local x2 = y2 / d2 - l32 * x3 - l42 * x4 - l52 * x5 - l62 * x6
  local x1 = y1 / d1 - l21 * x2 - l31 * x3 - l41 * x4 - l51 * x5 - l61 * x6
  return x1, x2, x3, x4, x5, x6
end

local spd6 = M.spd6

--- The damped Gauss-Newton step of the normal equations N, the damping raised (×10) from
-- `lambda` until the system solves (the diagonal of H scaled by `1 + lambda`).
-- @tparam {number,...} N normal equations (the module's layout)
-- @tparam number lambda the damping to try first
-- @treturn number the damping used
-- @treturn number the predicted squared displacement of the points,
--   `δᵀHδ = −δ·g − λ Σ H_ii δ_i²`
-- @treturn number δω1, δω2, δω3, δt1, δt2, δt3: the step
-- @return nil when no damping up to 1e8 solves
function M.damped_step(N, lambda)
  local d1, d2, d3, d4, d5, d6
  while true do
    local f = 1 + lambda
    d1, d2, d3, d4, d5, d6 = spd6(N[1] * f, N[2], N[3], N[4], N[5], N[6], N[7] * f, N[8],
      N[9], N[10], N[11], N[12] * f, N[13], N[14], N[15], N[16] * f, N[17], N[18],
      N[19] * f, N[20], N[21] * f, -N[22], -N[23], -N[24], -N[25], -N[26], -N[27])
    if d1 then break end
    if lambda > 1e8 then return nil end
    lambda = lambda * 10
  end
  local disp = -(d1 * N[22] + d2 * N[23] + d3 * N[24] + d4 * N[25] + d5 * N[26] + d6 * N[27])
    - lambda * (N[1] * d1 * d1 + N[7] * d2 * d2 + N[12] * d3 * d3 + N[16] * d4 * d4
      + N[19] * d5 * d5 + N[21] * d6 * d6)
  return lambda, disp, d1, d2, d3, d4, d5, d6
end

--- The rotation a step δω applies on the left, row-major: the Cayley transform of w = δω / 2,
-- `C = I + 2 ([w]× + [w]×²) / (1 + |w|²)`, an exact rotation that is exp(δω) to first order.
-- @tparam number d1 δω
-- @tparam number d2
-- @tparam number d3
-- @treturn number c11, c12, c13, c21, c22, c23, c31, c32, c33
function M.cayley(d1, d2, d3)
  local w1, w2, w3 = 0.5 * d1, 0.5 * d2, 0.5 * d3
  local ww = w1 * w1 + w2 * w2 + w3 * w3
  local n = 2 / (1 + ww)
  local p12, p13, p23 = n * w1 * w2, n * w1 * w3, n * w2 * w3
  return 1 + n * (w1 * w1 - ww), p12 - n * w3, p13 + n * w2,
    p12 + n * w3, 1 + n * (w2 * w2 - ww), p23 - n * w1,
    p13 - n * w2, p23 + n * w1, 1 + n * (w3 * w3 - ww)
end

--- A flat 3×3 rotation turned on the left by a step δω: `Q ← C(δω)·P` (`cayley`), Q's first
-- nine numbers (Q may not be P).
-- @tparam number d1 δω
-- @tparam number d2
-- @tparam number d3
-- @tparam {number,...} P the rotation, row-major
-- @tparam {number,...} Q filled
function M.turn(d1, d2, d3, P, Q)
  local c11, c12, c13, c21, c22, c23, c31, c32, c33 = M.cayley(d1, d2, d3)
  for j = 1, 3 do
    local a, b, c = P[j], P[3 + j], P[6 + j]
    Q[j] = c11 * a + c12 * b + c13 * c
    Q[3 + j] = c21 * a + c22 * b + c23 * c
    Q[6 + j] = c31 * a + c32 * b + c33 * c
  end
end

return M
