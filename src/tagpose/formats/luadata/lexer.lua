--- The tokens of a Lua data file, with one token of lookahead and the line of each.
--
-- `new` returns the lexer's state record, which the parser (`tagpose.formats.luadata`) passes to
-- every function:
--
--     {
--       text = string, n = #text, name = string,  -- the file and its name, for messages
--       pos = int,        -- the next byte to read (1-based)
--       line = int,       -- the line of pos (line ends \r\n, \n\r, \n, \r each count one)
--       peeked = kind or nil, peeked_value =, peeked_line = int,  -- the lookahead
--     }
--
-- A token is a kind — `"name"`, `"number"`, `"string"`, `"eof"` or the punctuation itself
-- (the longest of Lua's: `"..."`, `"=="`, `"{"`, ...) — and a value for names, numbers and
-- strings. Numbers are read by `compat.decimal` (the same on every VM); hexadecimal numerals
-- are refused. Strings take the escapes `\a \b \f \n \r \t \v \\ \" \' \ddd \xXX` and an
-- escaped line end; long strings and comments any level of `[==[`. Refusals are raised as a
-- `Failure` table `{message = "name:LINE: reason"}`. Everything is linear in the text.
-- @module tagpose.formats.luadata.lexer

local compat = require("tagpose.core.compat")
local failure = require("tagpose.formats.failure")

local decimal = compat.decimal
local byte, sub, find, char, concat, rep = string.byte, string.sub, string.find, string.char,
  table.concat, string.rep

local M = {}

--- The metatable of the refusals raised while reading (`tagpose.formats.failure.Failure`).
M.Failure = failure.Failure

local CR, LF, HASH, QUOTE2, QUOTE1, LBRACKET = 13, 10, 35, 34, 39, 91

local ESCAPES = { a = "\a", b = "\b", f = "\f", n = "\n", r = "\r", t = "\t", v = "\v",
  ["\\"] = "\\", ['"'] = '"', ["'"] = "'" }

--- Refuse the file: raise `"name:LINE: reason"` (LINE `at`, or the lexer's line).
-- @tparam table lx the lexer
-- @tparam string reason
-- @tparam[opt] int at the line
function M.fail(lx, reason, at)
  failure.raise(lx.name .. ":" .. (at or lx.line) .. ": " .. reason)
end

local fail = M.fail

--- A lexer at the start of a file's text (after a `#` first line, as Lua skips it).
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table the lexer
function M.new(text, name)
  local n = #text
  local pos = 1
  if byte(text, 1) == HASH then pos = (find(text, "[\r\n]") or n + 1) end
  return { text = text, n = n, name = name, pos = pos, line = 1, peeked = nil,
    peeked_value = nil, peeked_line = nil }
end

-- count the line ends in text[i..j] (\r\n, \n\r, \n and \r each one, as Lua counts them),
-- looking at those bytes only: a search for the next line end in the whole text would scan
-- the rest of a long line at every token (quadratic in the length of the line)
local function count_lines(lx, i, j)
  if j < i then return end
  local s = sub(lx.text, i, j)
  local k = find(s, "[\r\n]")
  local m = #s
  while k do
    local c, d = byte(s, k), byte(s, k + 1)
    if k < m and (d == LF or d == CR) and d ~= c then k = k + 1 end
    lx.line = lx.line + 1
    k = find(s, "[\r\n]", k + 1)
  end
end

-- the level of a long bracket at position i ("[[" 0, "[=[" 1, ...) and its last position,
-- or nil
local function long_level(text, i)
  local _, e = find(text, "^%[=*%[", i)
  if not e then return nil end
  return e - i - 1, e
end

-- a long string or comment from i; returns its text (first line end dropped) and the
-- position after it
local function long_bracket(lx, i, what)
  local text = lx.text
  local start = lx.line
  local level, e = long_level(text, i)
  local close = "]" .. rep("=", level) .. "]"
  local j = find(text, close, e + 1, true)
  if not j then fail(lx, what .. " from line " .. start .. " not closed", start) end
  local body_start = e + 1
  local c = byte(text, body_start)
  if c == CR or c == LF then
    local d = byte(text, body_start + 1)
    body_start = body_start + (((d == CR or d == LF) and d ~= c) and 2 or 1)
  end
  count_lines(lx, e + 1, j - 1)
  return sub(text, body_start, j - 1), j + #close
end

-- skip spaces, line ends and comments
local function skip(lx)
  local text, n = lx.text, lx.n
  while true do
    local q = find(text, "[^ \t\r\n\f\v]", lx.pos)
    if not q then
      count_lines(lx, lx.pos, n)
      lx.pos = n + 1
      return
    end
    count_lines(lx, lx.pos, q - 1)
    lx.pos = q
    if sub(text, q, q + 1) ~= "--" then return end
    if long_level(text, q + 2) then
      local _
      _, lx.pos = long_bracket(lx, q + 2, "long comment")
    else
      lx.pos = find(text, "[\r\n]", q) or n + 1
    end
  end
end

-- the numeral at lx.pos (a digit, or '.' and a digit)
local function number(lx)
  local text, pos = lx.text, lx.pos
  local _, e = find(text, "^[%w%.]*", pos)
  -- an exponent's sign: 1e-3
  while (byte(text, e) == 101 or byte(text, e) == 69) and (byte(text, e + 1) == 43
    or byte(text, e + 1) == 45) and not find(text, "^0[xX]", pos) do
    local _, f = find(text, "^[%w%.]*", e + 2)
    e = f
  end
  local numeral = sub(text, pos, e)
  lx.pos = e + 1
  if find(numeral, "^0[xX]") then
    fail(lx, "hexadecimal numeral " .. numeral .. ": write the decimal value")
  end
  local v = decimal(numeral)
  if not v then fail(lx, "malformed number " .. numeral) end
  return "number", v
end

-- the escape whose backslash is at j: its text and the position after it
local function escape(lx, j)
  local text = lx.text
  local x = sub(text, j + 1, j + 1)
  if ESCAPES[x] then return ESCAPES[x], j + 2 end
  if x == "\n" or x == "\r" then
    local y = byte(text, j + 2)
    local i = j + 2
    if (y == LF or y == CR) and y ~= byte(x) then i = i + 1 end
    lx.line = lx.line + 1
    return "\n", i
  end
  if x == "x" then
    local hex = sub(text, j + 2, j + 3)
    if not find(hex, "^%x%x$") then fail(lx, "bad escape \\x" .. hex) end
    return char(tonumber(hex, 16)), j + 4
  end
  if find(x, "^%d$") then
    local _, f = find(text, "^%d%d?%d?", j + 1)
    local v = tonumber(sub(text, j + 1, f))
    if v > 255 then fail(lx, "escape \\" .. v .. " is too large") end
    return char(v), f + 1
  end
  fail(lx, "escape \\" .. x .. " is not read (write the character or \\ddd)")
end

-- the quoted string at lx.pos, its quote c
local function quoted(lx, c)
  local text = lx.text
  local parts = {}
  local i = lx.pos + 1
  local stops = "[\\\r\n" .. char(c) .. "]"
  while true do
    local j = find(text, stops, i)
    if not j then fail(lx, "unfinished string") end
    parts[#parts + 1] = sub(text, i, j - 1)
    local d = byte(text, j)
    if d == c then
      lx.pos = j + 1
      return "string", concat(parts)
    elseif d == LF or d == CR then
      fail(lx, "unfinished string (a line end inside quotes)")
    end
    local part
    part, i = escape(lx, j)
    parts[#parts + 1] = part
  end
end

-- punctuation and operators at lx.pos, its first byte c: the longest of Lua's
local function punctuation(lx, c)
  local text, pos = lx.text, lx.pos
  local three = sub(text, pos, pos + 2)
  if three == "..." then
    lx.pos = pos + 3
    return three
  end
  local two = sub(text, pos, pos + 1)
  if two == ".." or two == "==" or two == "~=" or two == "<=" or two == ">=" or two == "//"
    or two == "::" or two == "<<" or two == ">>" then
    lx.pos = pos + 2
    return two
  end
  lx.pos = pos + 1
  return char(c)
end

-- the next token: its kind and value; lx.pos moves past it
local function token(lx)
  skip(lx)
  local text, pos = lx.text, lx.pos
  if pos > lx.n then return "eof" end
  local c = byte(text, pos)
  local s, e = find(text, "^[%a_][%w_]*", pos)
  if s then
    lx.pos = e + 1
    return "name", sub(text, s, e)
  end
  if (c >= 48 and c <= 57) or (c == 46 and find(text, "^%.%d", pos)) then return number(lx) end
  if c == QUOTE2 or c == QUOTE1 then return quoted(lx, c) end
  if c == LBRACKET and long_level(text, pos) then
    local v
    v, lx.pos = long_bracket(lx, pos, "long string")
    return "string", v
  end
  return punctuation(lx, c)
end

--- The next token, without taking it.
-- @tparam table lx the lexer
-- @treturn string its kind
-- @return its value
-- @treturn int its line (the line where it ends)
function M.peek(lx)
  if not lx.peeked then
    lx.peeked, lx.peeked_value = token(lx)
    lx.peeked_line = lx.line
  end
  return lx.peeked, lx.peeked_value, lx.peeked_line
end

--- The next token, taken.
-- @tparam table lx the lexer
-- @treturn string its kind
-- @return its value
-- @treturn int its line
function M.take(lx)
  local k, v, l = M.peek(lx)
  lx.peeked = nil
  return k, v, l
end

--- A token as a message names it: `'x'`, `a string`, `the end of the file`.
-- @tparam string kind
-- @param value
-- @treturn string
function M.describe(kind, value)
  if kind == "eof" then return "the end of the file" end
  if kind == "name" or kind == "number" then return "'" .. tostring(value) .. "'" end
  if kind == "string" then return "a string" end
  return "'" .. kind .. "'"
end

return M
