--- Refinement of a tag pose over all four corners, and the second pose of the planar ambiguity.
--
-- `refine` minimises the sum of squared pixel distances between the four observed corners and
-- the projected tag corners over the six pose parameters, by Levenberg-Marquardt: the rotation
-- is updated on the left by a rotation vector, `R ← exp([ω]×) R`, the translation additively,
-- so the parametrisation is minimal and has no singularity. It stops when a step moves the
-- projected corners by less than `STEP_TOLERANCE` px (RMS), or after `MAX_ITERATIONS`
-- linearisations.
--
-- `mirror` gives the start of the other local minimum: a square seen in perspective has two
-- poses that project almost alike, one with its normal reflected about the line of sight
-- (IPPE, Schweighofer-Pinz). With `v` the unit line of sight to the tag centre, the mirrored
-- pose keeps the centre and takes `R' = (I - 2 v vᵀ) R diag(1, 1, -1)`.
--
-- Poses are a flat rotation `r` (row-major, tag → camera) and `tx, ty, tz`; pixels are flat
-- `{u1, v1, ..., u4, v4}`; `half` is half the tag side.
-- @module tagpose.refine

local rotation = require("tagpose.rotation")
local linsolve = require("tagpose.linsolve")

local sqrt = math.sqrt
local huge = math.huge

local M = {}

--- Bound on the linearisations (Jacobian evaluations) of one refinement.
M.MAX_ITERATIONS = 20
--- A step that moves the projected corners by less than this (px, RMS) ends the refinement.
M.STEP_TOLERANCE = 1e-7

local CX = { -1, 1, 1, -1 }
local CY = { 1, 1, -1, -1 }

-- scratch
local H = {} -- 6x6 normal matrix, flat
local A = {} -- damped copy, factorised in place
local g = {} -- gradient J^T r
local d = {} -- step
local j = {} -- one Jacobian row
local trial = {} -- trial rotation
local inc = {} -- rotation increment

-- Sum of squared pixel residuals at the pose; when `normal` is true, also fills H and g.
-- Returns math.huge when a corner is not in front of the camera.
local function evaluate(camera, px, half, r, tx, ty, tz, normal)
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  if normal then
    for k = 1, 36 do H[k] = 0 end
    for k = 1, 6 do g[k] = 0 end
  end
  local cost = 0
  for i = 1, 4 do
    local a, b = CX[i] * half, CY[i] * half
    -- corner relative to the tag centre, in the camera frame, and its position
    local y1, y2, y3 = r[1] * a + r[2] * b, r[4] * a + r[5] * b, r[7] * a + r[8] * b
    local x1, x2, x3 = y1 + tx, y2 + ty, y3 + tz
    if not (x3 > 0) then return huge end
    local iz = 1 / x3
    local pu, pv = x1 * iz, x2 * iz
    local ru = fx * pu + cx - px[2 * i - 1]
    local rv = fy * pv + cy - px[2 * i]
    cost = cost + ru * ru + rv * rv
    if normal then
      for row = 1, 2 do
        -- d(residual)/dX for this row, then d/dω = Y × that, d/dt = that
        local e1, e2, e3, res
        if row == 1 then
          e1, e2, e3, res = fx * iz, 0, -fx * pu * iz, ru
        else
          e1, e2, e3, res = 0, fy * iz, -fy * pv * iz, rv
        end
        j[1] = y2 * e3 - y3 * e2
        j[2] = y3 * e1 - y1 * e3
        j[3] = y1 * e2 - y2 * e1
        j[4], j[5], j[6] = e1, e2, e3
        for p = 1, 6 do
          local jp = j[p]
          g[p] = g[p] + jp * res
          local base = (p - 1) * 6
          for q = p, 6 do
            H[base + q] = H[base + q] + jp * j[q]
          end
        end
      end
    end
  end
  return cost
end

--- Refine a pose in place over the four corners.
-- @tparam table camera a checked camera
-- @tparam {number,...} px observed pixels, flat
-- @tparam number half half the tag side
-- @tparam {number,...} r flat rotation: the start, replaced by the result
-- @tparam number tx start translation
-- @tparam number ty
-- @tparam number tz
-- @tparam[opt] int max_iterations bound on linearisations (default `MAX_ITERATIONS`)
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @treturn number the sum of squared pixel residuals at the result
-- @treturn int linearisations used
function M.refine(camera, px, half, r, tx, ty, tz, max_iterations)
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local lambda = 1e-6
  local cost = evaluate(camera, px, half, r, tx, ty, tz, false)
  if not (cost < huge) then return tx, ty, tz, cost, 0 end
  local k = 0
  while k < max_iterations do
    k = k + 1
    cost = evaluate(camera, px, half, r, tx, ty, tz, true)
    local accepted, small = false, false
    while not accepted do
      for p = 1, 6 do
        local base = (p - 1) * 6
        for q = p, 6 do
          A[base + q] = H[base + q]
          A[(q - 1) * 6 + p] = H[base + q]
        end
        A[base + p] = H[base + p] * (1 + lambda)
        d[p] = -g[p]
      end
      if linsolve.cholesky(6, A, d) then
        -- predicted RMS displacement of the corners: sqrt(dᵀ H d / 4)
        local disp = 0
        for p = 1, 6 do
          local base, s = (p - 1) * 6, H[(p - 1) * 6 + p] * d[p]
          for q = p + 1, 6 do
            s = s + 2 * H[base + q] * d[q]
          end
          disp = disp + d[p] * s
        end
        small = disp < 4 * M.STEP_TOLERANCE * M.STEP_TOLERANCE
        rotation.from_rotation_vector(d[1], d[2], d[3], inc)
        rotation.multiply(inc, r, trial)
        local nx, ny, nz = tx + d[4], ty + d[5], tz + d[6]
        local c = evaluate(camera, px, half, trial, nx, ny, nz, false)
        if c <= cost then
          for p = 1, 9 do r[p] = trial[p] end
          tx, ty, tz, cost = nx, ny, nz, c
          accepted = true
          lambda = lambda * 0.1
          if lambda < 1e-12 then lambda = 1e-12 end
        elseif small then
          break
        end
      end
      if not accepted then
        lambda = lambda * 10
        if lambda > 1e8 then break end
      end
    end
    if small or not accepted then break end
  end
  return tx, ty, tz, cost, k
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
