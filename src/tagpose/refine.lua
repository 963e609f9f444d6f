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
-- Poses are a flat rotation `r` (row-major, tag → camera) and `tx, ty, tz`; pixels are flat
-- `{u1, v1, ..., u4, v4}`; `half` is half the tag side.
-- @module tagpose.refine

local rotation = require("tagpose.rotation")
local linsolve = require("tagpose.linsolve")
local camera_model = require("tagpose.camera")

local sqrt = math.sqrt
local huge = math.huge
local lens, brown, fisheye = camera_model.lens, camera_model.brown, camera_model.fisheye
local spd6 = linsolve.spd6
local from_rotation_vector, multiply = rotation.from_rotation_vector, rotation.multiply

local M = {}

--- Bound on the linearisations (Jacobian evaluations) of one refinement.
M.MAX_ITERATIONS = 20
--- A step ends the refinement when the squared displacement it gives the projected corners
-- (summed over the corners) is below `STEP_RELATIVE` times the sum of squared residuals: the
-- pose then moves by a negligible fraction of its own statistical uncertainty...
M.STEP_RELATIVE = 1e-2
--- ... or below `STEP_TOLERANCE`² (px²) when the residuals are at round-off (exact corners).
M.STEP_TOLERANCE = 1e-5

local CX = { -1, 1, 1, -1 }
local CY = { 1, 1, -1, -1 }

local trial = {} -- trial rotation
local inc = {} -- rotation increment

--- Sum of squared pixel residuals of a pose.
-- @tparam table camera a checked camera
-- @tparam {number,...} px observed pixels, flat
-- @tparam number half half the tag side
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @treturn number the sum over the four corners of the squared pixel distance (`math.huge` when
--   a corner is not in front of the camera)
function M.cost(camera, px, half, r, tx, ty, tz)
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  local kind, l1, l2, l3, l4, l5, l6, l7, l8 = lens(camera)
  local r1, r2, r4, r5, r7, r8 = r[1], r[2], r[4], r[5], r[7], r[8]
  local sum = 0
  for i = 1, 4 do
    local a, b = CX[i] * half, CY[i] * half
    local z = r7 * a + r8 * b + tz
    if not (z > 0) then return huge end
    local pu, pv = (r1 * a + r2 * b + tx) / z, (r4 * a + r5 * b + ty) / z
    if kind == 1 then
      pu, pv = brown(pu, pv, l1, l2, l3, l4, l5, l6, l7, l8)
    elseif kind == 2 then
      pu, pv = fisheye(pu, pv, l1, l2, l3, l4)
    end
    local du, dv = fx * pu + cx - px[2 * i - 1], fy * pv + cy - px[2 * i]
    sum = sum + du * du + dv * dv
  end
  return sum
end

local cost = M.cost

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
-- @treturn number the sum of squared pixel residuals at the result (`math.huge` when the start
--   puts a corner behind the camera)
-- @treturn int linearisations used
function M.refine(camera, px, half, r, tx, ty, tz, max_iterations)
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  local kind, l1, l2, l3, l4, l5, l6, l7, l8 = lens(camera)
  local floor, relative = 4 * M.STEP_TOLERANCE * M.STEP_TOLERANCE, M.STEP_RELATIVE
  local lambda = 1e-6
  local k = 0
  local sum = huge
  while k < max_iterations do
    k = k + 1
    -- linearise: normal equations H δ = -g and the cost, corner by corner
    local h11, h12, h13, h14, h15, h16 = 0, 0, 0, 0, 0, 0
    local h22, h23, h24, h25, h26 = 0, 0, 0, 0, 0
    local h33, h34, h35, h36 = 0, 0, 0, 0
    local h44, h45, h46, h55, h56, h66 = 0, 0, 0, 0, 0, 0
    local g1, g2, g3, g4, g5, g6 = 0, 0, 0, 0, 0, 0
    local r1, r2, r4, r5, r7, r8 = r[1], r[2], r[4], r[5], r[7], r[8]
    sum = 0
    for i = 1, 4 do
      local a, b = CX[i] * half, CY[i] * half
      local y1, y2, y3 = r1 * a + r2 * b, r4 * a + r5 * b, r7 * a + r8 * b
      local z = y3 + tz
      if not (z > 0) then return tx, ty, tz, huge, k end
      local iz = 1 / z
      local pu, pv = (y1 + tx) * iz, (y2 + ty) * iz
      local xd, yd, j11, j12, j21, j22 = pu, pv, 1, 0, 0, 1
      if kind == 1 then
        xd, yd, j11, j12, j21, j22 = brown(pu, pv, l1, l2, l3, l4, l5, l6, l7, l8)
      elseif kind == 2 then
        xd, yd, j11, j12, j21, j22 = fisheye(pu, pv, l1, l2, l3, l4)
      end
      local ru = fx * xd + cx - px[2 * i - 1]
      local rv = fy * yd + cy - px[2 * i]
      sum = sum + ru * ru + rv * rv
      -- row u: e = fx·(j11 ∂pu/∂X + j12 ∂pv/∂X), with ∂p/∂X = (1, 0, -p) / z; the Jacobian
      -- row is (Y × e, e)
      local e1, e2 = fx * j11 * iz, fx * j12 * iz
      local e3 = -(e1 * pu + e2 * pv)
      local w1, w2, w3 = y2 * e3 - y3 * e2, y3 * e1 - y1 * e3, y1 * e2 - y2 * e1
      h11, h12, h13 = h11 + w1 * w1, h12 + w1 * w2, h13 + w1 * w3
      h14, h15, h16 = h14 + w1 * e1, h15 + w1 * e2, h16 + w1 * e3
      h22, h23, h24, h25, h26 = h22 + w2 * w2, h23 + w2 * w3, h24 + w2 * e1, h25 + w2 * e2,
        h26 + w2 * e3
      h33, h34, h35, h36 = h33 + w3 * w3, h34 + w3 * e1, h35 + w3 * e2, h36 + w3 * e3
      h44, h45, h46 = h44 + e1 * e1, h45 + e1 * e2, h46 + e1 * e3
      h55, h56, h66 = h55 + e2 * e2, h56 + e2 * e3, h66 + e3 * e3
      g1, g2, g3 = g1 + w1 * ru, g2 + w2 * ru, g3 + w3 * ru
      g4, g5, g6 = g4 + e1 * ru, g5 + e2 * ru, g6 + e3 * ru
      -- row v: the same with fy, j21, j22
      e1, e2 = fy * j21 * iz, fy * j22 * iz
      e3 = -(e1 * pu + e2 * pv)
      w1, w2, w3 = y2 * e3 - y3 * e2, y3 * e1 - y1 * e3, y1 * e2 - y2 * e1
      h11, h12, h13 = h11 + w1 * w1, h12 + w1 * w2, h13 + w1 * w3
      h14, h15, h16 = h14 + w1 * e1, h15 + w1 * e2, h16 + w1 * e3
      h22, h23, h24, h25, h26 = h22 + w2 * w2, h23 + w2 * w3, h24 + w2 * e1, h25 + w2 * e2,
        h26 + w2 * e3
      h33, h34, h35, h36 = h33 + w3 * w3, h34 + w3 * e1, h35 + w3 * e2, h36 + w3 * e3
      h44, h45, h46 = h44 + e1 * e1, h45 + e1 * e2, h46 + e1 * e3
      h55, h56, h66 = h55 + e2 * e2, h56 + e2 * e3, h66 + e3 * e3
      g1, g2, g3 = g1 + w1 * rv, g2 + w2 * rv, g3 + w3 * rv
      g4, g5, g6 = g4 + e1 * rv, g5 + e2 * rv, g6 + e3 * rv
    end
    if not (sum < huge) then return tx, ty, tz, huge, k end
    -- damped steps until one lowers the cost
    local accepted, converged = false, false
    while true do
      local s = 1 + lambda
      local d1, d2, d3, d4, d5, d6 = spd6(h11 * s, h12, h13, h14, h15, h16, h22 * s, h23, h24,
        h25, h26, h33 * s, h34, h35, h36, h44 * s, h45, h46, h55 * s, h56, h66 * s,
        -g1, -g2, -g3, -g4, -g5, -g6)
      if d1 then
        -- predicted squared displacement of the corners: δᵀHδ = -δ·g - λ Σ H_ii δ_i²
        local disp = -(d1 * g1 + d2 * g2 + d3 * g3 + d4 * g4 + d5 * g5 + d6 * g6)
          - lambda * (h11 * d1 * d1 + h22 * d2 * d2 + h33 * d3 * d3 + h44 * d4 * d4
            + h55 * d5 * d5 + h66 * d6 * d6)
        converged = disp < floor + relative * sum
        from_rotation_vector(d1, d2, d3, inc)
        multiply(inc, r, trial)
        local nx, ny, nz = tx + d4, ty + d5, tz + d6
        local c = cost(camera, px, half, trial, nx, ny, nz)
        if c <= sum then
          for p = 1, 9 do r[p] = trial[p] end
          tx, ty, tz, sum = nx, ny, nz, c
          accepted = true
          lambda = lambda * 0.1
          if lambda < 1e-12 then lambda = 1e-12 end
          break
        end
        if converged then break end
      end
      lambda = lambda * 10
      if lambda > 1e8 then break end
    end
    if converged or not accepted then break end
  end
  return tx, ty, tz, sum, k
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
