--- Lua data files read as data: `return { ... }` of literals, without running anything.
--
-- A camera or layout file written in Lua is a table constructor of literals; reading it this
-- way (a small parser, not `load`) means that a file that never returns, fills memory, calls
-- a function or reads a global cannot do any of it: it is refused, with its line.
--
-- Accepted: `return` followed by one value and an optional `;`; values `nil`, `true`, `false`,
-- decimal numbers with an optional unary minus (`-0.28`, `.5`, `1e-3`), strings (`'...'`,
-- `"..."` with the escapes `\a \b \f \n \r \t \v \\ \" \' \ddd \xXX` and an escaped line end,
-- and long strings `[[...]]`, `[==[...]==]`), and tables `{ ... }` of such values with fields
-- `name = v`, `[literal] = v` and positional `v`, separated by `,` or `;`; comments `--...`
-- and `--[[...]]`. Numbers are read as `compat.decimal` reads them: the same on every VM.
--
-- Refused, with the line: anything else (a call, an operator, a global variable, a function,
-- a loop or any other statement, hexadecimal numerals), duplicate keys (Lua would keep the
-- last one silently), nesting deeper than `MAX_DEPTH`.
--
-- The tokens come from `tagpose.formats.luadata.lexer`; this module parses them, passing the
-- lexer's state record and the `where` table (`where[tbl][key]` = line) between its functions.
-- @module tagpose.formats.luadata

local failure = require("tagpose.formats.failure")
local lexer = require("tagpose.formats.luadata.lexer")

local fail, peek, take, describe = lexer.fail, lexer.peek, lexer.take, lexer.describe

local M = {}

--- Deepest nesting of tables read (deeper input is refused).
M.MAX_DEPTH = 32

local KEYWORDS = {
  ["and"] = "an operator", ["or"] = "an operator", ["not"] = "an operator",
  ["function"] = "a function", ["while"] = "a loop", ["for"] = "a loop", ["repeat"] = "a loop",
  ["until"] = "a loop", ["if"] = "a statement", ["then"] = "a statement",
  ["else"] = "a statement", ["elseif"] = "a statement", ["end"] = "a statement",
  ["local"] = "a statement", ["do"] = "a statement", ["goto"] = "a statement",
  ["break"] = "a statement", ["return"] = "a statement", ["in"] = "a statement",
  ["nil"] = true, ["true"] = true, ["false"] = true,
}

-- refuse a token that is not data, saying what it is
local function not_data(lx, kind, value, at)
  if kind == "name" then
    local what = KEYWORDS[value]
    if type(what) == "string" then fail(lx, what .. " ('" .. value .. "') is not data", at) end
    local k = peek(lx)
    if k == "(" or k == "string" or k == "{" then
      fail(lx, "a call ('" .. value .. "(...)') is not data", at)
    elseif k == "." or k == ":" then
      take(lx)
      local k2, v2 = peek(lx)
      local field = k2 == "name" and v2 or "..."
      fail(lx, "a global variable ('" .. value .. k .. field .. "') is not data", at)
    elseif k == "[" then
      fail(lx, "a global variable ('" .. value .. "[...]') is not data", at)
    end
    fail(lx, "a global variable ('" .. value .. "') is not data", at)
  end
  if kind == "eof" then fail(lx, "a value expected, got the end of the file", at) end
  if kind == "(" then fail(lx, "a parenthesised expression is not data", at) end
  if kind == "..." then fail(lx, "'...' is not data", at) end
  fail(lx, "an operator (" .. describe(kind, value) .. ") is not data", at)
end

-- the key of a field `[literal] = v`, its '[' taken
local function bracket_key(lx)
  local k, kv, kat = take(lx)
  if k == "-" and peek(lx) == "number" then
    local _, num = take(lx)
    k, kv = "number", -num
  end
  if k ~= "number" and k ~= "string" and not (k == "name" and (kv == "true"
    or kv == "false")) then
    if k == "name" and kv == "nil" then fail(lx, "a nil key", kat) end
    not_data(lx, k, kv, kat)
  end
  if k == "name" then kv = kv == "true" end
  if take(lx) ~= "]" then fail(lx, "']' expected after the key", kat) end
  if take(lx) ~= "=" then fail(lx, "'=' expected after the key [" .. tostring(kv) .. "]", kat) end
  return kv
end

-- the key of the next field of a table (`[k] =`, `name =` or the next position), taken
local function field_key(lx, kind, v, at, index)
  if kind == "[" then
    take(lx)
    return bracket_key(lx), index
  end
  if kind == "name" and not KEYWORDS[v] then
    take(lx)
    if peek(lx) == "=" then
      take(lx)
      return v, index
    end
    not_data(lx, "name", v, at)
  end
  return index + 1, index + 1
end

-- after a field: '}' (true), or ',' or ';' (false); anything else is refused
local function field_end(lx, open_line)
  local sep, sv, sat = take(lx)
  if sep == "}" then return true end
  if sep ~= "," and sep ~= ";" then
    if sep == "eof" then fail(lx, "table from line " .. open_line .. " not closed", sat) end
    if sep == "string" or sep == "number" or (sep == "name" and not KEYWORDS[sv])
      or sep == "{" then
      fail(lx, "',' or '}' expected, got " .. describe(sep, sv), sat)
    end
    not_data(lx, sep, sv, sat)
  end
  return false
end

local value

-- the table whose '{' (on line open_line) is taken
local function table_constructor(lx, where, depth, open_line)
  if depth > M.MAX_DEPTH then
    fail(lx, "tables nested deeper than " .. M.MAX_DEPTH, open_line)
  end
  local out, lines = {}, {}
  where[out] = lines
  local index = 0
  while true do
    local kind, v, at = peek(lx)
    if kind == "}" then
      take(lx)
      return out
    end
    local key
    key, index = field_key(lx, kind, v, at, index)
    if type(key) == "number" and key ~= key then fail(lx, "a NaN key", at) end
    if lines[key] then
      fail(lx, "key " .. (type(key) == "string" and "'" .. key .. "'" or "[" .. tostring(key)
        .. "]") .. " given twice (first on line " .. lines[key] .. ")", at)
    end
    lines[key] = at
    out[key] = value(lx, where, depth + 1)
    if field_end(lx, open_line) then return out end
  end
end

-- the value at the lexer's position
value = function(lx, where, depth)
  local kind, v, at = take(lx)
  if kind == "number" or kind == "string" then return v end
  if kind == "{" then return table_constructor(lx, where, depth, at) end
  if kind == "-" then
    local k2, v2 = take(lx)
    if k2 == "number" then return -v2 end
    not_data(lx, "-", nil, at)
  end
  if kind == "name" then
    if v == "nil" then return nil end
    if v == "true" then return true end
    if v == "false" then return false end
  end
  not_data(lx, kind, v, at)
end

-- refuse a chunk that does not start with 'return'
local function not_return(lx, kind, v, at)
  if kind == "eof" then fail(lx, "the file is empty: 'return { ... }' expected", at) end
  if kind == "name" and KEYWORDS[v] == nil then
    local k2 = peek(lx)
    if k2 == "." or k2 == ":" then
      take(lx)
      local k3, v3 = peek(lx)
      v = v .. k2 .. (k3 == "name" and v3 or "...")
    end
    fail(lx, "an assignment or a call ('" .. v .. "') is not data: 'return { ... }' expected", at)
  end
  if kind == "name" and type(KEYWORDS[v]) == "string" then
    fail(lx, KEYWORDS[v] .. " ('" .. v .. "') is not data: 'return { ... }' expected", at)
  end
  fail(lx, "'return { ... }' expected, got " .. describe(kind, v), at)
end

-- the chunk: [shebang] return value [;]
local function parse(text, name)
  local lx = lexer.new(text, name)
  local kind, v, at = take(lx)
  if kind ~= "name" or v ~= "return" then not_return(lx, kind, v, at) end
  local where = {}
  local _, _, value_line = peek(lx)
  local result = value(lx, where, 1)
  if peek(lx) == ";" then take(lx) end
  kind, v, at = take(lx)
  if kind ~= "eof" then
    if kind == "-" or kind == "+" or kind == "*" or kind == "/" or kind == ".." or kind == "^"
      or kind == "%" or kind == "==" or kind == "(" or kind == "[" or kind == "." then
      not_data(lx, kind, v, at)
    end
    fail(lx, "unexpected " .. describe(kind, v) .. " after the returned value", at)
  end
  return result, where, value_line
end

--- Read a Lua data file's text.
-- @tparam string text the file's text
-- @tparam[opt="lua"] string name the file's name, for messages
-- @treturn any the value the file returns
-- @treturn table where each key was: `where[tbl][key]` is the line of the field (`tbl` a table
--   of the value)
-- @treturn int the line where the returned value starts
-- @return nil, string `"name:LINE: reason"` when the text is not data this reader accepts
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
-- @usage
-- local camera, where = luadata.decode("return { fx = 600, fy = 600 }", "camera.lua")
function M.decode(text, name)
  failure.check(text, name, true)
  return failure.protect(parse, text, name or "lua")
end

return M
