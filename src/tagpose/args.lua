--- Argument checks shared by the public entry points.
--
-- Misuse of a public function raises with Lua's own wording, at the caller's level:
-- `bad argument #3 to 'solve' (positive number expected for tag_size, got number -1)`.
-- The helpers here build the pieces of such messages; the entry points raise them.
-- @module tagpose.args

local compat = require("tagpose.compat")

local is_finite = compat.is_finite

local M = {}

--- A short description of a value for an error message: `number -2`, `string abc`, `nil`.
-- @tparam any v
-- @treturn string
function M.describe(v)
  local t = type(v)
  if t == "number" or t == "string" then return t .. " " .. tostring(v) end
  return t
end

--- True for a finite number greater than zero.
-- @tparam any v
-- @treturn boolean
function M.is_positive(v)
  return is_finite(v) and v > 0
end

--- True for a whole number of at least 1 (a count, such as an iteration bound).
-- @tparam any v
-- @treturn boolean
function M.is_count(v)
  return is_finite(v) and v >= 1 and v == math.floor(v)
end

--- Read four corners (`{u, v}` or `{x = u, y = v}` each) into the flat array `out`
-- (`{u1, v1, ..., u4, v4}`).
-- @tparam any corners
-- @tparam {number,...} out array to fill
-- @treturn true|int `true`, or the index of the first corner that is not finite
-- @return false, string when `corners` is not four corners (the misuse, for an error message)
function M.read_corners(corners, out)
  if type(corners) ~= "table" then
    return false, "table of four corners expected, got " .. type(corners)
  end
  if #corners ~= 4 then return false, "four corners expected, got " .. #corners end
  local bad = true
  for i = 1, 4 do
    local c = corners[i]
    if type(c) ~= "table" then
      return false, "corner " .. i .. ": table expected, got " .. type(c)
    end
    local u, v = c[1], c[2]
    if u == nil then u = c.x end
    if v == nil then v = c.y end
    if type(u) ~= "number" or type(v) ~= "number" then
      return false, "corner " .. i .. ": numbers {u, v} or {x =, y =} expected, got "
        .. M.describe(u) .. " and " .. M.describe(v)
    end
    -- finite exactly when u - u is 0 (NaN and ±inf give NaN)
    if bad == true and not (u - u == 0 and v - v == 0) then bad = i end
    out[2 * i - 1], out[2 * i] = u, v
  end
  return bad
end

--- Raise `bad argument #n to 'fname' (message)`.
-- @tparam int n argument position
-- @tparam string fname the public function's name
-- @tparam string message what was expected and what came
-- @tparam int level the stack level to blame, as for `error` (counted from the caller of this
--   function)
function M.raise(n, fname, message, level)
  error("bad argument #" .. n .. " to '" .. fname .. "' (" .. message .. ")", level + 1)
end

return M
