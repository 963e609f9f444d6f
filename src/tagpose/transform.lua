--- Pose algebra: the inverse of a pose, two poses composed, a pose applied to a point.
--
-- A pose maps one frame into another, `X_to = R·X_from + t`, as `tagpose.solve` returns it
-- (tag → camera) and `tagpose.layout.solve` (body → camera): a table with `position =
-- {x =, y =, z =}` (t) and the rotation as `rotation` (nested `rotation[row][col]`) and/or
-- `quaternion = {w =, x =, y =, z =}`. So
--
-- * `inverse(pose)` maps back, `X_from = Rᵀ·(X_to - t)`: the camera in the tag's frame, or
--   a robot's camera in a field map's frame from the field's pose in the camera;
-- * `compose(a, b)` is a after b, `X = Ra·(Rb·X + tb) + ta`: with `a` the camera's pose on the
--   robot (camera → robot) and `b` a tag's pose in the camera, the tag in the robot's frame;
-- * `apply(pose, point)` is `R·point + t`.
--
-- Results are new tables with `position`, `rotation` (nested) and `quaternion` (unit, `w >= 0`)
-- and nothing else: a pose's `covariance`, `confidence` or `error` does not carry over.
-- Lengths are in the poses' unit; rotations are exact compositions (no angles in between).
-- @module tagpose.transform

local rotation = require("tagpose.core.rotation")
local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")

local is_finite, describe = compat.is_finite, args.describe

local M = {}

--- How far from orthonormal a pose's `rotation` may be (the largest entry of `R·Rᵀ - I`), and
-- how far (radians) its `rotation` and `quaternion` may disagree when it has both.
M.TOLERANCE = 1e-6

-- Raise a misuse at the caller of the public function (two calls up from the helper that
-- calls this).
local function raise(n, fname, message)
  args.raise(n, fname, message, 4)
end

-- x, y, z of a point {x =, y =, z =} or {x, y, z}; nil when it is neither (or not finite).
local function read_point(p)
  if type(p) ~= "table" then return nil end
  local x, y, z = p.x, p.y, p.z
  if x == nil and y == nil and z == nil then x, y, z = p[1], p[2], p[3] end
  if is_finite(x) and is_finite(y) and is_finite(z) then return x, y, z end
  return nil
end

-- A pose's rotation given as a matrix, nested or flat, into r; or nil and what is wrong.
local function read_matrix(m, r)
  if type(m) ~= "table" then return nil, "table expected, got " .. type(m) end
  if not rotation.read(m, r) then
    if type(m[1]) == "table" and (type(m[2]) ~= "table" or type(m[3]) ~= "table") then
      return nil, "three rows expected"
    end
    return nil, "nested {{r11, r12, r13}, {r21, r22, r23}, {r31, r32, r33}} or flat {r11, ..., "
      .. "r33} of finite numbers expected"
  end
  local worst, det = rotation.deviation(r)
  if not (worst <= M.TOLERANCE and det > 0) then
    return nil, ("not a rotation matrix (largest entry of R·Rᵀ - I %.3g, determinant %.3g)")
      :format(worst, det)
  end
  return r
end

local from_q = {}

-- Read pose argument n of fname: its rotation into r (flat), and its translation; raises at
-- the public function's caller when the pose is not one.
local function read_pose(p, n, fname, r)
  if type(p) ~= "table" then raise(n, fname, "pose table expected, got " .. type(p)) end
  local tx, ty, tz = read_point(p.position)
  if not tx then
    raise(n, fname, "pose.position: {x =, y =, z =} of finite numbers expected, got "
      .. describe(p.position))
  end
  local m, q = p.rotation, p.quaternion
  if m == nil and q == nil then
    raise(n, fname, "pose.rotation or pose.quaternion expected")
  end
  local have
  if m ~= nil then
    local ok, why = read_matrix(m, r)
    if not ok then raise(n, fname, "pose.rotation: " .. why) end
    have = true
  end
  if q ~= nil then
    local w, x, y, z
    if type(q) == "table" then w, x, y, z = q.w, q.x, q.y, q.z end
    if not (is_finite(w) and is_finite(x) and is_finite(y) and is_finite(z)) then
      raise(n, fname, "pose.quaternion: {w =, x =, y =, z =} of finite numbers, not zero, "
        .. "expected")
    end
    -- normalised without overflow: {w = 1e200, x = 1e200} is a quarter turn
    w, x, y, z = rotation.unit_quaternion(w, x, y, z)
    if not w then
      raise(n, fname, "pose.quaternion: {w =, x =, y =, z =} of finite numbers, not zero, "
        .. "expected")
    end
    if have then
      local angle = rotation.angle(r, rotation.from_quaternion(w, x, y, z, from_q))
      if not (angle <= M.TOLERANCE) then
        raise(n, fname, ("pose.rotation and pose.quaternion disagree by %.3g rad"):format(angle))
      end
    else
      rotation.from_quaternion(w, x, y, z, r)
    end
  end
  return tx, ty, tz
end

-- The public pose of a flat rotation and a translation.
local function new_pose(r, x, y, z)
  local w, qx, qy, qz = rotation.to_quaternion(r)
  return {
    position = { x = x, y = y, z = z },
    rotation = rotation.to_nested(r),
    quaternion = { w = w, x = qx, y = qy, z = qz },
  }
end

--- The inverse of a pose: if `pose` maps frame A into frame B (`X_B = R·X_A + t`), the
-- result maps B into A (`X_A = Rᵀ·X_B - Rᵀ·t`). Of a tag's pose in the camera it is the
-- camera's pose in the tag's frame; of a field map's pose in the camera
-- (`tagpose.layout.solve`), the camera's pose on the field.
-- @tparam table pose `position = {x =, y =, z =}` and `rotation` (nested `[row][col]`, or flat
--   row-major) and/or `quaternion = {w =, x =, y =, z =}` (normalised); with both, they must
--   agree (`TOLERANCE`)
-- @treturn table `{position =, rotation =, quaternion =}` (`w >= 0`)
-- @raise `bad argument #1 to 'inverse' (...)` when pose is not one (missing or non-finite
--   fields, a matrix that is not a rotation, a rotation and a quaternion that disagree)
-- @usage
-- local body = assert(tagpose.layout.solve(detections, camera, field))
-- local on_field = tagpose.transform.inverse(body)   -- the camera on the field
-- print(on_field.position.x, on_field.position.y, on_field.position.z)
function M.inverse(pose)
  local r = {}
  local x, y, z = read_pose(pose, 1, "inverse", r)
  rotation.transpose(r, r)
  return new_pose(r, -(r[1] * x + r[2] * y + r[3] * z), -(r[4] * x + r[5] * y + r[6] * z),
    -(r[7] * x + r[8] * y + r[9] * z))
end

--- Two poses composed, a after b: `X = Ra·(Rb·X + tb) + ta`. If b maps A into B and a maps
-- B into C, the result maps A into C: the camera's pose on the robot after a tag's pose in
-- the camera is the tag's pose on the robot; the camera's pose on the field after the robot's
-- pose in the camera (`inverse` of the mount) is the robot's pose on the field.
-- @tparam table a a pose (as for `inverse`)
-- @tparam table b a pose
-- @treturn table `{position =, rotation =, quaternion =}` (`w >= 0`)
-- @raise `bad argument #n to 'compose' (...)` when a or b is not a pose
-- @usage
-- local tag_on_robot = tagpose.transform.compose(camera_on_robot, tag_in_camera)
function M.compose(a, b)
  local ra, rb = {}, {}
  local ax, ay, az = read_pose(a, 1, "compose", ra)
  local bx, by, bz = read_pose(b, 2, "compose", rb)
  local x = ra[1] * bx + ra[2] * by + ra[3] * bz + ax
  local y = ra[4] * bx + ra[5] * by + ra[6] * bz + ay
  local z = ra[7] * bx + ra[8] * by + ra[9] * bz + az
  return new_pose(rotation.multiply(ra, rb, ra), x, y, z)
end

local applied = {}

--- A pose applied to a point: `R·point + t` (the point from the pose's source frame into its
-- target frame).
-- @tparam table pose a pose (as for `inverse`)
-- @tparam table point `{x =, y =, z =}` or `{x, y, z}`
-- @treturn table `{x =, y =, z =}`
-- @raise `bad argument #n to 'apply' (...)` when pose is not a pose or point not a point
-- @usage
-- -- the tag's top-left corner (c4) in the camera frame
-- local c4 = tagpose.transform.apply(pose, { x = -s / 2, y = -s / 2, z = 0 })
function M.apply(pose, point)
  local r = applied
  local tx, ty, tz = read_pose(pose, 1, "apply", r)
  local x, y, z = read_point(point)
  if not x then
    args.raise(2, "apply", "point {x =, y =, z =} or {x, y, z} of finite numbers expected, got "
      .. describe(point), 2)
  end
  return { x = r[1] * x + r[2] * y + r[3] * z + tx, y = r[4] * x + r[5] * y + r[6] * z + ty,
    z = r[7] * x + r[8] * y + r[9] * z + tz }
end

return M
