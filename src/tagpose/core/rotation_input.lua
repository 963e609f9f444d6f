--- The checked route of `tagpose.rotation`: the matrices and quaternions a user passes, read.
--
-- The functions of `tagpose.core.rotation` take flat row-major arrays of nine numbers on their
-- fast route (two type checks); anything else comes here: a nested `r[row][col]` matrix (the
-- shape of `pose.rotation`) read flat into a scratch array, a result given back in the shape
-- asked, and misuse raised as `bad argument #n to 'name' (...)` at the caller of the public
-- function. Also the reading of matrices that the pose algebra shares (`read`, `deviation`)
-- and the quaternion normalisation without overflow of every reader (`unit_quaternion`).
-- @module tagpose.core.rotation_input

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")

local sqrt, abs, max = math.sqrt, math.abs, math.max
local is_finite = compat.is_finite

local M = {}

--- A quaternion normalised without overflow or underflow: scaled by its largest component,
-- then divided by its length.
-- @tparam number w finite
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @treturn number|nil w, or nil when the quaternion's length is 1e-6 or less
-- @treturn number x
-- @treturn number y
-- @treturn number z
function M.unit_quaternion(w, x, y, z)
  local m = max(abs(w), abs(x), abs(y), abs(z))
  if not (m > 0) then return nil end
  w, x, y, z = w / m, x / m, y / m, z / m
  local n = sqrt(w * w + x * x + y * y + z * z) -- in [1, 2]
  if not (m * n > 1e-6) then return nil end
  return w / n, x / n, y / n, z / n
end

--- A rotation given as a matrix, nested `r[row][col]` or flat row-major, read into `out`
-- (flat), its nine entries checked finite: `out`, or nil where it is not such a matrix. It does
-- not check that the matrix is a rotation (`deviation`).
-- @tparam any m the matrix
-- @tparam {number,...} out nine numbers to fill
-- @treturn ?{number,...} out, or nil
function M.read(m, out)
  if type(m) ~= "table" then return nil end
  local m1, m2, m3 = m[1], m[2], m[3]
  if type(m1) == "table" then
    if type(m2) ~= "table" or type(m3) ~= "table" then return nil end
    out[1], out[2], out[3] = m1[1], m1[2], m1[3]
    out[4], out[5], out[6] = m2[1], m2[2], m2[3]
    out[7], out[8], out[9] = m3[1], m3[2], m3[3]
  else
    for i = 1, 9 do out[i] = m[i] end
  end
  for i = 1, 9 do
    if not is_finite(out[i]) then return nil end
  end
  return out
end

--- Is m a flat matrix, for the fast route (its first and last entries numbers)?
-- @tparam any m
-- @treturn boolean
function M.flat(m)
  return type(m) == "table" and type(m[1]) == "number" and type(m[9]) == "number"
end

--- Is `out` nil or a flat array, for the fast route?
-- @tparam any out
-- @treturn boolean
function M.flat_out(out)
  return out == nil or (type(out) == "table" and type(out[1]) ~= "table")
end

--- Matrix argument n of fname, flat (into scratch), or raise at the caller of fname.
-- @tparam any m
-- @tparam int n its position
-- @tparam string fname the public function
-- @tparam {number,...} scratch nine numbers to fill
-- @tparam[opt] int depth the helpers between fname and this (0)
-- @treturn {number,...} scratch
function M.matrix(m, n, fname, scratch, depth)
  if M.read(m, scratch) then return scratch end
  args.raise(n, fname, "3x3 matrix expected: nested {{r11, r12, r13}, {r21, r22, r23}, "
    .. "{r31, r32, r33}} or flat {r11, ..., r33} of finite numbers, got " .. args.describe(m)
    .. (type(m) == "table" and " (not nine finite numbers)" or ""), 3 + (depth or 0))
end

--- Check an `out` argument (position n of fname): nil, or a table; raise otherwise.
-- @tparam any out
-- @tparam int n
-- @tparam string fname
-- @tparam[opt] int depth as for `matrix`
function M.check_out(out, n, fname, depth)
  if out ~= nil and type(out) ~= "table" then
    args.raise(n, fname, "table expected for out, got " .. type(out), 3 + (depth or 0))
  end
end

--- The nested form of a flat r, into out's rows (or new ones).
-- @tparam {number,...} r flat 3×3
-- @tparam[opt] table out nested rows to fill
-- @treturn table out
local function nested(r, out)
  out = out or {}
  local r1, r2, r3 = out[1] or {}, out[2] or {}, out[3] or {}
  r1[1], r1[2], r1[3] = r[1], r[2], r[3]
  r2[1], r2[2], r2[3] = r[4], r[5], r[6]
  r3[1], r3[2], r3[3] = r[7], r[8], r[9]
  out[1], out[2], out[3] = r1, r2, r3
  return out
end

M.nested = nested

--- A result r (flat, fresh) in the shape asked: into out (nested or flat), else nested when
-- the first matrix argument was.
-- @tparam ?{number,...} r
-- @tparam ?table out
-- @tparam boolean was_nested
-- @treturn ?table
function M.shaped(r, out, was_nested)
  if r == nil then return nil end
  if out ~= nil then
    if type(out[1]) == "table" then return nested(r, out) end
    for i = 1, 9 do out[i] = r[i] end
    return out
  end
  if was_nested then return nested(r) end
  return r
end

local function is_nested(m)
  return type(m) == "table" and type(m[1]) == "table"
end

local scratch_a, scratch_b = {}, {}

--- f(r, out) through the checked route, for the public function fname (which calls this, never
-- tail-calls it: Lua 5.1 counts a tail call as a level of its own).
-- @tparam function f the fast route
-- @tparam string fname
-- @tparam any r
-- @tparam any out
-- @return f's results, shaped
function M.unary(f, fname, r, out)
  local was_nested = is_nested(r)
  r = M.matrix(r, 1, fname, scratch_a, 1)
  M.check_out(out, 2, fname, 1)
  local res, why = f(r, {})
  if res == nil then return nil, why end
  return M.shaped(res, out, was_nested)
end

--- f(a, b, out) through the checked route (as `unary`).
-- @tparam function f
-- @tparam string fname
-- @tparam any a
-- @tparam any b
-- @tparam any out
-- @treturn table
function M.binary(f, fname, a, b, out)
  local was_nested = is_nested(a)
  a = M.matrix(a, 1, fname, scratch_a, 1)
  b = M.matrix(b, 2, fname, scratch_b, 1)
  M.check_out(out, 3, fname, 1)
  return M.shaped(f(a, b, {}), out, was_nested)
end

--- Quaternion arguments of fname (four numbers, or a table `{w =, x =, y =, z =}` and the
-- next argument as `out`), or raise at its caller.
-- @tparam string fname
-- @tparam any w
-- @tparam any x
-- @tparam any y
-- @tparam any z
-- @tparam any out
-- @return w, x, y, z, out
function M.quaternion_args(fname, w, x, y, z, out)
  if type(w) == "table" then w, x, y, z, out = w.w, w.x, w.y, w.z, x end
  if not (is_finite(w) and is_finite(x) and is_finite(y) and is_finite(z)) then
    args.raise(1, fname, "quaternion expected: four finite numbers w, x, y, z or a table "
      .. "{w =, x =, y =, z =}", 3)
  end
  if not M.unit_quaternion(w, x, y, z) then
    args.raise(1, fname, "quaternion expected, got a zero one", 3)
  end
  M.check_out(out, 5, fname)
  return w, x, y, z, out
end

--- How far a flat 3×3 is from a rotation: the largest entry of `R·Rᵀ - I` (in absolute value)
-- and its determinant (a rotation: 0 and 1).
-- @tparam {number,...} r flat 3×3 (or nested)
-- @treturn number the largest entry of `|R·Rᵀ - I|`
-- @treturn number det R
function M.deviation(r)
  if not M.flat(r) then r = M.matrix(r, 1, "deviation", scratch_a) end
  local worst = 0
  for i = 0, 6, 3 do
    for j = 0, 6, 3 do
      local d = r[i + 1] * r[j + 1] + r[i + 2] * r[j + 2] + r[i + 3] * r[j + 3]
      if i == j then d = d - 1 end
      if d < 0 then d = -d end
      if d > worst then worst = d end
    end
  end
  return worst, r[1] * (r[5] * r[9] - r[6] * r[8]) - r[2] * (r[4] * r[9] - r[6] * r[7])
    + r[3] * (r[4] * r[8] - r[5] * r[7])
end

return M
