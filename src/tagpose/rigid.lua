--- The pose of a rigid body from the pixels of known points on it: Levenberg-Marquardt over the
-- six pose parameters, optionally with one of the body's axes held near a known direction.
--
-- It minimises the sum of squared pixel distances between the observed points and the
-- projections (through the camera's lens model) of the body points `P_k`, placed in the camera
-- by `X = R·P_k + t`, plus two optional priors: `w²·|R·a × u|²`, the body axis `a` held near
-- the camera-frame direction `u` (`w` in pixels per radian of misalignment), and
-- `v²·(n·t - d)²`, the body origin held near the plane `n·X = d` (`v` in pixels per unit of
-- length). As in
-- `tagpose.refine`, the rotation is updated on the left by the Cayley transform of a rotation
-- vector and the normal equations are accumulated point by point:
--
--     r = (u(R, t) - u_obs, v(R, t) - v_obs),   ∂r/∂t = e,   ∂r/∂ω = Y × e,   Y = R·P_k
--
-- with `e` the row of ∂pixel/∂X at the point. It stops when a step moves the projected points by
-- a negligible amount (`STEP_RELATIVE`, `STEP_TOLERANCE`) or after `max_iterations`
-- linearisations.
--
-- Rotations are flat, row-major 3×3 (body → camera); body points are flat
-- `{x1, y1, z1, x2, ...}` in the body frame; pixels are flat `{u1, v1, u2, v2, ...}`.
-- @module tagpose.rigid

local camera_model = require("tagpose.camera")
local refine = require("tagpose.refine")

local huge = math.huge
local lens, brown, fisheye = camera_model.lens, camera_model.brown, camera_model.fisheye
local accumulate, damped_step, cayley = refine.accumulate, refine.damped_step, refine.cayley

local M = {}

--- Default bound on the linearisations of one fit.
M.MAX_ITERATIONS = 20
--- A step ends the fit when the squared displacement it gives the projected points is below
-- `STEP_RELATIVE` times the cost...
M.STEP_RELATIVE = 1e-3
--- ... or below `STEP_TOLERANCE`² (px²) per point (exact data).
M.STEP_TOLERANCE = 1e-5

-- constants of a fit, packed as `tagpose.refine` packs a camera (its `accumulate` reads them):
-- fx, fy, cx, cy, an unused slot, the lens kind and its 8 coefficients (see camera.lens), then
-- the axis prior: a (body, 15-17), u (camera, 18-20), w (21), then the plane prior: n (22-24),
-- d (25), v (26)
local K = {}

local function constants(camera, prior)
  K[1], K[2], K[3], K[4], K[5] = camera.fx, camera.fy, camera.cx, camera.cy, 0
  K[6], K[7], K[8], K[9], K[10], K[11], K[12], K[13], K[14] = lens(camera)
  for i = 7, 14 do
    if K[i] == nil then K[i] = 0 end
  end
  K[21], K[26] = 0, 0
  if prior then
    if prior[7] > 0 then
      for i = 1, 7 do K[14 + i] = prior[i] end
    end
    local v = prior[12]
    if v and v > 0 then
      for i = 8, 12 do K[14 + i] = prior[i] end
    end
  end
  return K
end

-- Sum of squared pixel residuals of points first..last at the pose Q = {r (9), t (3)}, without
-- the prior; math.huge when a point is not in front of the camera.
local function residuals(C, Q, points, px, first, last)
  local kind = C[6]
  local sum = 0
  for k = first, last do
    -- (the pose is read from Q inside the loop: with it in locals LuaJIT cannot compile the
    -- loop's exits)
    local b = 3 * k
    local a1, a2, a3 = points[b - 2], points[b - 1], points[b]
    local z = Q[7] * a1 + Q[8] * a2 + Q[9] * a3 + Q[12]
    if not (z > 0) then return huge end
    local pu = (Q[1] * a1 + Q[2] * a2 + Q[3] * a3 + Q[10]) / z
    local pv = (Q[4] * a1 + Q[5] * a2 + Q[6] * a3 + Q[11]) / z
    if kind == 1 then
      pu, pv = brown(pu, pv, C[7], C[8], C[9], C[10], C[11], C[12], C[13], C[14])
    elseif kind == 2 then
      pu, pv = fisheye(pu, pv, C[7], C[8], C[9], C[10])
    end
    local du, dv = C[1] * pu + C[3] - px[2 * k - 1], C[2] * pv + C[4] - px[2 * k]
    sum = sum + du * du + dv * dv
  end
  return sum
end

-- The priors' cost w²·|R·a × u|² + v²·(n·t - d)² at the pose Q.
local function prior_cost(C, Q)
  local sum = 0
  local w = C[21]
  if w > 0 then
    local b1, b2, b3, u1, u2, u3 = C[15], C[16], C[17], C[18], C[19], C[20]
    local a1 = Q[1] * b1 + Q[2] * b2 + Q[3] * b3
    local a2 = Q[4] * b1 + Q[5] * b2 + Q[6] * b3
    local a3 = Q[7] * b1 + Q[8] * b2 + Q[9] * b3
    local e1, e2, e3 = a2 * u3 - a3 * u2, a3 * u1 - a1 * u3, a1 * u2 - a2 * u1
    sum = w * w * (e1 * e1 + e2 * e2 + e3 * e3)
  end
  local v = C[26]
  if v > 0 then
    local e = v * (C[22] * Q[10] + C[23] * Q[11] + C[24] * Q[12] - C[25])
    sum = sum + e * e
  end
  return sum
end

-- The normal equations of the pose Q accumulated into N as {h11, ..., h16, h22, ..., h66,
-- g1, ..., g6} (upper triangle row by row, then the gradient), and the cost (math.huge when a
-- point is not in front of the camera).
local function linearise(N, C, Q, points, px, n)
  local r1, r2, r3, r4, r5, r6, r7, r8, r9 = Q[1], Q[2], Q[3], Q[4], Q[5], Q[6], Q[7], Q[8], Q[9]
  local tx, ty, tz = Q[10], Q[11], Q[12]
  for k = 1, 27 do N[k] = 0 end
  local s = 0
  for k = 1, n do
    local b = 3 * k
    local a1, a2, a3 = points[b - 2], points[b - 1], points[b]
    -- the point relative to the body origin (Y), in the camera frame
    s = s + accumulate(N, C, r1 * a1 + r2 * a2 + r3 * a3, r4 * a1 + r5 * a2 + r6 * a3,
      r7 * a1 + r8 * a2 + r9 * a3, tx, ty, tz, px[2 * k - 1], px[2 * k])
    if not (s < huge) then return huge end
  end
  local w = C[21]
  if w > 0 then
    -- the prior e = w·(A × u), A = R·a: ∂e/∂ω = w·(A uᵀ - (A·u) I); rows j = 1..3 of it
    local b1, b2, b3, u1, u2, u3 = C[15], C[16], C[17], C[18], C[19], C[20]
    local A1, A2, A3 = r1 * b1 + r2 * b2 + r3 * b3, r4 * b1 + r5 * b2 + r6 * b3,
      r7 * b1 + r8 * b2 + r9 * b3
    local d = A1 * u1 + A2 * u2 + A3 * u3
    local e1, e2, e3 = w * (A2 * u3 - A3 * u2), w * (A3 * u1 - A1 * u3), w * (A1 * u2 - A2 * u1)
    s = s + e1 * e1 + e2 * e2 + e3 * e3
    for row = 1, 3 do
      local Ar, er = A1, e1
      if row == 2 then Ar, er = A2, e2 elseif row == 3 then Ar, er = A3, e3 end
      local j1, j2, j3 = w * Ar * u1, w * Ar * u2, w * Ar * u3
      if row == 1 then j1 = j1 - w * d elseif row == 2 then j2 = j2 - w * d else j3 = j3 - w * d end
      N[1], N[2], N[3] = N[1] + j1 * j1, N[2] + j1 * j2, N[3] + j1 * j3
      N[7], N[8], N[12] = N[7] + j2 * j2, N[8] + j2 * j3, N[12] + j3 * j3
      N[22], N[23], N[24] = N[22] + j1 * er, N[23] + j2 * er, N[24] + j3 * er
    end
  end
  local v = C[26]
  if v > 0 then
    -- the plane prior e = v·(n·t - d): ∂e/∂t = v·n
    local n1, n2, n3 = v * C[22], v * C[23], v * C[24]
    local e = n1 * tx + n2 * ty + n3 * tz - v * C[25]
    s = s + e * e
    N[16], N[17], N[18] = N[16] + n1 * n1, N[17] + n1 * n2, N[18] + n1 * n3
    N[19], N[20], N[21] = N[19] + n2 * n2, N[20] + n2 * n3, N[21] + n3 * n3
    N[25], N[26], N[27] = N[25] + n1 * e, N[26] + n2 * e, N[27] + n3 * e
  end
  return s
end

-- The damped step from the pose P (`refine.damped_step`, `refine.cayley`): writes the trial
-- pose into Q, R ← C(δω)·R, t ← t + δt, and returns the damping used and the predicted squared
-- displacement of the points; nil when no damping up to 1e8 solves.
local function step(N, lambda, P, Q)
  local disp, d1, d2, d3, d4, d5, d6
  lambda, disp, d1, d2, d3, d4, d5, d6 = damped_step(N, lambda)
  if not lambda then return nil end
  local c11, c12, c13, c21, c22, c23, c31, c32, c33 = cayley(d1, d2, d3)
  for j = 1, 3 do
    local a, b, c = P[j], P[3 + j], P[6 + j]
    Q[j] = c11 * a + c12 * b + c13 * c
    Q[3 + j] = c21 * a + c22 * b + c23 * c
    Q[6 + j] = c31 * a + c32 * b + c33 * c
  end
  Q[10], Q[11], Q[12] = P[10] + d4, P[11] + d5, P[12] + d6
  return lambda, disp
end

local N = {} -- the normal equations
local pose_p, pose_q = {}, {} -- the pose and the trial pose: r (9), t (3)

--- Fit the pose of a rigid body to the pixels of its points, in place.
-- @tparam table camera a checked camera
-- @tparam {number,...} points body points, flat `{x1, y1, z1, ...}`
-- @tparam {number,...} px their observed pixels, flat `{u1, v1, ...}`
-- @tparam int n number of points (at least 3, not all on one line through the camera)
-- @tparam {number,...} r flat body → camera rotation: the start, replaced by the result
-- @tparam number tx start translation (the body origin in the camera frame)
-- @tparam number ty
-- @tparam number tz
-- @tparam[opt] int max_iterations bound on linearisations (default `MAX_ITERATIONS`)
-- @tparam[opt] {number,...} prior `{ax, ay, az, ux, uy, uz, w, nx, ny, nz, d, v}`: hold the
--   unit body axis `a` near the unit camera direction `u`, with weight `w` (px per radian), and
--   the body origin near the plane `n·X = d` (`n` unit, camera frame), with weight `v` (px per
--   unit of length); a weight of 0 (or a missing `v`) leaves that prior out
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @treturn number the cost at the result: the sum of squared pixel residuals (plus the priors'
--   terms); `math.huge` when the start puts a point behind the camera
-- @treturn int linearisations used
function M.fit(camera, points, px, n, r, tx, ty, tz, max_iterations, prior)
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local C = constants(camera, prior)
  local floor, relative = n * M.STEP_TOLERANCE * M.STEP_TOLERANCE, M.STEP_RELATIVE
  local P, Q = pose_p, pose_q
  for i = 1, 9 do Q[i] = r[i] end
  Q[10], Q[11], Q[12] = tx, ty, tz
  for i = 1, 12 do P[i] = Q[i] end
  local lambda, k, sum, retry = 1e-6, 0, huge, false
  while k < max_iterations do
    k = k + 1
    local s = linearise(N, C, Q, points, px, n)
    if k == 1 and not (s < huge) then return tx, ty, tz, huge, k end
    if s <= sum or retry then
      for i = 1, 12 do P[i] = Q[i] end
      sum = s
      if k > 1 and not retry and lambda > 1e-12 then lambda = lambda * 0.1 end
      retry = false
      local disp
      lambda, disp = step(N, lambda, P, Q)
      if not lambda then break end
      if disp < floor + relative * sum or k >= max_iterations then
        local c = residuals(C, Q, points, px, 1, n)
        if c < huge then c = c + prior_cost(C, Q) end
        if c <= sum then
          for i = 1, 12 do P[i] = Q[i] end
          sum = c
        end
        break
      end
    else
      lambda = lambda * 10
      if lambda > 1e8 then break end
      for i = 1, 12 do Q[i] = P[i] end
      retry = true
    end
  end
  for i = 1, 9 do r[i] = P[i] end
  return P[10], P[11], P[12], sum, k
end

local cost_pose = {}

--- Sum of squared pixel residuals of some of the points at a pose (no prior).
-- @tparam table camera a checked camera
-- @tparam {number,...} points body points, flat
-- @tparam {number,...} px observed pixels, flat
-- @tparam int first first point
-- @tparam int last last point
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @treturn number the sum over points `first..last` of the squared pixel distance
--   (`math.huge` when one is not in front of the camera)
function M.cost(camera, points, px, first, last, r, tx, ty, tz)
  local Q = cost_pose
  for i = 1, 9 do Q[i] = r[i] end
  Q[10], Q[11], Q[12] = tx, ty, tz
  return residuals(constants(camera, nil), Q, points, px, first, last)
end

return M
