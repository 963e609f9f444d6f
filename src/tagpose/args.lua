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
