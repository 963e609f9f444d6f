--- The joint fit of a rigid set of points through the lens, on flat arrays: the kernel under
-- `tagpose.layout.solve` (and, in time, under `tagpose.block`'s hypotheses).
--
-- `fit` is `tagpose.rigid.fit` (Levenberg-Marquardt over the six pose parameters, the
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
-- Without priors the iterations run about the points' centroid (the body origin moved there
-- while fitting, put back after): a body whose origin is far from its tags — a field map's
-- corner, metres from the tags a camera sees — then has no curved valley between the
-- rotation and the translation, and the fit converges to the minimum in a few steps instead
-- of stopping short of it. The normal equations are those of the body origin, as before.
--
-- Rotations are flat, row-major 3×3 (body → camera); body points are flat `{x1, y1, z1, ...}`;
-- pixels are flat `{u1, v1, u2, v2, ...}`.
-- @module tagpose.layout.fit

local lsq = require("tagpose.core.lsq")
local rigid = require("tagpose.rigid")

local huge = math.huge


local M = {}

local K = {} -- the camera, packed for the kernels
local body = { r = nil } -- the pose under way
local centred = {} -- the points about their centroid

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
-- @tparam[opt] int max_iterations bound on linearisations (default `tagpose.rigid`'s)
-- @tparam[opt] {number,...} prior the priors of `tagpose.rigid.fit` (with priors the
--   iterations run about the body origin, whose translation the plane prior holds)
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
  local gx, gy, gz, fitted = 0, 0, 0, points
  if not prior then
    -- about the points' centroid g: X = R·(P - g) + (t + R·g)
    for k = 1, 3 * n, 3 do
      gx, gy, gz = gx + points[k], gy + points[k + 1], gz + points[k + 2]
    end
    gx, gy, gz = gx / n, gy / n, gz / n
    fitted = centred
    for k = 1, 3 * n, 3 do
      fitted[k], fitted[k + 1], fitted[k + 2] = points[k] - gx, points[k + 1] - gy,
        points[k + 2] - gz
    end
  end
  body.r = r
  body.tx = tx + r[1] * gx + r[2] * gy + r[3] * gz
  body.ty = ty + r[4] * gx + r[5] * gy + r[6] * gz
  body.tz = tz + r[7] * gx + r[8] * gy + r[9] * gz
  rigid.fit(C, fitted, px, n, body, max_iterations, prior)
  local cost, k = body.cost, body.linearisations
  tx = body.tx - (r[1] * gx + r[2] * gy + r[3] * gz)
  ty = body.ty - (r[4] * gx + r[5] * gy + r[6] * gz)
  tz = body.tz - (r[7] * gx + r[8] * gy + r[9] * gz)
  if not (cost < huge) then return tx, ty, tz, huge, k, huge end
  local sse
  if N then
    sse = M.normal(camera, points, px, n, r, tx, ty, tz, N)
  else
    sse = rigid.cost(C, points, px, 1, n, r, tx, ty, tz)
  end
  return tx, ty, tz, cost, k, sse
end

--- Sum of squared pixel residuals of points first..last at a pose (`tagpose.rigid.cost`).
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
