--- The pose of a rigid body from the pixels of known points on it: Levenberg-Marquardt over the
-- six pose parameters, optionally with one of the body's axes held near a known direction.
--
-- It minimises the sum of squared pixel distances between the observed points and the
-- projections (through the camera's lens model) of the body points `P_k`, placed in the camera
-- by `X = R·P_k + t`, plus two optional priors: `w²·|R·a × u|²`, the body axis `a` held near
-- the camera-frame direction `u` (`w` in pixels per radian of misalignment), and
-- `v²·(n·t - d)²`, the body origin held near the plane `n·X = d` (`v` in pixels per unit of
-- length). As in
-- `tagpose.core.refine`, the rotation is updated on the left by the Cayley transform of a rotation
-- vector and the normal equations are accumulated point by point:
--
--     r = (u(R, t) - u_obs, v(R, t) - v_obs),   ∂r/∂t = e,   ∂r/∂ω = Y × e,   Y = R·P_k
--
-- with `e` the row of ∂pixel/∂X at the point. It stops when a step moves the projected points by
-- a negligible amount (`STEP_RELATIVE`, `STEP_TOLERANCE`) or after `max_iterations`
-- linearisations.
--
-- Rotations are flat, row-major 3×3 (body → camera); body points are flat
-- `{x1, y1, z1, x2, ...}` in the body frame; pixels are flat `{u1, v1, u2, v2, ...}`; the
-- camera is packed (`tagpose.core.lsq.pack`); the kernels are `tagpose.core.lsq`'s.
-- @module tagpose.rigid

local lsq = require("tagpose.core.lsq")

local huge = math.huge
local damped_step, turn, residual = lsq.damped_step, lsq.turn, lsq.residual

local M = {}

--- Default bound on the linearisations of one fit.
M.MAX_ITERATIONS = 20
--- A step ends the fit when the squared displacement it gives the projected points is below
-- `STEP_RELATIVE` times the cost...
M.STEP_RELATIVE = 1e-3
--- ... or below `STEP_TOLERANCE`² (px²) per point (exact data).
M.STEP_TOLERANCE = 1e-5

--- A prior record for `fit`, both priors off: fill its fields to use them.
-- `axis_x, axis_y, axis_z`: the unit body axis `a`; `up_x, up_y, up_z`: the unit camera
-- direction `u` it is held near; `axis_weight`: `w`, px per radian (0: off).
-- `normal_x, normal_y, normal_z`: the plane's unit normal `n` (camera frame); `level`: `d`;
-- `plane_weight`: `v`, px per unit of length (0: off).
-- @treturn table
function M.prior()
  return { axis_x = 0, axis_y = 0, axis_z = 0, up_x = 0, up_y = 0, up_z = 0, axis_weight = 0,
    normal_x = 0, normal_y = 0, normal_z = 0, level = 0, plane_weight = 0 }
end

local NO_PRIOR = M.prior()

-- Sum of squared pixel residuals of points first..last at the pose Q = {r (9), t (3)}, without
-- the prior; math.huge when a point is not in front of the camera.
local function residuals(C, Q, points, px, first, last)
  local sum = 0
  for k = first, last do
    -- (the pose is read from Q inside the loop: with it in locals LuaJIT cannot compile the
    -- loop's exits)
    local b = 3 * k
    local a1, a2, a3 = points[b - 2], points[b - 1], points[b]
    local du, dv = residual(C, Q[1] * a1 + Q[2] * a2 + Q[3] * a3 + Q[10],
      Q[4] * a1 + Q[5] * a2 + Q[6] * a3 + Q[11], Q[7] * a1 + Q[8] * a2 + Q[9] * a3 + Q[12],
      px[2 * k - 1], px[2 * k])
    sum = sum + du * du + dv * dv
  end
  return sum
end

-- The priors' cost w²·|R·a × u|² + v²·(n·t - d)² at the pose Q.
local function prior_cost(pr, Q)
  local sum = 0
  local w = pr.axis_weight
  if w > 0 then
    local b1, b2, b3, u1, u2, u3 = pr.axis_x, pr.axis_y, pr.axis_z, pr.up_x, pr.up_y, pr.up_z
    local a1 = Q[1] * b1 + Q[2] * b2 + Q[3] * b3
    local a2 = Q[4] * b1 + Q[5] * b2 + Q[6] * b3
    local a3 = Q[7] * b1 + Q[8] * b2 + Q[9] * b3
    local e1, e2, e3 = a2 * u3 - a3 * u2, a3 * u1 - a1 * u3, a1 * u2 - a2 * u1
    sum = w * w * (e1 * e1 + e2 * e2 + e3 * e3)
  end
  local v = pr.plane_weight
  if v > 0 then
    local e = v * (pr.normal_x * Q[10] + pr.normal_y * Q[11] + pr.normal_z * Q[12] - pr.level)
    sum = sum + e * e
  end
  return sum
end

-- The normal equations of the pose Q accumulated into N (`tagpose.core.lsq`'s layout), and the cost
-- (math.huge when a point is not in front of the camera).
local function linearise(N, C, pr, Q, points, px, n)
  local s = lsq.points(N, C, Q, Q[10], Q[11], Q[12], points, px, n)
  if not (s < huge) then return huge end
  local w = pr.axis_weight
  if w > 0 then
    -- the prior e = w·(A × u), A = R·a: ∂e/∂ω = w·(A uᵀ - (A·u) I); rows j = 1..3 of it
    local b1, b2, b3, u1, u2, u3 = pr.axis_x, pr.axis_y, pr.axis_z, pr.up_x, pr.up_y, pr.up_z
    local A1, A2, A3 = Q[1] * b1 + Q[2] * b2 + Q[3] * b3, Q[4] * b1 + Q[5] * b2 + Q[6] * b3,
      Q[7] * b1 + Q[8] * b2 + Q[9] * b3
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
  local v = pr.plane_weight
  if v > 0 then
    -- the plane prior e = v·(n·t - d): ∂e/∂t = v·n
    local n1, n2, n3 = v * pr.normal_x, v * pr.normal_y, v * pr.normal_z
    local e = n1 * Q[10] + n2 * Q[11] + n3 * Q[12] - v * pr.level
    s = s + e * e
    N[16], N[17], N[18] = N[16] + n1 * n1, N[17] + n1 * n2, N[18] + n1 * n3
    N[19], N[20], N[21] = N[19] + n2 * n2, N[20] + n2 * n3, N[21] + n3 * n3
    N[25], N[26], N[27] = N[25] + n1 * e, N[26] + n2 * e, N[27] + n3 * e
  end
  return s
end

-- The damped step from the pose P (`lsq.damped_step`, `lsq.turn`): writes the trial pose
-- into Q, R ← C(δω)·R, t ← t + δt, and returns the damping used and the predicted squared
-- displacement of the points; nil when no damping up to 1e8 solves.
local function step(N, lambda, P, Q)
  local disp, d1, d2, d3, d4, d5, d6
  lambda, disp, d1, d2, d3, d4, d5, d6 = damped_step(N, lambda)
  if not lambda then return nil end
  turn(d1, d2, d3, P, Q)
  Q[10], Q[11], Q[12] = P[10] + d4, P[11] + d5, P[12] + d6
  return lambda, disp
end

local N = {} -- the normal equations
local pose_p, pose_q = {}, {} -- the pose and the trial pose: r (9), t (3)

--- Fit the pose of a rigid body to the pixels of its points, in place.
-- @tparam table C a packed camera (`tagpose.core.lsq.pack`)
-- @tparam {number,...} points body points, flat `{x1, y1, z1, ...}`
-- @tparam {number,...} px their observed pixels, flat `{u1, v1, ...}`
-- @tparam int n number of points (at least 3, not all on one line through the camera)
-- @tparam table body the pose `{r = flat body → camera rotation, tx =, ty =, tz =}` (the body
--   origin in the camera frame): the start, replaced by the result; `cost` is set to the sum
--   of squared pixel residuals plus the priors' terms (`math.huge` when the start puts a point
--   behind the camera, the pose then left as it was) and `linearisations` to the
--   linearisations used
-- @tparam[opt] int max_iterations bound on linearisations (default `MAX_ITERATIONS`)
-- @tparam[opt] table prior a `prior()` record: hold the unit body axis near a camera
--   direction, and the body origin near a plane
-- @treturn table body
function M.fit(C, points, px, n, body, max_iterations, prior)
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local pr = prior or NO_PRIOR
  local floor, relative = n * M.STEP_TOLERANCE * M.STEP_TOLERANCE, M.STEP_RELATIVE
  local P, Q = pose_p, pose_q
  local r = body.r
  for i = 1, 9 do Q[i] = r[i] end
  Q[10], Q[11], Q[12] = body.tx, body.ty, body.tz
  for i = 1, 12 do P[i] = Q[i] end
  local lambda, k, sum, retry = 1e-6, 0, huge, false
  while k < max_iterations do
    k = k + 1
    local s = linearise(N, C, pr, Q, points, px, n)
    if k == 1 and not (s < huge) then
      body.cost, body.linearisations = huge, k
      return body
    end
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
        if c < huge then c = c + prior_cost(pr, Q) end
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
  body.tx, body.ty, body.tz, body.cost, body.linearisations = P[10], P[11], P[12], sum, k
  return body
end

local cost_pose = {}

--- Sum of squared pixel residuals of some of the points at a pose (no prior).
-- @tparam table C a packed camera
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
function M.cost(C, points, px, first, last, r, tx, ty, tz)
  local Q = cost_pose
  for i = 1, 9 do Q[i] = r[i] end
  Q[10], Q[11], Q[12] = tx, ty, tz
  return residuals(C, Q, points, px, first, last)
end


local normal_pose = {}

--- The normal equations of a pose (pixels and priors, no σ), for its covariance.
-- @tparam table C a packed camera
-- @tparam {number,...} points body points, flat
-- @tparam {number,...} px observed pixels, flat
-- @tparam int n number of points
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam[opt] table prior a `prior()` record
-- @tparam {number,...} out filled with `tagpose.core.lsq`'s layout (H in its first 21 numbers)
-- @treturn number the cost at the pose, priors included (`math.huge` when a point is not in
--   front of the camera)
function M.normal(C, points, px, n, r, tx, ty, tz, prior, out)
  local Q = normal_pose
  for i = 1, 9 do Q[i] = r[i] end
  Q[10], Q[11], Q[12] = tx, ty, tz
  return linearise(out, C, prior or NO_PRIOR, Q, points, px, n)
end

return M
