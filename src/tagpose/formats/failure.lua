--- How the file readers refuse a text: a refusal is raised as a `Failure` table
-- `{message = "name:LINE: reason"}` from wherever the reader finds the fault, and the reader's
-- `decode` turns it into `nil, message` (`protect`); any other error (a bug) goes on as it was
-- raised. Used by the JSON, XML, YAML and Lua data readers, WPILib field maps and calibration
-- files; each catches its own refusals, so one reader's never reaches another's caller.
-- @module tagpose.formats.failure

local M = {}

--- The metatable of the refusals raised while reading.
M.Failure = {}

local Failure = M.Failure

--- Refuse the text: raise a `Failure` whose message is `message` as it is.
-- @tparam string message
function M.raise(message)
  error(setmetatable({ message = message }, Failure), 0)
end

local function finish(ok, result, ...)
  if ok then return result, ... end
  if getmetatable(result) == Failure then return nil, result.message end
  error(result, 0)
end

--- Call `f(...)`: what it returns, or `nil, message` when it raised a `Failure`; any other
-- error is raised again as it was.
-- @tparam function f
-- @param ... its arguments
-- @return what `f` returns
-- @return nil, string the refusal's message
function M.protect(f, ...)
  return finish(pcall(f, ...))
end

--- Check a `decode(text, name, ...)`'s first two arguments, raising the misuse at the caller
-- of the function that called `check` (which must not call it as a tail call): `bad argument
-- #1 to 'decode' (string expected, got T)` when `text` is not a string, `#2` when `name` is not
-- one (nor nil, when `optional`).
-- @tparam any text
-- @tparam any name
-- @tparam[opt] boolean optional whether `name` may be nil
function M.check(text, name, optional)
  if type(text) ~= "string" then
    error("bad argument #1 to 'decode' (string expected, got " .. type(text) .. ")", 3)
  end
  if type(name) ~= "string" and not (optional and name == nil) then
    error("bad argument #2 to 'decode' (string expected, got " .. type(name) .. ")", 3)
  end
end

return M
