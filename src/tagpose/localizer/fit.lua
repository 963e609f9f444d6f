--- The robot's pose on a map from one camera frame: a weighted least-squares fit of the six
-- pose parameters to the corners of every map tag the frame saw, with the priors a robot has,
-- a per-tag consistency test, and a covariance that carries the mount's and the map's errors.
--
-- Frames: the field (map) frame, z up; the robot frame (ROS: x forward, y left, z up, origin on
-- the floor); the camera's optical frame (x right, y down, z forward). The pose is robot →
-- field, `X_field = R·X_robot + t`; a mount is camera → robot, `X_robot = M·X_cam + m`.
-- Rotations are flat, row-major 3×3.
--
-- The parameters move the pose by a step `(δω, δt)`, the rotation on the left in the field
-- frame, `R ← exp([δω]×)·R`, as `tagpose.core.lsq`'s kernels do (its normal equations' layout,
-- its damped step). A corner at field point `P`, seen in the camera at `X = (R·M)ᵀ·(P − R·m − t)`,
-- has the residual `(fx·(X₁/X₃ − x), fy·(X₂/X₃ − y)) / σ` (x, y its normalised, undistorted
-- image coordinates) and the Jacobian rows `(e × v, −e)` with `e = R·M·∂pixel/∂X / σ` and
-- `v = P − t`. The priors, each a residual over its σ: the robot's height `t₃` (the floor), the
-- robot's up axis `R·ẑ` across the field's (gravity: roll and pitch small), and the heading
-- `atan2(R₂₁, R₁₁)` near a given one (a gyro whose offset is known to that σ).
--
-- The covariance (position, then the rotation vector, field frame: the order of a ROS
-- `PoseWithCovariance`) is `H⁻¹ + H⁻¹·Gᵀ... `: the information's inverse plus the mount's and the
-- map's errors carried through the fit, `H⁻¹ (Σ_b J̃_b Σ_b J̃_bᵀ) H⁻¹` with `J̃_b = Jᵀ·∂r/∂b` for
-- each camera's mount (6 numbers) and each tag's place (3 numbers).
-- @module tagpose.localizer.fit

local lsq = require("tagpose.core.lsq")
local linalg = require("tagpose.localizer.linalg")
local rotation = require("tagpose.core.rotation")
local compat = require("tagpose.core.compat")

local huge, pi = math.huge, math.pi
local SQRT3 = math.sqrt(3)
local atan2 = compat.atan2
local damped_step, turn = lsq.damped_step, lsq.turn
local multiply = rotation.multiply

local M = {}

--- Linearisations of one fit at most.
M.MAX_ITERATIONS = 12

-- The angle a wrapped to (-π, π].
local function wrap(a)
  a = a % (2 * pi)
  if a > pi then a = a - 2 * pi end
  return a
end
M.wrap = wrap

--- The heading of a robot → field rotation: `atan2(R₂₁, R₁₁)` (the ZYX yaw).
-- @tparam {number,...} r flat rotation
-- @treturn number radians
function M.yaw(r)
  return atan2(r[4], r[1])
end

-- The upper-triangle index of (a, b), a ≤ b, in lsq's layout.
local IDX = {}
do
  local k = 0
  for a = 1, 6 do
    IDX[a] = {}
    for b = a, 6 do
      k = k + 1
      IDX[a][b] = k
    end
  end
  for a = 1, 6 do
    for b = 1, a - 1 do IDX[a][b] = IDX[b][a] end
  end
end

-- One residual row j (6 numbers, lsq order: δω then δt) and its value r into N.
local function add_row(N, j1, j2, j3, j4, j5, j6, r)
  N[1], N[2], N[3] = N[1] + j1 * j1, N[2] + j1 * j2, N[3] + j1 * j3
  N[4], N[5], N[6] = N[4] + j1 * j4, N[5] + j1 * j5, N[6] + j1 * j6
  N[7], N[8], N[9] = N[7] + j2 * j2, N[8] + j2 * j3, N[9] + j2 * j4
  N[10], N[11] = N[10] + j2 * j5, N[11] + j2 * j6
  N[12], N[13], N[14], N[15] = N[12] + j3 * j3, N[13] + j3 * j4, N[14] + j3 * j5, N[15] + j3 * j6
  N[16], N[17], N[18] = N[16] + j4 * j4, N[17] + j4 * j5, N[18] + j4 * j6
  N[19], N[20], N[21] = N[19] + j5 * j5, N[20] + j5 * j6, N[21] + j6 * j6
  N[22], N[23], N[24] = N[22] + j1 * r, N[23] + j2 * r, N[24] + j3 * r
  N[25], N[26], N[27] = N[25] + j4 * r, N[26] + j5 * r, N[27] + j6 * r
end

local function zero(N, n)
  for i = 1, n do N[i] = 0 end
  return N
end

-- The camera → field rotation of an observation under the pose: R·M into out.
local rfc = {}

-- The corners of observation o under the pose (r, t): the sum of squared residuals over σ² (huge
-- when a corner is behind the camera), and what is asked of their gradients `e` (field frame):
-- the pose's normal equations into N; with G the mount's (G.mount) and the tag place's
-- (o.gtag) cross terms with the pose, for the covariance; with A and b the tag place's own
-- normal equations, `A += e eᵀ`, `b += e r` (the map check).
local function corner_terms(o, r, tx, ty, tz, sigma, N, G, A, b)
  local mnt = o.mount
  multiply(r, mnt.r, rfc)
  local f1, f2, f3, f4, f5, f6, f7, f8, f9 = rfc[1], rfc[2], rfc[3], rfc[4], rfc[5], rfc[6],
    rfc[7], rfc[8], rfc[9]
  local m = mnt.t
  -- the camera's centre in the field
  local cx = r[1] * m[1] + r[2] * m[2] + r[3] * m[3] + tx
  local cy = r[4] * m[1] + r[5] * m[2] + r[6] * m[3] + ty
  local cz = r[7] * m[1] + r[8] * m[2] + r[9] * m[3] + tz
  local P, obs = o.tag.points, o.xy
  local fx, fy = o.fx / sigma, o.fy / sigma
  local sum = 0
  for k = 1, 4 do
    local q = 3 * k
    local p1, p2, p3 = P[q - 2], P[q - 1], P[q]
    local d1, d2, d3 = p1 - cx, p2 - cy, p3 - cz
    local X = f1 * d1 + f4 * d2 + f7 * d3
    local Y = f2 * d1 + f5 * d2 + f8 * d3
    local Z = f3 * d1 + f6 * d2 + f9 * d3
    if not (Z > 1e-9) then return huge end
    local iz = 1 / Z
    local xn, yn = X * iz, Y * iz
    local ru, rv = fx * (xn - obs[2 * k - 1]), fy * (yn - obs[2 * k])
    sum = sum + ru * ru + rv * rv
    -- ∂(u, v)/∂X in the camera frame, then in the field frame (columns of R·M)
    local a1, a3 = fx * iz, -fx * xn * iz
    local b2, b3 = fy * iz, -fy * yn * iz
    local eu1, eu2, eu3 = f1 * a1 + f3 * a3, f4 * a1 + f6 * a3, f7 * a1 + f9 * a3
    local ev1, ev2, ev3 = f2 * b2 + f3 * b3, f5 * b2 + f6 * b3, f8 * b2 + f9 * b3
    if A then
      for side = 1, 2 do
        local e1, e2, e3, res = eu1, eu2, eu3, ru
        if side == 2 then e1, e2, e3, res = ev1, ev2, ev3, rv end
        A[1], A[2], A[3] = A[1] + e1 * e1, A[2] + e1 * e2, A[3] + e1 * e3
        A[4], A[5], A[6] = A[4] + e2 * e1, A[5] + e2 * e2, A[6] + e2 * e3
        A[7], A[8], A[9] = A[7] + e3 * e1, A[8] + e3 * e2, A[9] + e3 * e3
        b[1], b[2], b[3] = b[1] + e1 * res, b[2] + e2 * res, b[3] + e3 * res
      end
    end
    if N then
      local v1, v2, v3 = p1 - tx, p2 - ty, p3 - tz
      -- rows (e × v, −e): a point moves by δt + δω × v, so the residual by e·δt + (v × e)·δω;
      -- the point is fixed and the robot moves, hence the signs
      local wu1, wu2, wu3 = eu2 * v3 - eu3 * v2, eu3 * v1 - eu1 * v3, eu1 * v2 - eu2 * v1
      local wv1, wv2, wv3 = ev2 * v3 - ev3 * v2, ev3 * v1 - ev1 * v3, ev1 * v2 - ev2 * v1
      add_row(N, wu1, wu2, wu3, -eu1, -eu2, -eu3, ru)
      add_row(N, wv1, wv2, wv3, -ev1, -ev2, -ev3, rv)
      if G then
        -- the mount's step (ε, δm) in the robot frame: the camera moves by δm + ε × (q − m)
        -- where q is the point in the robot frame; the residual by the same rows with the
        -- gradient in the robot frame, e_r = Rᵀ e, and w = q − m. The tag's step δp in the
        -- field: the residual moves by e·δp.
        local q1 = r[1] * v1 + r[4] * v2 + r[7] * v3 - m[1]
        local q2 = r[2] * v1 + r[5] * v2 + r[8] * v3 - m[2]
        local q3 = r[3] * v1 + r[6] * v2 + r[9] * v3 - m[3]
        for side = 1, 2 do
          local e1, e2, e3, w1, w2, w3 = eu1, eu2, eu3, wu1, wu2, wu3
          if side == 2 then e1, e2, e3, w1, w2, w3 = ev1, ev2, ev3, wv1, wv2, wv3 end
          local g1 = r[1] * e1 + r[4] * e2 + r[7] * e3
          local g2 = r[2] * e1 + r[5] * e2 + r[8] * e3
          local g3 = r[3] * e1 + r[6] * e2 + r[9] * e3
          local jm1, jm2, jm3 = g2 * q3 - g3 * q2, g3 * q1 - g1 * q3, g1 * q2 - g2 * q1
          local jrow = { w1, w2, w3, -e1, -e2, -e3 }
          local jm = { jm1, jm2, jm3, -g1, -g2, -g3 }
          local gm, gp = G.mount, o.gtag
          for a = 1, 6 do
            local ja = jrow[a]
            for c = 1, 6 do gm[(a - 1) * 6 + c] = gm[(a - 1) * 6 + c] + ja * jm[c] end
            gp[(a - 1) * 3 + 1] = gp[(a - 1) * 3 + 1] + ja * e1
            gp[(a - 1) * 3 + 2] = gp[(a - 1) * 3 + 2] + ja * e2
            gp[(a - 1) * 3 + 3] = gp[(a - 1) * 3 + 3] + ja * e3
          end
        end
      end
    end
  end
  return sum
end

--- The normal equations of a tag's place (its centre moved by δp in the field, the robot's pose
-- held): `A += Σ e eᵀ`, `b += Σ e r` over its 8 residuals; the least-squares move is
-- `δp = −A⁻¹ b`.
-- @tparam table o an observation
-- @tparam {number,...} r robot → field rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number sigma σ, px
-- @tparam {number,...} A 3×3 (flat) to add to
-- @tparam {number,...} b 3 numbers to add to
-- @treturn boolean false when a corner is behind the camera (A and b then incomplete)
function M.tag_normal(o, r, tx, ty, tz, sigma, A, b)
  return corner_terms(o, r, tx, ty, tz, sigma, nil, nil, A, b) < huge
end

--- The pixel cost of one observation at a pose: the sum of squared residuals over σ².
-- @tparam table o an observation (see `fit`)
-- @tparam {number,...} r robot → field rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number sigma σ, px
-- @treturn number χ² of its 8 residuals (math.huge when the tag is behind the camera)
function M.tag_cost(o, r, tx, ty, tz, sigma)
  return corner_terms(o, r, tx, ty, tz, sigma)
end

-- The priors' cost and (with N) rows.
local function prior_terms(pr, r, tz, N)
  local sum = 0
  if pr.sigma_z then
    local s = 1 / pr.sigma_z
    local e = tz * s
    sum = sum + e * e
    if N then add_row(N, 0, 0, 0, 0, 0, s, e) end
  end
  if pr.sigma_tilt then
    local s = 1 / pr.sigma_tilt
    local u1, u2, u3 = r[3], r[6], r[9]
    local e1, e2 = u1 * s, u2 * s
    sum = sum + e1 * e1 + e2 * e2
    -- δu = δω × u
    if N then
      add_row(N, 0, u3 * s, -u2 * s, 0, 0, 0, e1)
      add_row(N, -u3 * s, 0, u1 * s, 0, 0, 0, e2)
    end
  end
  if pr.yaw then
    local s = 1 / pr.sigma_yaw
    local r11, r21, r31 = r[1], r[4], r[7]
    local e = wrap(atan2(r21, r11) - pr.yaw) * s
    sum = sum + e * e
    if N then
      local n = r11 * r11 + r21 * r21
      add_row(N, -r31 * r11 / n * s, -r31 * r21 / n * s, s, 0, 0, 0, e)
    end
  end
  return sum
end

--- The priors' cost at a pose: the floor's, gravity's and the heading's residuals over their σ,
-- squared and summed, as the fit counts them.
-- @tparam table pr the priors (`fit`)
-- @tparam {number,...} r robot → field rotation
-- @tparam number tz the robot's height
-- @treturn number χ²
function M.prior_cost(pr, r, tz)
  return prior_terms(pr, r, tz)
end

-- Total cost over the active observations.
local function cost(obs, n, active, pr, r, tx, ty, tz, sigma, N)
  if N then zero(N, 27) end
  local sum = 0
  for i = 1, n do
    if active[i] then
      local c = corner_terms(obs[i], r, tx, ty, tz, sigma, N)
      if not (c < huge) then return huge end
      sum = sum + c
    end
  end
  return sum + prior_terms(pr, r, tz, N)
end

local N = {}
local trial = {}

--- Fit the robot's pose to the active observations, in place, from the start `pose`.
-- An observation is `{tag = {points = 12 field numbers (c1..c4)}, mount = {r = flat camera →
-- robot rotation, t = {3}}, xy = {8 normalised undistorted corner coordinates}, fx =, fy =}`.
-- @tparam {table,...} obs observations
-- @tparam int n how many
-- @tparam {boolean,...} active which take part
-- @tparam table pr the priors: `sigma_z`, `sigma_tilt` (radians), `yaw` and `sigma_yaw`
--   (each nil: off)
-- @tparam table pose `{r = flat robot → field rotation, t = {x, y, z}}`, replaced by the fit
-- @tparam number sigma σ, px
-- @tparam[opt] int iterations bound on the linearisations (default `MAX_ITERATIONS`)
-- @treturn number the final cost (χ² of corners and priors), math.huge when the start puts a
--   tag behind a camera
function M.fit(obs, n, active, pr, pose, sigma, iterations)
  local r, t = pose.r, pose.t
  local c = cost(obs, n, active, pr, r, t[1], t[2], t[3], sigma, N)
  if not (c < huge) then return huge end
  local lambda = 1e-6
  for _ = 1, iterations or M.MAX_ITERATIONS do
    local lam, disp, d1, d2, d3, d4, d5, d6 = damped_step(N, lambda)
    if not lam then break end
    turn(d1, d2, d3, r, trial)
    local nx, ny, nz = t[1] + d4, t[2] + d5, t[3] + d6
    local c2 = cost(obs, n, active, pr, trial, nx, ny, nz, sigma)
    if c2 <= c then
      for j = 1, 9 do r[j] = trial[j] end
      t[1], t[2], t[3] = nx, ny, nz
      local done = c - c2 < 1e-6 * c + 1e-10 or disp < 1e-8
      c = c2
      lambda = lam * 0.1
      cost(obs, n, active, pr, r, t[1], t[2], t[3], sigma, N)
      if done then break end
    else
      lambda = lam * 10
      if lambda > 1e6 then break end
    end
  end
  rotation.orthonormalise(r, r)
  return c
end


-- lsq order (δω, δt) → the contract's (δt, δω)
local ORDER = { 4, 5, 6, 1, 2, 3 }
-- the rows of x, y and the heading in lsq order
local SENS_ROWS = { 4, 5, 3 }

--- The covariance of a fit (after `fit`): the information's inverse plus the mount's and the
-- map's errors carried through, and the per-tag χ² of the residuals.
-- @tparam {table,...} obs
-- @tparam int n
-- @tparam {boolean,...} active
-- @tparam table pr the priors
-- @tparam table pose the fitted pose
-- @tparam number sigma σ, px
-- @tparam table nuisance `mount_position`, `mount_angle`, `map_position`: the RMS length of
--   each error over its three axes (m, rad, m; 0: none), each axis σ/√3
-- @treturn {number,...} the 6×6 covariance, flat row-major, (x, y, z, rx, ry, rz)
-- @treturn {number,...} its part from the corners' noise alone (the information's inverse)
-- @treturn table the sensitivities of (x, y, heading) to the errors, each over its σ per axis
--   (so that their covariance is `S Sᵀ`): `mount` (3×6, the frame's camera: turn then shift,
--   robot frame), `tags` (`[id]` = 3×3, the tag's place)
-- @return nil when the information is singular
function M.covariance(obs, n, active, pr, pose, sigma, nuisance)
  local r, t = pose.r, pose.t
  zero(N, 27)
  local G = { mount = {} }
  local cams, mounts = {}, {}
  for i = 1, n do
    if active[i] then
      local o = obs[i]
      o.gtag = zero(o.gtag or {}, 18)
      -- one mount block per camera (a frame may hold several cameras' observations)
      local key = o.mount
      local gm = cams[key]
      if not gm then
        gm = zero({}, 36)
        cams[key] = gm
        mounts[#mounts + 1] = gm
      end
      G.mount = gm
      corner_terms(o, r, t[1], t[2], t[3], sigma, N, G)
    end
  end
  prior_terms(pr, r, t[3], N)
  local H = {}
  for a = 1, 6 do
    for b = 1, 6 do H[(a - 1) * 6 + b] = N[IDX[a][b]] end
  end
  local Hi = linalg.invert(H, 6, {})
  if not Hi then return nil end
  -- Σ_b G_b Σ_b G_bᵀ, 6×6 (lsq order)
  local S = zero({}, 36)
  -- (each σ is the RMS length of the error, all three axes together: σ²/3 per axis)
  local sp, sa, sm = (nuisance.mount_position or 0) / SQRT3, (nuisance.mount_angle or 0) / SQRT3,
    (nuisance.map_position or 0) / SQRT3
  for _, gm in ipairs(mounts) do
    for a = 1, 6 do
      for b = 1, 6 do
        local s = 0
        for c = 1, 3 do s = s + gm[(a - 1) * 6 + c] * gm[(b - 1) * 6 + c] * sa * sa end
        for c = 4, 6 do s = s + gm[(a - 1) * 6 + c] * gm[(b - 1) * 6 + c] * sp * sp end
        S[(a - 1) * 6 + b] = S[(a - 1) * 6 + b] + s
      end
    end
  end
  for i = 1, n do
    -- (an observation may carry its own: a tag whose place is in doubt)
    local o = obs[i]
    local si = o.map_sigma and o.map_sigma / SQRT3 or sm
    if active[i] and si > 0 then
      local gp = o.gtag
      for a = 1, 6 do
        for b = 1, 6 do
          local s = 0
          for c = 1, 3 do s = s + gp[(a - 1) * 3 + c] * gp[(b - 1) * 3 + c] end
          S[(a - 1) * 6 + b] = S[(a - 1) * 6 + b] + s * si * si
        end
      end
    end
  end
  -- C = Hi + Hi S Hi
  local T = zero({}, 36)
  for a = 1, 6 do
    for b = 1, 6 do
      local s = 0
      for c = 1, 6 do s = s + Hi[(a - 1) * 6 + c] * S[(c - 1) * 6 + b] end
      T[(a - 1) * 6 + b] = s
    end
  end
  local out, noise = {}, {}
  for a = 1, 6 do
    for b = 1, 6 do
      local s = Hi[(ORDER[a] - 1) * 6 + ORDER[b]]
      noise[(a - 1) * 6 + b] = s
      for c = 1, 6 do s = s + T[(ORDER[a] - 1) * 6 + c] * Hi[(c - 1) * 6 + ORDER[b]] end
      out[(a - 1) * 6 + b] = s
    end
  end
  -- the sensitivities of x, y and the heading to each error, over its σ per axis: the solution
  -- moves by −H⁻¹ G δb (x, y, heading: lsq rows 4, 5, 3)
  local sens = { mount = {}, tags = {} }
  local function rows(g, cols, scale, into)
    for j = 1, 3 do
      local rr = SENS_ROWS[j]
      for c = 1, cols do
        local v = 0
        for k = 1, 6 do v = v + Hi[(rr - 1) * 6 + k] * g[(k - 1) * cols + c] end
        into[(j - 1) * cols + c] = -v * scale(c)
      end
    end
    return into
  end
  local gm1 = mounts[1]
  if gm1 then rows(gm1, 6, function(c) return c <= 3 and sa or sp end, sens.mount) end
  for i = 1, n do
    local o = obs[i]
    local si = o.map_sigma and o.map_sigma / SQRT3 or sm
    if active[i] then sens.tags[o.id] = rows(o.gtag, 3, function() return si end, {}) end
  end
  return out, noise, sens
end

return M
