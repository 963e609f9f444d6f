--- The joint fit of a rigid set of points through the lens, on flat arrays: the kernel under
-- `tagpose.layout.solve` (and, in time, under `tagpose.block`'s hypotheses).
--
-- `fit` is `tagpose.layout.rigid.fit` (Levenberg-Marquardt over the six pose parameters, the
-- rotation updated on the left by the Cayley transform of a rotation vector, with the optional
-- axis and plane priors) followed by one linearisation at the result, so that the caller gets
-- the final normal equations for the covariance and the confidence. The normal equations are
-- packed as `tagpose.core.refine` packs them, pixel terms only (no prior):
--
--     N[1..21]   the upper triangle of JᵀJ over (δω, δt), row by row
--     N[22..27]  the gradient Jᵀr
--
-- in pixel units, δω a small left rotation vector in the camera frame and δt the move of the
-- body origin in the camera frame (`tagpose.uncertainty.from_normal` turns them into the 6×6
-- covariance, ordered (x, y, z, rx, ry, rz) as ROS `PoseWithCovariance`).
--
-- Rotations are flat, row-major 3×3 (body → camera); body points are flat `{x1, y1, z1, ...}`;
-- pixels are flat `{u1, v1, u2, v2, ...}`.
-- @module tagpose.layout.fit

local lsq = require("tagpose.core.lsq")
local rigid = require("tagpose.layout.rigid")

local huge = math.huge


local M = {}

local K = {} -- the camera, packed for the kernels
local body = { r = nil } -- the pose under way

local function constants(camera)
  return lsq.pack(camera, K)
end

--- The normal equations of a pose over points 1..n (pixel terms only).
-- @tparam table camera a checked camera
-- @tparam {number,...} points body points, flat
-- @tparam {number,...} px observed pixels, flat
-- @tparam int n number of points
-- @tparam {number,...} r flat body → camera rotation
-- @tparam number tx the body origin in the camera frame
-- @tparam number ty
-- @tparam number tz
-- @tparam {number,...} N array to fill with the 27 numbers of the module's header
-- @treturn number the sum of squared pixel residuals (`math.huge` when a point is not in
--   front of the camera; N is then incomplete)
function M.normal(camera, points, px, n, r, tx, ty, tz, N)
  return lsq.points(N, constants(camera), r, tx, ty, tz, points, px, n)
end

--- Fit the pose of a rigid set of points to their pixels, in place.
-- @tparam table camera a checked camera
-- @tparam {number,...} points body points, flat `{x1, y1, z1, ...}`
-- @tparam {number,...} px their observed pixels, flat `{u1, v1, ...}`
-- @tparam int n number of points (at least 3, not all on one line through the camera)
-- @tparam {number,...} r flat body → camera rotation: the start, replaced by the result
-- @tparam number tx start translation (the body origin in the camera frame)
-- @tparam number ty
-- @tparam number tz
-- @tparam[opt] int max_iterations bound on linearisations (default `tagpose.layout.rigid`'s)
-- @tparam[opt] {number,...} prior the priors of `tagpose.layout.rigid.fit`
-- @tparam[opt] {number,...} N when given, filled with the normal equations at the result
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @treturn number the cost at the result (squared pixel residuals plus the priors' terms;
--   `math.huge` when the start puts a point behind the camera)
-- @treturn int linearisations used
-- @treturn number the sum of squared pixel residuals alone at the result
function M.fit(camera, points, px, n, r, tx, ty, tz, max_iterations, prior, N)
  local C = constants(camera)
  body.r, body.tx, body.ty, body.tz = r, tx, ty, tz
  rigid.fit(C, points, px, n, body, max_iterations, prior)
  local cost, k = body.cost, body.linearisations
  tx, ty, tz = body.tx, body.ty, body.tz
  if not (cost < huge) then return tx, ty, tz, huge, k, huge end
  local sse
  if N then
    sse = M.normal(camera, points, px, n, r, tx, ty, tz, N)
  else
    sse = rigid.cost(C, points, px, 1, n, r, tx, ty, tz)
  end
  return tx, ty, tz, cost, k, sse
end

--- Sum of squared pixel residuals of points first..last at a pose (`tagpose.layout.rigid.cost`).
-- @tparam table camera a checked camera
-- @tparam {number,...} points body points, flat
-- @tparam {number,...} px observed pixels, flat
-- @tparam int first first point
-- @tparam int last last point
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @treturn number
function M.cost(camera, points, px, first, last, r, tx, ty, tz)
  return rigid.cost(constants(camera), points, px, first, last, r, tx, ty, tz)
end

return M
