--- Rotations: matrix ⇄ quaternion ⇄ rotation vector, composition, orthonormalisation.
--
-- A rotation matrix is a flat, row-major, 1-based array of nine numbers:
-- `{r11, r12, r13, r21, r22, r23, r31, r32, r33}`. Its columns are the images of the source
-- frame's axes. Every function also takes the nested `r[row][col]` matrices tagpose returns
-- (`pose.rotation`), and answers a matrix in the shape it was given (the shape of `out` when
-- given, else of its first matrix). Quaternions are passed as four numbers `w, x, y, z`
-- (scalar first; `from_quaternion` also takes a pose's `{w =, x =, y =, z =}`) and returned
-- unit with `w >= 0`. Angles are radians. Functions that fill an `out` array read all their
-- inputs first, so `out` may be one of the inputs. Misuse (a matrix that is not nine finite
-- numbers, a quaternion that is not four) raises `bad argument #n to 'name' (...)`.
-- @module tagpose.core.rotation

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local input = require("tagpose.core.rotation_input")

local sqrt, sin, cos, asin = math.sqrt, math.sin, math.cos, math.asin
local atan2, is_finite = compat.atan2, compat.is_finite
-- the checked route (`tagpose.core.rotation_input`): taken only when an argument is not a flat
-- array of numbers
local flat, flat_out, matrix, check_out = input.flat, input.flat_out, input.matrix,
  input.check_out
local unary, binary, quaternion_args = input.unary, input.binary, input.quaternion_args
local scratch_a, scratch_b = {}, {} -- nested arguments read flat (never handed out)

local M = {}

--- A quaternion normalised without overflow or underflow
-- (`tagpose.core.rotation_input.unit_quaternion`).
-- @function unit_quaternion
M.unit_quaternion = input.unit_quaternion

--- Quaternion of a rotation matrix by Shepperd's method (branch on the largest of the trace
-- and the diagonal terms, so no square root of a small number is taken).
-- @tparam {number,...} r flat 3×3 rotation
-- @treturn number w (>= 0)
-- @treturn number x
-- @treturn number y
-- @treturn number z
function M.to_quaternion(r)
  if not flat(r) then r = matrix(r, 1, "to_quaternion", scratch_a) end
  -- each branch reads only what it needs (LuaJIT cannot compile the exits of a version that
  -- loads all nine entries first: "register coalescing too complex")
  local r11, r22, r33 = r[1], r[5], r[9]
  local tr = r11 + r22 + r33
  local w, x, y, z
  if tr >= r11 and tr >= r22 and tr >= r33 then
    local s = 2 * sqrt(1 + tr)
    w, x, y, z = 0.25 * s, (r[8] - r[6]) / s, (r[3] - r[7]) / s, (r[4] - r[2]) / s
  elseif r11 >= r22 and r11 >= r33 then
    local s = 2 * sqrt(1 + r11 - r22 - r33)
    w, x, y, z = (r[8] - r[6]) / s, 0.25 * s, (r[2] + r[4]) / s, (r[3] + r[7]) / s
  elseif r22 >= r33 then
    local s = 2 * sqrt(1 - r11 + r22 - r33)
    w, x, y, z = (r[3] - r[7]) / s, (r[2] + r[4]) / s, 0.25 * s, (r[6] + r[8]) / s
  else
    local s = 2 * sqrt(1 - r11 - r22 + r33)
    w, x, y, z = (r[4] - r[2]) / s, (r[3] + r[7]) / s, (r[6] + r[8]) / s, 0.25 * s
  end
  local n = sqrt(w * w + x * x + y * y + z * z)
  if w < 0 then n = -n end
  return w / n, x / n, y / n, z / n
end

--- Rotation matrix of a quaternion (normalised first).
-- @tparam number w
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @tparam[opt] {number,...} out array to fill (a new one if absent)
-- @treturn {number,...} flat 3×3 rotation
function M.from_quaternion(w, x, y, z, out)
  if type(w) ~= "number" or type(x) ~= "number" or type(y) ~= "number" or type(z) ~= "number"
    or not flat_out(out) then
    w, x, y, z, out = quaternion_args("from_quaternion", w, x, y, z, out)
    if out ~= nil and type(out[1]) == "table" then
      return M.to_nested(M.from_quaternion(w, x, y, z), out)
    end
  end
  out = out or {}
  local n = sqrt(w * w + x * x + y * y + z * z)
  if not (n > 1e-150 and n < 1e150) then
    -- (a length that would overflow or underflow: normalised by the largest component first)
    local uw, ux, uy, uz = M.unit_quaternion(w, x, y, z)
    if uw then w, x, y, z, n = uw, ux, uy, uz, 1 end
  end
  w, x, y, z = w / n, x / n, y / n, z / n
  out[1] = 1 - 2 * (y * y + z * z)
  out[2] = 2 * (x * y - w * z)
  out[3] = 2 * (x * z + w * y)
  out[4] = 2 * (x * y + w * z)
  out[5] = 1 - 2 * (x * x + z * z)
  out[6] = 2 * (y * z - w * x)
  out[7] = 2 * (x * z - w * y)
  out[8] = 2 * (y * z + w * x)
  out[9] = 1 - 2 * (x * x + y * y)
  return out
end

--- The rotation vector (axis times angle, the angle in [0, π]) of a rotation matrix: the
-- logarithm map, inverse of `from_rotation_vector`. A pose's covariance is over this vector:
-- `R_true = exp([r]×) · R` gives `r = to_rotation_vector(R_true · Rᵀ)`.
-- @tparam {number,...} r flat 3×3 rotation
-- @treturn number wx
-- @treturn number wy
-- @treturn number wz
function M.to_rotation_vector(r)
  if not flat(r) then r = matrix(r, 1, "to_rotation_vector", scratch_a) end
  local w, x, y, z = M.to_quaternion(r)
  local s = sqrt(x * x + y * y + z * z)
  if s == 0 then return 0, 0, 0 end
  local k = 2 * atan2(s, w) / s
  return k * x, k * y, k * z
end

--- Rotation matrix of a rotation vector (axis times angle): the exponential map `exp([w]×)`,
-- by Rodrigues' formula with a series near zero, so small vectors keep full precision.
-- @tparam number wx
-- @tparam number wy
-- @tparam number wz
-- @tparam[opt] {number,...} out array to fill
-- @treturn {number,...} flat 3×3 rotation
function M.from_rotation_vector(wx, wy, wz, out)
  if type(wx) ~= "number" or type(wy) ~= "number" or type(wz) ~= "number"
    or not flat_out(out) then
    local bad = not is_finite(wx) and 1 or not is_finite(wy) and 2 or not is_finite(wz) and 3
    if bad then
      args.raise(bad, "from_rotation_vector", "finite number expected, got "
        .. args.describe(select(bad, wx, wy, wz)), 2)
    end
    check_out(out, 4, "from_rotation_vector")
    return M.to_nested(M.from_rotation_vector(wx, wy, wz), out)
  end
  out = out or {}
  local t2 = wx * wx + wy * wy + wz * wz
  local a, b
  if t2 < 1e-8 then
    a = 1 - t2 / 6 + t2 * t2 / 120
    b = 0.5 - t2 / 24 + t2 * t2 / 720
  else
    local t = sqrt(t2)
    a = sin(t) / t
    b = (1 - cos(t)) / t2
  end
  -- R = I + a [w]x + b [w]x^2, with [w]x^2 = w w^T - |w|^2 I
  local bxy, bxz, byz = b * wx * wy, b * wx * wz, b * wy * wz
  out[1] = 1 - b * (wy * wy + wz * wz)
  out[2] = bxy - a * wz
  out[3] = bxz + a * wy
  out[4] = bxy + a * wz
  out[5] = 1 - b * (wx * wx + wz * wz)
  out[6] = byz - a * wx
  out[7] = bxz - a * wy
  out[8] = byz + a * wx
  out[9] = 1 - b * (wx * wx + wy * wy)
  return out
end

--- Product `a * b` of two 3×3 matrices.
-- @tparam {number,...} a flat 3×3
-- @tparam {number,...} b flat 3×3
-- @tparam[opt] {number,...} out array to fill (may be `a` or `b`)
-- @treturn {number,...} out
function M.multiply(a, b, out)
  if not (flat(a) and flat(b) and flat_out(out)) then
    local res = binary(M.multiply, "multiply", a, b, out)
    return res
  end
  out = out or {}
  local a1, a2, a3, a4, a5, a6, a7, a8, a9 = a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9]
  local b1, b2, b3, b4, b5, b6, b7, b8, b9 = b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9]
  out[1] = a1 * b1 + a2 * b4 + a3 * b7
  out[2] = a1 * b2 + a2 * b5 + a3 * b8
  out[3] = a1 * b3 + a2 * b6 + a3 * b9
  out[4] = a4 * b1 + a5 * b4 + a6 * b7
  out[5] = a4 * b2 + a5 * b5 + a6 * b8
  out[6] = a4 * b3 + a5 * b6 + a6 * b9
  out[7] = a7 * b1 + a8 * b4 + a9 * b7
  out[8] = a7 * b2 + a8 * b5 + a9 * b8
  out[9] = a7 * b3 + a8 * b6 + a9 * b9
  return out
end

--- Product `a * bᵀ` of two 3×3 matrices (for a rotation b: a times b's inverse).
-- @tparam {number,...} a flat 3×3
-- @tparam {number,...} b flat 3×3
-- @tparam[opt] {number,...} out array to fill (may be `a` or `b`)
-- @treturn {number,...} out
function M.multiply_transpose(a, b, out)
  if not (flat(a) and flat(b) and flat_out(out)) then
    local res = binary(M.multiply_transpose, "multiply_transpose", a, b, out)
    return res
  end
  out = out or {}
  local a1, a2, a3, a4, a5, a6, a7, a8, a9 = a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9]
  local b1, b2, b3, b4, b5, b6, b7, b8, b9 = b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9]
  out[1], out[2], out[3] = a1 * b1 + a2 * b2 + a3 * b3, a1 * b4 + a2 * b5 + a3 * b6,
    a1 * b7 + a2 * b8 + a3 * b9
  out[4], out[5], out[6] = a4 * b1 + a5 * b2 + a6 * b3, a4 * b4 + a5 * b5 + a6 * b6,
    a4 * b7 + a5 * b8 + a6 * b9
  out[7], out[8], out[9] = a7 * b1 + a8 * b2 + a9 * b3, a7 * b4 + a8 * b5 + a9 * b6,
    a7 * b7 + a8 * b8 + a9 * b9
  return out
end

--- Product `aᵀ * b` of two 3×3 matrices (for a rotation a: a's inverse times b).
-- @tparam {number,...} a flat 3×3
-- @tparam {number,...} b flat 3×3
-- @tparam[opt] {number,...} out array to fill (may be `a` or `b`)
-- @treturn {number,...} out
function M.transpose_multiply(a, b, out)
  if not (flat(a) and flat(b) and flat_out(out)) then
    local res = binary(M.transpose_multiply, "transpose_multiply", a, b, out)
    return res
  end
  out = out or {}
  local a1, a2, a3, a4, a5, a6, a7, a8, a9 = a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9]
  local b1, b2, b3, b4, b5, b6, b7, b8, b9 = b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9]
  out[1], out[2], out[3] = a1 * b1 + a4 * b4 + a7 * b7, a1 * b2 + a4 * b5 + a7 * b8,
    a1 * b3 + a4 * b6 + a7 * b9
  out[4], out[5], out[6] = a2 * b1 + a5 * b4 + a8 * b7, a2 * b2 + a5 * b5 + a8 * b8,
    a2 * b3 + a5 * b6 + a8 * b9
  out[7], out[8], out[9] = a3 * b1 + a6 * b4 + a9 * b7, a3 * b2 + a6 * b5 + a9 * b8,
    a3 * b3 + a6 * b6 + a9 * b9
  return out
end

--- Transpose (= inverse) of a rotation.
-- @tparam {number,...} r flat 3×3
-- @tparam[opt] {number,...} out array to fill (may be `r`)
-- @treturn {number,...} out
function M.transpose(r, out)
  if not (flat(r) and flat_out(out)) then
    local res = unary(M.transpose, "transpose", r, out)
    return res
  end
  out = out or {}
  local r2, r3, r4, r6, r7, r8 = r[2], r[3], r[4], r[6], r[7], r[8]
  out[1], out[5], out[9] = r[1], r[5], r[9]
  out[2], out[3], out[4], out[6], out[7], out[8] = r4, r7, r2, r8, r3, r6
  return out
end

--- Geodesic angle between two rotations (the angle of `a^T b`), in [0, π].
-- Computed from the chord `|a - b|_F = 2√2 sin(θ/2)`, which keeps full precision for small
-- angles (the trace formula loses half the digits there).
-- @tparam {number,...} a flat 3×3 rotation
-- @tparam {number,...} b flat 3×3 rotation
-- @treturn number angle in radians
function M.angle(a, b)
  if not (flat(a) and flat(b)) then
    a, b = matrix(a, 1, "angle", scratch_a), matrix(b, 2, "angle", scratch_b)
  end
  local s = 0
  for i = 1, 9 do
    local d = a[i] - b[i]
    s = s + d * d
  end
  local h = sqrt(s / 8)
  if h >= 1 then return math.pi end
  return 2 * asin(h)
end

--- Nearest orthonormal frame to a nearly orthonormal matrix, keeping columns 1 and 2 in their
-- plane: each is turned by half their deviation from a right angle (so neither is preferred),
-- both are made unit, and column 3 becomes their cross product (a proper rotation).
-- @tparam {number,...} r flat 3×3
-- @tparam[opt] {number,...} out array to fill (may be `r`)
-- @treturn {number,...} out
-- @return nil, string when columns 1 and 2 are zero or parallel
function M.orthonormalise(r, out)
  -- (columns 1 and 2 only are read: the flat route takes a third column unset)
  if not (type(r) == "table" and type(r[1]) == "number" and type(r[8]) == "number"
    and flat_out(out)) then
    local res, why = unary(M.orthonormalise, "orthonormalise", r, out)
    return res, why
  end
  local x1, x2, x3 = r[1], r[4], r[7]
  local y1, y2, y3 = r[2], r[5], r[8]
  local nx = sqrt(x1 * x1 + x2 * x2 + x3 * x3)
  local ny = sqrt(y1 * y1 + y2 * y2 + y3 * y3)
  if not (nx > 0 and ny > 0) then return nil, "rotation: zero column" end
  x1, x2, x3 = x1 / nx, x2 / nx, x3 / nx
  y1, y2, y3 = y1 / ny, y2 / ny, y3 / ny
  -- bisector b and half-difference d of the two unit columns are exactly orthogonal
  local b1, b2, b3 = x1 + y1, x2 + y2, x3 + y3
  local d1, d2, d3 = x1 - y1, x2 - y2, x3 - y3
  local nb = sqrt(b1 * b1 + b2 * b2 + b3 * b3)
  local nd = sqrt(d1 * d1 + d2 * d2 + d3 * d3)
  if not (nb > 1e-12 and nd > 1e-12) then
    return nil, "rotation: columns are parallel"
  end
  local k = sqrt(0.5)
  b1, b2, b3 = k * b1 / nb, k * b2 / nb, k * b3 / nb
  d1, d2, d3 = k * d1 / nd, k * d2 / nd, k * d3 / nd
  x1, x2, x3 = b1 + d1, b2 + d2, b3 + d3
  y1, y2, y3 = b1 - d1, b2 - d2, b3 - d3
  out = out or {}
  out[1], out[4], out[7] = x1, x2, x3
  out[2], out[5], out[8] = y1, y2, y3
  out[3] = x2 * y3 - x3 * y2
  out[6] = x3 * y1 - x1 * y3
  out[9] = x1 * y2 - x2 * y1
  return out
end

--- Nested `{{r11, r12, r13}, {r21, r22, r23}, {r31, r32, r33}}` form of a flat rotation, the
-- shape of the public `pose.rotation`.
-- @tparam {number,...} r flat 3×3
-- @tparam[opt] table out nested table to fill
-- @treturn table nested rows
function M.to_nested(r, out)
  if not flat(r) then r = matrix(r, 1, "to_nested", scratch_a) end
  check_out(out, 2, "to_nested")
  return input.nested(r, out)
end

--- Flat form of a nested `rotation[row][col]` table.
-- @tparam table m nested rows
-- @tparam[opt] {number,...} out array to fill
-- @treturn {number,...} flat 3×3
function M.from_nested(m, out)
  local m1, m2, m3 = type(m) == "table" and m[1], type(m) == "table" and m[2],
    type(m) == "table" and m[3]
  if not (type(m1) == "table" and type(m2) == "table" and type(m3) == "table"
    and type(m1[1]) == "number" and type(m3[3]) == "number") or not flat_out(out) then
    m = matrix(m, 1, "from_nested", scratch_a)
    check_out(out, 2, "from_nested")
    m1, m2, m3 = { m[1], m[2], m[3] }, { m[4], m[5], m[6] }, { m[7], m[8], m[9] }
    if out ~= nil and type(out[1]) == "table" then
      return M.to_nested(M.from_nested({ m1, m2, m3 }), out)
    end
  end
  out = out or {}
  out[1], out[2], out[3] = m1[1], m1[2], m1[3]
  out[4], out[5], out[6] = m2[1], m2[2], m2[3]
  out[7], out[8], out[9] = m3[1], m3[2], m3[3]
  return out
end

--- The rotation a pose table carries, flat: its `rotation` (nested rows of finite numbers),
-- else its `quaternion` (`{w =, x =, y =, z =}`, finite and not zero; normalised). What the
-- callers that take a pose of the user's own (a tracking prior, a previous block) read.
-- @tparam any p a pose table, or anything
-- @tparam[opt] {number,...} out array to fill
-- @treturn {number,...} flat 3×3 (out, or a new array)
-- @return nil when p carries neither
function M.of_pose(p, out)
  if type(p) ~= "table" then return nil end
  local m = p.rotation
  if type(m) == "table" and type(m[1]) == "table" and type(m[2]) == "table"
    and type(m[3]) == "table" then
    local r = M.from_nested(m, out)
    local ok = true
    for k = 1, 9 do
      if not is_finite(r[k]) then ok = false end
    end
    if ok then return r end
  end
  local q = p.quaternion
  if type(q) == "table" and is_finite(q.w) and is_finite(q.x) and is_finite(q.y)
    and is_finite(q.z) and q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z > 0 then
    return M.from_quaternion(q.w, q.x, q.y, q.z, out)
  end
  return nil
end

--- A rotation given as a matrix, nested `r[row][col]` or flat row-major, read into `out`
-- (flat), its nine entries checked finite (`tagpose.core.rotation_input.read`).
-- @function read
M.read = input.read

--- How far a flat 3×3 is from a rotation: the largest entry of `R·Rᵀ - I` (in absolute value)
-- and its determinant (`tagpose.core.rotation_input.deviation`).
-- @function deviation
M.deviation = input.deviation

-- Roll, pitch and yaw, ROS's convention: `tagpose.core.rpy`.
local rpy = require("tagpose.core.rpy")

--- Below this `cos(pitch)` `to_rpy` is at gimbal lock (`tagpose.core.rpy.GIMBAL_LOCK`).
M.GIMBAL_LOCK = rpy.GIMBAL_LOCK
--- How far from orthonormal a rotation given to `to_rpy` may be
-- (`tagpose.core.rpy.RPY_TOLERANCE`).
M.RPY_TOLERANCE = rpy.RPY_TOLERANCE
--- Roll, pitch and yaw of a rotation matrix, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (ROS's
-- convention; `tagpose.core.rpy.to_rpy`).
-- @function to_rpy
M.to_rpy = rpy.to_rpy
--- The rotation of roll, pitch and yaw, nested (`tagpose.core.rpy.from_rpy`).
-- @function from_rpy
M.from_rpy = rpy.from_rpy

return M
