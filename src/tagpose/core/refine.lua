--- Refinement of a tag pose over all four corners, and the second pose of the planar ambiguity.
--
-- `refine` minimises the sum of squared pixel distances between the four observed corners and
-- the projected tag corners (through the camera's lens model) over the six pose parameters, by
-- Levenberg-Marquardt. The rotation is updated on the left by a rotation vector,
-- `R ← exp([ω]×) R`, the translation additively, so the parametrisation is minimal and has no
-- singularity. Each linearisation accumulates the 6×6 normal equations corner by corner:
--
--     r = (u(R, t) - u_obs, v(R, t) - v_obs),   ∂r/∂t = e,   ∂r/∂ω = Y × e
--
-- where `Y = R·c` is the corner relative to the tag centre and `e` the row of ∂pixel/∂X for
-- the corner's camera point X. It stops when a step moves the projected corners by a negligible
-- amount (`STEP_RELATIVE`, `STEP_TOLERANCE`), or after `MAX_ITERATIONS` linearisations.
--
-- `mirror` gives the start of the other local minimum: a square seen in perspective has two
-- poses that project almost alike, one with its normal reflected about the line of sight
-- (IPPE, Schweighofer-Pinz). With `v` the unit line of sight to the tag centre, the mirrored
-- pose keeps the centre and takes `R' = (I - 2 v vᵀ) R diag(1, 1, -1)`.
--
-- A pose is a candidate record (`tagpose.core.pipeline.candidate`): a flat rotation `r` (row-major,
-- tag → camera) and `tx, ty, tz`; pixels are flat `{u1, v1, ..., u4, v4}`; `half` is half the
-- tag side; the camera is packed (`tagpose.core.lsq.pack`). The kernels (per-point normal
-- equations, damped step, Cayley update) are `tagpose.core.lsq`'s.
-- @module tagpose.core.refine

local compat = require("tagpose.core.compat")
local lsq = require("tagpose.core.lsq")
local pose = require("tagpose.core.pose")

local sqrt = math.sqrt
local huge = math.huge
local accumulate, damped_step, cayley, residual = lsq.accumulate, lsq.damped_step, lsq.cayley,
  lsq.residual

local M = {}

--- Bound on the linearisations (Jacobian evaluations) of one refinement.
M.MAX_ITERATIONS = 20
--- A step ends the refinement when the squared displacement it gives the projected corners
-- (summed over the corners) is below `STEP_RELATIVE` times the sum of squared residuals: the
-- pose then moves by a negligible fraction of its own statistical uncertainty...
M.STEP_RELATIVE = 1e-2
--- ... or below `STEP_TOLERANCE`² (px²) when the residuals are at round-off (exact corners).
M.STEP_TOLERANCE = 1e-5

local CX, CY = pose.CORNER_X, pose.CORNER_Y

-- Sum of squared pixel residuals of a pose Q = {ax, ay, az, bx, by, bz, tx, ty, tz}: the tag's x
-- and y axes in the camera (columns 1 and 2 of R) and t; math.huge when a corner is not in
-- front of the camera.
local function residuals(px, C, half, Q)
  local ax, ay, az, bx, by, bz, tx, ty, tz = Q[1], Q[2], Q[3], Q[4], Q[5], Q[6], Q[7], Q[8], Q[9]
  local sum = 0
  for i = 1, 4 do
    local ca, cb = CX[i] * half, CY[i] * half
    local du, dv = residual(C, ax * ca + bx * cb + tx, ay * ca + by * cb + ty,
      az * ca + bz * cb + tz, px[2 * i - 1], px[2 * i])
    sum = sum + du * du + dv * dv
  end
  return sum
end

-- The normal equations of the pose Q (axes a, b; t) into N, corner by corner (`accumulate`),
-- and the sum of squared residuals (math.huge when a corner is not in front of the camera),
-- for any lens. The sums live in the table: LuaJIT cannot compile a loop that leaves with 27
-- live accumulators.
local function linearise_looped(N, px, C, half, Q)
  local qax, qay, qaz, qbx, qby, qbz, qx, qy, qz = Q[1], Q[2], Q[3], Q[4], Q[5], Q[6], Q[7], Q[8],
    Q[9]
  for k = 1, 27 do N[k] = 0 end
  local s = 0
  for i = 1, 4 do
    local ca, cb = CX[i] * half, CY[i] * half
    -- the corner relative to the tag centre (Y), in the camera frame
    s = s + accumulate(N, C, qax * ca + qbx * cb, qay * ca + qby * cb, qaz * ca + qbz * cb, qx,
      qy, qz, px[2 * i - 1], px[2 * i])
    if not (s < huge) then return huge end
  end
  return s
end

-- The normal equations H δ = -g of the pose Q (axes a, b; t) for a pinhole camera, into N as
-- {h11, h12, ..., h16, h22, ..., h66, g1, ..., g6} (upper triangle row by row), and the sum of
-- squared residuals (math.huge when a corner is not in front of the camera).
--
-- Per corner, with Y = R·c the corner relative to the tag centre and (pu, pv) its normalised
-- projection, the Jacobian rows of its two residuals over (δω, δt) are
--   u = (fx/z)·(-pu·Y2, Y3 + pu·Y1, -Y2, 1, 0, -pu),
--   v = (fy/z)·(-pv·Y2 - Y3, pv·Y1, Y1, 0, 1, -pv),
-- and H += u uᵀ + v vᵀ, g += u·ru + v·rv (zeros skipped: h45 stays 0). The corners c = (∓h, ±h)
-- give Y = ±A ± B, A and B half a side along the tag's axes. The same sums as
-- linearise_looped's pinhole case (a spec checks it), with the four corners written out and
-- the sums on locals: the fastest form on PUC Lua, and one LuaJIT cannot compile (too many live
-- values in one trace), so each VM gets its own (see `linearise` below).
local function linearise_unrolled(N, px, C, half, Q)
  local fx, fy, cx, cy = C.fx, C.fy, C.cx, C.cy
  local ax, ay, az = half * Q[1], half * Q[2], half * Q[3]
  local bx, by, bz = half * Q[4], half * Q[5], half * Q[6]
  local qx, qy, qz = Q[7], Q[8], Q[9]
  local h11, h12, h13, h14, h15, h16, h22, h23, h24, h25, h26 = 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
  local h33, h34, h35, h36, h44, h46, h55, h56, h66 = 0, 0, 0, 0, 0, 0, 0, 0, 0
  local g1, g2, g3, g4, g5, g6 = 0, 0, 0, 0, 0, 0
  local s = 0
  local y1, y2, y3, z, iz, pu, pv, ru, rv, fa, fb, u1, u2, u3, u6, v1, v2, v3, v6
  -- corner 1: Y = B - A
  y1, y2, y3 = bx - ax, by - ay, bz - az
  z = y3 + qz
  if not (z > 0) then return huge end
  iz = 1 / z
  pu, pv = (y1 + qx) * iz, (y2 + qy) * iz
  ru, rv = fx * pu + cx - px[1], fy * pv + cy - px[2]
  s = s + ru * ru + rv * rv
  fa, fb = fx * iz, fy * iz
  u1, u2, u3, u6 = -fa * pu * y2, fa * (y3 + pu * y1), -fa * y2, -fa * pu
  v1, v2, v3, v6 = -fb * (pv * y2 + y3), fb * pv * y1, fb * y1, -fb * pv
  h11, h12, h13 = h11 + u1 * u1 + v1 * v1, h12 + u1 * u2 + v1 * v2, h13 + u1 * u3 + v1 * v3
  h14, h15, h16 = h14 + u1 * fa, h15 + v1 * fb, h16 + u1 * u6 + v1 * v6
  h22, h23, h24 = h22 + u2 * u2 + v2 * v2, h23 + u2 * u3 + v2 * v3, h24 + u2 * fa
  h25, h26, h33 = h25 + v2 * fb, h26 + u2 * u6 + v2 * v6, h33 + u3 * u3 + v3 * v3
  h34, h35, h36 = h34 + u3 * fa, h35 + v3 * fb, h36 + u3 * u6 + v3 * v6
  h44, h46, h55, h56 = h44 + fa * fa, h46 + fa * u6, h55 + fb * fb, h56 + fb * v6
  h66, g1, g2 = h66 + u6 * u6 + v6 * v6, g1 + u1 * ru + v1 * rv, g2 + u2 * ru + v2 * rv
  g3, g4, g5, g6 = g3 + u3 * ru + v3 * rv, g4 + fa * ru, g5 + fb * rv, g6 + u6 * ru + v6 * rv
  -- corner 2: Y = A + B
  y1, y2, y3 = ax + bx, ay + by, az + bz
  z = y3 + qz
  if not (z > 0) then return huge end
  iz = 1 / z
  pu, pv = (y1 + qx) * iz, (y2 + qy) * iz
  ru, rv = fx * pu + cx - px[3], fy * pv + cy - px[4]
  s = s + ru * ru + rv * rv
  fa, fb = fx * iz, fy * iz
  u1, u2, u3, u6 = -fa * pu * y2, fa * (y3 + pu * y1), -fa * y2, -fa * pu
  v1, v2, v3, v6 = -fb * (pv * y2 + y3), fb * pv * y1, fb * y1, -fb * pv
  h11, h12, h13 = h11 + u1 * u1 + v1 * v1, h12 + u1 * u2 + v1 * v2, h13 + u1 * u3 + v1 * v3
  h14, h15, h16 = h14 + u1 * fa, h15 + v1 * fb, h16 + u1 * u6 + v1 * v6
  h22, h23, h24 = h22 + u2 * u2 + v2 * v2, h23 + u2 * u3 + v2 * v3, h24 + u2 * fa
  h25, h26, h33 = h25 + v2 * fb, h26 + u2 * u6 + v2 * v6, h33 + u3 * u3 + v3 * v3
  h34, h35, h36 = h34 + u3 * fa, h35 + v3 * fb, h36 + u3 * u6 + v3 * v6
  h44, h46, h55, h56 = h44 + fa * fa, h46 + fa * u6, h55 + fb * fb, h56 + fb * v6
  h66, g1, g2 = h66 + u6 * u6 + v6 * v6, g1 + u1 * ru + v1 * rv, g2 + u2 * ru + v2 * rv
  g3, g4, g5, g6 = g3 + u3 * ru + v3 * rv, g4 + fa * ru, g5 + fb * rv, g6 + u6 * ru + v6 * rv
  -- corner 3: Y = A - B
  y1, y2, y3 = ax - bx, ay - by, az - bz
  z = y3 + qz
  if not (z > 0) then return huge end
  iz = 1 / z
  pu, pv = (y1 + qx) * iz, (y2 + qy) * iz
  ru, rv = fx * pu + cx - px[5], fy * pv + cy - px[6]
  s = s + ru * ru + rv * rv
  fa, fb = fx * iz, fy * iz
  u1, u2, u3, u6 = -fa * pu * y2, fa * (y3 + pu * y1), -fa * y2, -fa * pu
  v1, v2, v3, v6 = -fb * (pv * y2 + y3), fb * pv * y1, fb * y1, -fb * pv
  h11, h12, h13 = h11 + u1 * u1 + v1 * v1, h12 + u1 * u2 + v1 * v2, h13 + u1 * u3 + v1 * v3
  h14, h15, h16 = h14 + u1 * fa, h15 + v1 * fb, h16 + u1 * u6 + v1 * v6
  h22, h23, h24 = h22 + u2 * u2 + v2 * v2, h23 + u2 * u3 + v2 * v3, h24 + u2 * fa
  h25, h26, h33 = h25 + v2 * fb, h26 + u2 * u6 + v2 * v6, h33 + u3 * u3 + v3 * v3
  h34, h35, h36 = h34 + u3 * fa, h35 + v3 * fb, h36 + u3 * u6 + v3 * v6
  h44, h46, h55, h56 = h44 + fa * fa, h46 + fa * u6, h55 + fb * fb, h56 + fb * v6
  h66, g1, g2 = h66 + u6 * u6 + v6 * v6, g1 + u1 * ru + v1 * rv, g2 + u2 * ru + v2 * rv
  g3, g4, g5, g6 = g3 + u3 * ru + v3 * rv, g4 + fa * ru, g5 + fb * rv, g6 + u6 * ru + v6 * rv
  -- corner 4: Y = -(A + B)
  y1, y2, y3 = -ax - bx, -ay - by, -az - bz
  z = y3 + qz
  if not (z > 0) then return huge end
  iz = 1 / z
  pu, pv = (y1 + qx) * iz, (y2 + qy) * iz
  ru, rv = fx * pu + cx - px[7], fy * pv + cy - px[8]
  s = s + ru * ru + rv * rv
  fa, fb = fx * iz, fy * iz
  u1, u2, u3, u6 = -fa * pu * y2, fa * (y3 + pu * y1), -fa * y2, -fa * pu
  v1, v2, v3, v6 = -fb * (pv * y2 + y3), fb * pv * y1, fb * y1, -fb * pv
  h11, h12, h13 = h11 + u1 * u1 + v1 * v1, h12 + u1 * u2 + v1 * v2, h13 + u1 * u3 + v1 * v3
  h14, h15, h16 = h14 + u1 * fa, h15 + v1 * fb, h16 + u1 * u6 + v1 * v6
  h22, h23, h24 = h22 + u2 * u2 + v2 * v2, h23 + u2 * u3 + v2 * v3, h24 + u2 * fa
  h25, h26, h33 = h25 + v2 * fb, h26 + u2 * u6 + v2 * v6, h33 + u3 * u3 + v3 * v3
  h34, h35, h36 = h34 + u3 * fa, h35 + v3 * fb, h36 + u3 * u6 + v3 * v6
  h44, h46, h55, h56 = h44 + fa * fa, h46 + fa * u6, h55 + fb * fb, h56 + fb * v6
  h66, g1, g2 = h66 + u6 * u6 + v6 * v6, g1 + u1 * ru + v1 * rv, g2 + u2 * ru + v2 * rv
  g3, g4, g5, g6 = g3 + u3 * ru + v3 * rv, g4 + fa * ru, g5 + fb * rv, g6 + u6 * ru + v6 * rv
  N[1], N[2], N[3], N[4], N[5], N[6] = h11, h12, h13, h14, h15, h16
  N[7], N[8], N[9], N[10], N[11] = h22, h23, h24, h25, h26
  N[12], N[13], N[14], N[15], N[16], N[17] = h33, h34, h35, h36, h44, 0
  N[18], N[19], N[20], N[21] = h46, h55, h56, h66
  N[22], N[23], N[24], N[25], N[26], N[27] = g1, g2, g3, g4, g5, g6
  return s
end

-- The normal equations and the cost of the pose Q into N: on LuaJIT always the loop; on PUC
-- Lua the written-out corners for a pinhole, the loop through a lens.
local linearise
if compat.jit then
  linearise = linearise_looped
else
  linearise = function(N, px, C, half, Q)
    if C.lens == 0 then return linearise_unrolled(N, px, C, half, Q) end
    return linearise_looped(N, px, C, half, Q)
  end
end

M.linearise_looped, M.linearise_unrolled = linearise_looped, linearise_unrolled

-- The damped step from the pose P with the normal equations N: writes the trial pose into Q,
-- R ← C(δω) R, t ← t + δt, and returns the damping used, the predicted squared displacement
-- of the corners, and a bound on the squared displacement the step leaves to the next one
-- (`remainder`); nil when no damping up to 1e8 solves.
--
-- The remainder: a step is exact to first order, so the next step from Q is set by what the
-- step's second order moves the corners, about `f (k |δω| + |δt| / z)²` pixels per corner
-- (f the larger focal length, z the centre's depth, k² = side / z: a rotation by |δω| moves a
-- corner off its tangent by about |δω|² times its distance from the centre; a translation
-- bends the projection by (|δt| / z)² times f), squared and summed over the four corners.
local function step(N, lambda, P, Q, C, half)
  local disp, d1, d2, d3, d4, d5, d6
  lambda, disp, d1, d2, d3, d4, d5, d6 = damped_step(N, lambda)
  if not lambda then return nil end
  local c11, c12, c13, c21, c22, c23, c31, c32, c33 = cayley(d1, d2, d3)
  local ax, ay, az, bx, by, bz = P[1], P[2], P[3], P[4], P[5], P[6]
  Q[1], Q[2], Q[3] = c11 * ax + c12 * ay + c13 * az, c21 * ax + c22 * ay + c23 * az,
    c31 * ax + c32 * ay + c33 * az
  Q[4], Q[5], Q[6] = c11 * bx + c12 * by + c13 * bz, c21 * bx + c22 * by + c23 * bz,
    c31 * bx + c32 * by + c33 * bz
  local z = P[9]
  Q[7], Q[8], Q[9] = P[7] + d4, P[8] + d5, z + d6
  local f = C.fx > C.fy and C.fx or C.fy
  local m = sqrt(2 * half / z * (d1 * d1 + d2 * d2 + d3 * d3))
    + sqrt(d4 * d4 + d5 * d5 + d6 * d6) / z
  local e = f * (m * m)
  return lambda, disp, 4 * e * e
end

local normal_a, normal_b = {}, {} -- normal equations, filled by linearise
local pose_p, pose_q = {}, {} -- the refinement's pose and trial pose
local packed = {} -- a camera packed for `normal`

-- H (the normal equations' first 21 numbers) of A into out. (Written out: a loop here would
-- start traces on LuaJIT whose exits carry refine's state.)
local function keep(out, A)
  out[1], out[2], out[3], out[4], out[5], out[6], out[7] = A[1], A[2], A[3], A[4], A[5], A[6],
    A[7]
  out[8], out[9], out[10], out[11], out[12], out[13], out[14] = A[8], A[9], A[10], A[11], A[12],
    A[13], A[14]
  out[15], out[16], out[17], out[18], out[19], out[20], out[21] = A[15], A[16], A[17], A[18],
    A[19], A[20], A[21]
end

--- Refine a candidate pose in place over the four corners.
-- @tparam table C a packed camera (`tagpose.core.lsq.pack`)
-- @tparam {number,...} px observed pixels, flat
-- @tparam number half half the tag side
-- @tparam table cand a candidate record (`tagpose.core.pipeline.candidate`): its `r`, `tx`, `ty`,
--   `tz` are the start and are replaced by the result; `sse` is set to the sum of squared pixel
--   residuals at the result (`math.huge` when the start puts a corner behind the camera, the
--   pose then left as it was) and `linearisations` to the linearisations used
-- @tparam[opt] int max_iterations bound on linearisations (default `MAX_ITERATIONS`)
-- @treturn table cand
function M.refine(C, px, half, cand, max_iterations)
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local floor, relative = 4 * M.STEP_TOLERANCE * M.STEP_TOLERANCE, M.STEP_RELATIVE
  -- the pose P and the trial Q, each as the tag's x and y axes in the camera (columns 1 and 2
  -- of R; column 3 is their cross product) and t; A holds the normal equations at P, B a trial's
  local P, Q, A, B = pose_p, pose_q, normal_a, normal_b
  local r = cand.r
  P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8], P[9] = r[1], r[4], r[7], r[2], r[5], r[8],
    cand.tx, cand.ty, cand.tz
  local sum = linearise(A, px, C, half, P)
  if not (sum < huge) then
    cand.sse, cand.linearisations = huge, 1
    return cand
  end
  -- fresh: no trial was refused since A was computed, so the next trial is linearised at once
  -- (its equations are the next step's if it is taken); after a refusal, trials are costed
  -- only, and the one taken is linearised then
  local k, lambda, fresh = 1, 1e-6, true
  while true do
    local disp, remainder
    lambda, disp, remainder = step(A, lambda, P, Q, C, half)
    if not lambda then break end
    -- last: this step is negligible, or no more linearisations are allowed; or it is the first
    -- step from the start, undamped, and the step it leaves is negligible (from a start near a
    -- minimum Gauss-Newton converges quadratically, so the steps after that one are smaller
    -- still; farther away it may not, and the rule is not used)
    local small = disp < floor + relative * sum or k >= max_iterations
    local last = small or (k == 1 and lambda < 1e-3 and remainder < relative * (sum - disp))
    local s
    if last or not fresh then
      s = residuals(px, C, half, Q)
    else
      k = k + 1
      s = linearise(B, px, C, half, Q)
    end
    if s <= sum then
      for i = 1, 9 do P[i] = Q[i] end
      sum = s
      if last then break end
      if fresh then
        A, B = B, A
      else
        k = k + 1
        linearise(A, px, C, half, P)
      end
      fresh = true
      if lambda > 1e-12 then lambda = lambda * 0.1 end
    else
      -- the trial raised the cost: more damping from the same pose and equations
      if small then break end
      lambda = lambda * 10
      if lambda > 1e8 then break end
      fresh = false
    end
  end
  local ax, ay, az, bx, by, bz = P[1], P[2], P[3], P[4], P[5], P[6]
  r[1], r[4], r[7], r[2], r[5], r[8] = ax, ay, az, bx, by, bz
  r[3], r[6], r[9] = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
  cand.tx, cand.ty, cand.tz, cand.sse, cand.linearisations = P[7], P[8], P[9], sum, k
  -- H of the last linearisation, for the uncertainty (one step before the result when the last
  -- step left a negligible remainder: linearising again would cost a quarter of a solve and
  -- changes no covariance measurably)
  local out = cand.normal
  if out then keep(out, A) end
  return cand
end

--- The normal equations of a pose over the four corners, without refining it (the report's
-- method's pose, for its covariance).
-- @tparam table camera a checked camera
-- @tparam {number,...} px observed pixels, flat
-- @tparam number half half the tag side
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam {number,...} out 27 numbers to fill (`tagpose.core.lsq`'s layout)
-- @treturn number the sum of squared pixel residuals (`math.huge` when a corner is behind the
--   camera)
function M.normal(camera, px, half, r, tx, ty, tz, out)
  local Q = pose_q
  Q[1], Q[2], Q[3], Q[4], Q[5], Q[6], Q[7], Q[8], Q[9] = r[1], r[4], r[7], r[2], r[5], r[8], tx,
    ty, tz
  return linearise_looped(out, px, lsq.pack(camera, packed), half, Q)
end

--- The start of the other local minimum: the pose with the tag's normal reflected about the
-- line of sight to its centre.
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam {number,...} out flat rotation to fill (may not be `r`)
-- @treturn {number,...} out
function M.mirror(r, tx, ty, tz, out)
  local n = sqrt(tx * tx + ty * ty + tz * tz)
  local v1, v2, v3 = tx / n, ty / n, tz / n
  for col = 1, 3 do
    local a, b, c = r[col], r[3 + col], r[6 + col]
    local s = 2 * (v1 * a + v2 * b + v3 * c)
    local sign = col == 3 and -1 or 1
    out[col] = sign * (a - s * v1)
    out[3 + col] = sign * (b - s * v2)
    out[6 + col] = sign * (c - s * v3)
  end
  return out
end

return M
