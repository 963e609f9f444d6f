--- Roll, pitch and yaw: `R = Rz(yaw)·Ry(pitch)·Rx(roll)`, ROS's convention (tf2's `setRPY`,
-- REP 103's fixed axes: roll about x first, then pitch about the fixed y, then yaw about the
-- fixed z), radians. Public as `tagpose.rotation.to_rpy` and `from_rpy`, which check their
-- arguments. Matrices nested `r[row][col]` (the shape of `pose.rotation`) or flat row-major.
-- @module tagpose.core.rpy

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local input = require("tagpose.core.rotation_input")

local sqrt, sin, cos, abs = math.sqrt, math.sin, math.cos, math.abs
local atan2, is_finite = compat.atan2, compat.is_finite

local M = {}

--- Below this `cos(pitch)` (the length of R's first column's x, y part) `to_rpy` is at gimbal
-- lock: roll and yaw turn about one axis there, so yaw is set to 0 and roll carries the turn
-- (as tf2's `getRPY`). The rotation it describes is still R to 2·10⁻¹³.
M.GIMBAL_LOCK = 1e-13
--- How far from orthonormal (largest entry of `R·Rᵀ - I`) a rotation given to `to_rpy` may be.
M.RPY_TOLERANCE = 1e-6

local rpy_flat = {}

--- Roll, pitch and yaw of a rotation matrix, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (ROS's
-- convention). Yaw comes from R's first column, then roll from the second row of `Rz(-yaw)·R`,
-- which is `(0, cos roll, -sin roll)` whatever the pitch: so `from_rpy(to_rpy(R))` is R to
-- round-off everywhere, at and near gimbal lock too (pitch ±π/2, see `GIMBAL_LOCK`).
-- @tparam table r the rotation: nested `r[row][col]` (the shape of `pose.rotation`) or the
--   flat row-major nine numbers
-- @treturn number roll, in [-π, π]
-- @treturn number pitch, in [-π/2, π/2]
-- @treturn number yaw, in [-π, π] (0 at gimbal lock)
-- @raise `bad argument #1 to 'to_rpy' (...)` when r is not a 3×3 of finite numbers or not a
--   rotation (`RPY_TOLERANCE`)
-- @usage
-- local roll, pitch, yaw = tagpose.rotation.to_rpy(pose.rotation)
function M.to_rpy(r)
  r = input.read(r, rpy_flat)
  if not r then
    args.raise(1, "to_rpy", "rotation matrix expected: nested {{r11, r12, r13}, {r21, r22, r23}, "
      .. "{r31, r32, r33}} or flat {r11, ..., r33} of finite numbers", 2)
  end
  local worst, det = input.deviation(r)
  if not (worst <= M.RPY_TOLERANCE and det > 0) then
    args.raise(1, "to_rpy", ("not a rotation matrix (largest entry of R·Rᵀ - I %.3g, "
      .. "determinant %.3g)"):format(worst, det), 2)
  end
  local r11, r12, r13, r21, r22, r23, r31 = r[1], r[2], r[3], r[4], r[5], r[6], r[7]
  local h = sqrt(r11 * r11 + r21 * r21)
  local yaw = 0
  if h >= M.GIMBAL_LOCK then yaw = atan2(r21, r11) end
  local cy, sy = cos(yaw), sin(yaw)
  local roll = atan2(sy * r13 - cy * r23, cy * r22 - sy * r12)
  return roll, atan2(-r31, h), yaw
end

local TWO_PI = 2 * math.pi
local degrees_said = false -- whether from_rpy said once that its angles look like degrees

--- The rotation of roll, pitch and yaw, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (ROS's convention).
-- Angles beyond ±2π are taken as given, and said once on standard error (degrees?).
-- @tparam number roll radians, about x
-- @tparam number pitch radians, about y
-- @tparam number yaw radians, about z
-- @treturn table nested `{{r11, r12, r13}, {r21, r22, r23}, {r31, r32, r33}}` (the shape of
--   `pose.rotation`; `from_nested` makes it flat)
-- @raise `bad argument #n to 'from_rpy' (finite number expected, got ...)`
-- @usage
-- local mount = { position = { x = 0.3, y = 0, z = 0.5 },
--   rotation = tagpose.rotation.from_rpy(0, math.rad(-15), 0) }
function M.from_rpy(roll, pitch, yaw)
  local bad = not is_finite(roll) and 1 or not is_finite(pitch) and 2 or not is_finite(yaw) and 3
  if bad then
    args.raise(bad, "from_rpy", "finite number expected, got "
      .. args.describe(select(bad, roll, pitch, yaw)), 2)
  end
  if not degrees_said and (abs(roll) > TWO_PI or abs(pitch) > TWO_PI or abs(yaw) > TWO_PI) then
    degrees_said = true
    io.stderr:write("tagpose.rotation: warning: from_rpy(", tostring(roll), ", ",
      tostring(pitch), ", ", tostring(yaw), "): an angle beyond ±2π is not radians (degrees?"
      .. " math.rad(30) is 30°)\n")
  end
  local cr, sr, cp, sp, cy, sy = cos(roll), sin(roll), cos(pitch), sin(pitch), cos(yaw), sin(yaw)
  return {
    { cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr },
    { sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr },
    { -sp, cp * sr, cp * cr },
  }
end

return M
