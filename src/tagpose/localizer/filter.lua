--- The robot's planar state between camera frames: an extended Kalman filter on
-- `(x, y, c, k, β₁, ..., βₘ)`: the robot's position on the field, the gyro's offset (the heading
-- being `gyro − c`), the odometry's scale error (a step of the wheels is `1 + k` times the
-- odometry's), and each camera's heading error (its mount's turn about the vertical, measured
-- to `mount_angle_sigma`, not known: the cameras disagree by it on the heading, and a filter
-- that forced one heading on both would move the robot sideways by the distance to the tags
-- times it).
--
-- Odometry moves the state by its increments, taken in the robot frame with the odometry's own
-- heading (so that an odometry that was never reset, in a frame turned and shifted from the
-- field's, gives the same steps) and turned into the field with the gyro's heading less `c`;
-- each step adds `(ODOMETRY_FRACTION·|step|)²` per axis (wheel slip), and the offset walks
-- (`OFFSET_WALK`: the gyro's drift). A camera frame's pose `(x, y, yaw)` with its 3×3
-- covariance corrects the state unless its Mahalanobis distance is past `GATE`; a frame sure of
-- itself (several tags) past the gate widens the position's variance by `JUMP²` (a robot pushed
-- where its wheels did not register gives such frames one after another, until they pass
-- again).
--
-- Covariances are flat row-major over the state.
-- @module tagpose.localizer.filter

local fit = require("tagpose.localizer.fit")
local linalg = require("tagpose.localizer.linalg")

local cos, sin, sqrt = math.cos, math.sin, math.sqrt
local wrap = fit.wrap

local M = {}

--- σ of an odometry step per axis, as a fraction of the step's length.
M.ODOMETRY_FRACTION = 0.03
--- σ² per second of the position when no odometry is fed (m²/s): a robot at 3 m/s.
M.FREE_WALK = 9
--- σ² per second of the gyro's offset (rad²/s).
M.OFFSET_WALK = 1e-7
--- Mahalanobis² gate of a frame's (x, y, yaw) (3 dof, P = 1e-4).
M.GATE = 21.1
--- Added to the position's σ (m) by each frame past the gate that is sure of itself.
M.JUMP = 0.08
--- σ of the odometry's scale error before any frame tells.
M.SCALE_SIGMA = 0.05

local Filter = {}
Filter.__index = Filter


--- A filter started at a frame's pose.
-- @tparam number x
-- @tparam number y
-- @tparam number c the offset: gyro − yaw
-- @tparam {number,...} P3 3×3 over (x, y, c); the scale starts at 0 with `SCALE_SIGMA`
-- @tparam int cameras how many cameras (each a heading error, 0 with `camera_sigma`)
-- @tparam number camera_sigma σ of a camera's heading error (radians)
-- @tparam[opt] {number,...} W3 3×3 over (x, y, c) of the frame's own noise alone, the start of
--   `Pw` (the frames' noise carried through the gains; default P3)
-- @treturn table
function M.new(x, y, c, P3, cameras, camera_sigma, W3)
  local NS = 4 + cameras
  local function start(S3)
    local P = {}
    for i = 1, NS * NS do P[i] = 0 end
    for i = 1, 3 do
      for j = 1, 3 do P[(i - 1) * NS + j] = S3[(i - 1) * 3 + j] end
    end
    P[3 * NS + 4] = M.SCALE_SIGMA * M.SCALE_SIGMA
    for i = 1, cameras do P[(3 + i) * NS + 4 + i] = camera_sigma * camera_sigma end
    return P
  end
  local beta = {}
  for i = 1, cameras do beta[i] = 0 end
  return setmetatable({ x = x, y = y, c = c, k = 0, beta = beta, P = start(P3),
    Pw = start(W3 or P3), n = NS, rejected = 0 }, Filter)
end

--- A copy (a snapshot to return to).
function Filter:copy()
  local P, Pw, beta = {}, {}, {}
  for i = 1, #self.P do P[i], Pw[i] = self.P[i], self.Pw[i] end
  for i = 1, #self.beta do beta[i] = self.beta[i] end
  return setmetatable({ x = self.x, y = self.y, c = self.c, k = self.k, beta = beta, P = P,
    Pw = Pw, n = self.n, rejected = self.rejected }, Filter)
end

-- P ← F P Fᵀ for F = I + the column `f` in column `col` (rows 1, 2).
local function add_column(P, NS, col, f1, f2)
  -- rows: r1 += f1 r_col, r2 += f2 r_col; then the same on columns
  for j = 1, NS do
    local pc = P[(col - 1) * NS + j]
    P[j] = P[j] + f1 * pc
    P[NS + j] = P[NS + j] + f2 * pc
  end
  for i = 1, NS do
    local pc = P[(i - 1) * NS + col]
    P[(i - 1) * NS + 1] = P[(i - 1) * NS + 1] + f1 * pc
    P[(i - 1) * NS + 2] = P[(i - 1) * NS + 2] + f2 * pc
  end
end

--- Move by an odometry step: (bx, by) in the robot frame, turned by the heading `gyro − c` and
-- scaled by `1 + k`.
-- @tparam number bx
-- @tparam number by
-- @tparam number gyro the gyro's reading at the step's middle
-- @tparam number dt the step's duration (s)
function Filter:step(bx, by, gyro, dt)
  local yaw = gyro - self.c
  local co, si = cos(yaw), sin(yaw)
  local ux, uy = co * bx - si * by, si * bx + co * by
  local s = 1 + self.k
  local fx, fy = s * ux, s * uy
  self.x, self.y = self.x + fx, self.y + fy
  -- ∂/∂c of the step: (fy, −fx); ∂/∂k: (ux, uy)
  local NS = self.n
  local q = M.ODOMETRY_FRACTION * M.ODOMETRY_FRACTION * (bx * bx + by * by) + 1e-8
  for pass = 1, 2 do
    local P = pass == 1 and self.P or self.Pw
    add_column(P, NS, 3, fy, -fx)
    add_column(P, NS, 4, ux, uy)
    P[1], P[NS + 2] = P[1] + q, P[NS + 2] + q
    P[2 * NS + 3] = P[2 * NS + 3] + M.OFFSET_WALK * dt
  end
end

--- Let time pass with no odometry: the position and the offset walk.
-- @tparam number dt seconds
-- @tparam boolean odometry the robot has odometry (only the offset walks)
function Filter:walk(dt, odometry)
  local NS = self.n
  for pass = 1, 2 do
    local P = pass == 1 and self.P or self.Pw
    if not odometry then
      P[1], P[NS + 2] = P[1] + M.FREE_WALK * dt, P[NS + 2] + M.FREE_WALK * dt
    end
    P[2 * NS + 3] = P[2 * NS + 3] + M.OFFSET_WALK * dt
  end
end


--- Correct the state with a frame's pose (x, y, yaw) from camera `cam` (its index) and the
-- 3×3 covariance R of the frame's pose, the gyro reading at the frame's time; at (dx, dy) from
-- the state's position (the odometry's motion between the state's time and the frame's). A
-- frame `sure` of itself (several tags) that is past the gate widens the position's variance (a
-- push the wheels did not see). `Rw`, the part of R that is the frame's own noise, is carried
-- through the same gains into `Pw` (default R).
-- @treturn boolean accepted
-- @treturn number the Mahalanobis² distance
function Filter:update(cam, zx, zy, zyaw, R, gyro, dx, dy, sure, Rw)
  local P, NS = self.P, self.n
  -- the measurement's rows: (x, y, −c + β_cam), each as two (column, sign) pairs
  local HC = { { 1, 1, 1, 0 }, { 2, 1, 2, 0 }, { 3, -1, 4 + cam, 1 } }
  local y = { zx - (self.x + dx), zy - (self.y + dy),
    wrap(zyaw - (gyro - self.c + self.beta[cam])) }
  -- PH = P Hᵀ (NS × 3), S = H P Hᵀ + R
  local PH = {}
  for r = 1, NS do
    for m = 1, 3 do
      local h = HC[m]
      PH[(r - 1) * 3 + m] = h[2] * P[(r - 1) * NS + h[1]] + h[4] * P[(r - 1) * NS + h[3]]
    end
  end
  local S = {}
  for i = 1, 3 do
    local h = HC[i]
    for j = 1, 3 do
      S[(i - 1) * 3 + j] = h[2] * PH[(h[1] - 1) * 3 + j] + h[4] * PH[(h[3] - 1) * 3 + j]
        + R[(i - 1) * 3 + j]
    end
  end
  local Si = linalg.inverse3(S)
  if not Si then return false, math.huge end
  local d2 = 0
  for i = 1, 3 do
    for j = 1, 3 do d2 = d2 + y[i] * Si[(i - 1) * 3 + j] * y[j] end
  end
  if not (d2 <= M.GATE) then
    if sure then
      self.rejected = self.rejected + 1
      local j = M.JUMP * M.JUMP
      local Pw = self.Pw
      P[1], P[NS + 2] = P[1] + j, P[NS + 2] + j
      Pw[1], Pw[NS + 2] = Pw[1] + j, Pw[NS + 2] + j
    end
    return false, d2
  end
  self.rejected = 0
  -- K = PH S⁻¹
  local K, dxs = {}, {}
  for r = 1, NS do
    local v = 0
    for c = 1, 3 do
      local k = PH[(r - 1) * 3 + 1] * Si[c] + PH[(r - 1) * 3 + 2] * Si[3 + c]
        + PH[(r - 1) * 3 + 3] * Si[6 + c]
      K[(r - 1) * 3 + c] = k
      v = v + k * y[c]
    end
    dxs[r] = v
  end
  self.x, self.y, self.c, self.k = self.x + dxs[1], self.y + dxs[2], self.c + dxs[3],
    self.k + dxs[4]
  local beta = self.beta
  for i = 1, #beta do beta[i] = beta[i] + dxs[4 + i] end
  -- P ← P − K (PH)ᵀ
  for r = 1, NS do
    for c = r, NS do
      local v = P[(r - 1) * NS + c]
      for m = 1, 3 do v = v - K[(r - 1) * 3 + m] * PH[(c - 1) * 3 + m] end
      P[(r - 1) * NS + c], P[(c - 1) * NS + r] = v, v
    end
  end
  -- the frames' own noise through the same gains (Joseph's form): Pw ← A Pw Aᵀ + K Rw Kᵀ,
  -- A = I − K H; what the mounts and the map add is the caller's (`tagpose.localizer.bias`)
  local Pw, A = self.Pw, {}
  Rw = Rw or R
  for r = 1, NS do
    for c = 1, NS do
      local v = r == c and 1 or 0
      for m = 1, 3 do
        local h = HC[m]
        local hc = (h[1] == c and h[2] or 0) + (h[3] == c and h[4] or 0)
        v = v - K[(r - 1) * 3 + m] * hc
      end
      A[(r - 1) * NS + c] = v
    end
  end
  local T = {}
  for r = 1, NS do
    for c = 1, NS do
      local v = 0
      for k = 1, NS do v = v + A[(r - 1) * NS + k] * Pw[(k - 1) * NS + c] end
      T[(r - 1) * NS + c] = v
    end
  end
  for r = 1, NS do
    for c = r, NS do
      local v = 0
      for k = 1, NS do v = v + T[(r - 1) * NS + k] * A[(c - 1) * NS + k] end
      for m = 1, 3 do
        local km = K[(r - 1) * 3 + m]
        for l = 1, 3 do v = v + km * Rw[(m - 1) * 3 + l] * K[(c - 1) * 3 + l] end
      end
      Pw[(r - 1) * NS + c], Pw[(c - 1) * NS + r] = v, v
    end
  end
  return true, d2
end

--- The robot's heading (`gyro − c`): its covariances with x and y, and its variance, from the
-- frames' own noise (`Pw`).
function Filter:heading_cov()
  local P, NS = self.Pw, self.n
  return -P[3], -P[NS + 3], P[2 * NS + 3]
end

--- σ of x, y and the offset.
function Filter:sd()
  local P = self.P
  local NS = self.n
  return sqrt(P[1]), sqrt(P[NS + 2]), sqrt(P[2 * NS + 3])
end

return M
