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
-- @module tagpose.luadata

local compat = require("tagpose.compat")

local decimal = compat.decimal
local byte, sub, find, char, concat = string.byte, string.sub, string.find, string.char,
  table.concat

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

local ESCAPES = { a = "\a", b = "\b", f = "\f", n = "\n", r = "\r", t = "\t", v = "\v",
  ["\\"] = "\\", ['"'] = '"', ["'"] = "'" }

local Failure = {}

local function parse(text, name)
  local pos, line, n = 1, 1, #text

  local function fail(reason, at)
    error(setmetatable({ message = name .. ":" .. (at or line) .. ": " .. reason }, Failure), 0)
  end

  -- count the line ends in text[i..j] (\r\n, \n\r, \n and \r each one, as Lua counts them)
  local function count_lines(i, j)
    while true do
      local k = find(text, "[\r\n]", i)
      if not k or k > j then return end
      local c, d = byte(text, k), byte(text, k + 1)
      if k < j and (d == 10 or d == 13) and d ~= c then k = k + 1 end
      line = line + 1
      i = k + 1
    end
  end

  -- the level of a long bracket at position i ("[[" 0, "[=[" 1, ...), or nil
  local function long_level(i)
    local _, e = find(text, "^%[=*%[", i)
    if not e then return nil end
    return e - i - 1, e
  end

  -- a long string or comment from i; returns its text (first line end dropped) and the
  -- position after it
  local function long_bracket(i, what)
    local start = line
    local level, e = long_level(i)
    local close = "]" .. string.rep("=", level) .. "]"
    local j = find(text, close, e + 1, true)
    if not j then fail(what .. " from line " .. start .. " not closed", start) end
    local body_start = e + 1
    local c = byte(text, body_start)
    if c == 13 or c == 10 then
      local d = byte(text, body_start + 1)
      body_start = body_start + (((d == 13 or d == 10) and d ~= c) and 2 or 1)
    end
    count_lines(e + 1, j - 1)
    return sub(text, body_start, j - 1), j + #close
  end

  local function skip()
    while true do
      local q = find(text, "[^ \t\r\n\f\v]", pos)
      if not q then
        count_lines(pos, n)
        pos = n + 1
        return
      end
      count_lines(pos, q - 1)
      pos = q
      if sub(text, q, q + 1) ~= "--" then return end
      if long_level(q + 2) then
        local _
        _, pos = long_bracket(q + 2, "long comment")
      else
        local e = find(text, "[\r\n]", q) or n + 1
        pos = e
      end
    end
  end

  -- the next token: kind ("name", "number", "string", "eof", or the punctuation itself) and
  -- its value; pos moves past it
  local function token()
    skip()
    if pos > n then return "eof" end
    local c = byte(text, pos)
    local s, e = find(text, "^[%a_][%w_]*", pos)
    if s then
      pos = e + 1
      return "name", sub(text, s, e)
    end
    if (c >= 48 and c <= 57) or (c == 46 and find(text, "^%.%d", pos)) then
      local _
      _, e = find(text, "^[%w%.]*", pos)
      -- an exponent's sign: 1e-3
      while (byte(text, e) == 101 or byte(text, e) == 69) and (byte(text, e + 1) == 43
        or byte(text, e + 1) == 45) and not find(text, "^0[xX]", pos) do
        local _, f = find(text, "^[%w%.]*", e + 2)
        e = f
      end
      local numeral = sub(text, pos, e)
      pos = e + 1
      if find(numeral, "^0[xX]") then
        fail("hexadecimal numeral " .. numeral .. ": write the decimal value")
      end
      local v = decimal(numeral)
      if not v then fail("malformed number " .. numeral) end
      return "number", v
    end
    if c == 34 or c == 39 then -- " '
      local parts = {}
      local i = pos + 1
      local quote = char(c)
      while true do
        local j = find(text, "[\\\r\n" .. quote .. "]", i)
        if not j then fail("unfinished string") end
        parts[#parts + 1] = sub(text, i, j - 1)
        local d = byte(text, j)
        if d == c then
          pos = j + 1
          return "string", concat(parts)
        elseif d == 10 or d == 13 then
          fail("unfinished string (a line end inside quotes)")
        end
        local x = sub(text, j + 1, j + 1)
        if ESCAPES[x] then
          parts[#parts + 1] = ESCAPES[x]
          i = j + 2
        elseif x == "\n" or x == "\r" then
          parts[#parts + 1] = "\n"
          local y = byte(text, j + 2)
          i = j + 2
          if (y == 10 or y == 13) and y ~= byte(x) then i = i + 1 end
          line = line + 1
        elseif x == "x" then
          local hex = sub(text, j + 2, j + 3)
          if not find(hex, "^%x%x$") then fail("bad escape \\x" .. hex) end
          parts[#parts + 1] = char(tonumber(hex, 16))
          i = j + 4
        elseif find(x, "^%d$") then
          local _, f = find(text, "^%d%d?%d?", j + 1)
          local v = tonumber(sub(text, j + 1, f))
          if v > 255 then fail("escape \\" .. v .. " is too large") end
          parts[#parts + 1] = char(v)
          i = f + 1
        else
          fail("escape \\" .. x .. " is not read (write the character or \\ddd)")
        end
      end
    end
    if c == 91 and long_level(pos) then -- [[
      local v
      v, pos = long_bracket(pos, "long string")
      return "string", v
    end
    -- punctuation, operators: the longest of Lua's
    local three = sub(text, pos, pos + 2)
    if three == "..." then
      pos = pos + 3
      return three
    end
    local two = sub(text, pos, pos + 1)
    if two == ".." or two == "==" or two == "~=" or two == "<=" or two == ">=" or two == "//"
      or two == "::" or two == "<<" or two == ">>" then
      pos = pos + 2
      return two
    end
    pos = pos + 1
    return char(c)
  end

  -- one token of lookahead
  local peeked, peeked_value, peeked_line
  local function peek()
    if not peeked then
      peeked, peeked_value = token()
      peeked_line = line
    end
    return peeked, peeked_value, peeked_line
  end
  local function take()
    local k, v, l = peek()
    peeked = nil
    return k, v, l
  end

  local function describe(kind, value)
    if kind == "eof" then return "the end of the file" end
    if kind == "name" or kind == "number" then return "'" .. tostring(value) .. "'" end
    if kind == "string" then return "a string" end
    return "'" .. kind .. "'"
  end

  local function not_data(kind, value, at)
    if kind == "name" then
      local what = KEYWORDS[value]
      if type(what) == "string" then fail(what .. " ('" .. value .. "') is not data", at) end
      local k = peek()
      if k == "(" or k == "string" or k == "{" then
        fail("a call ('" .. value .. "(...)') is not data", at)
      elseif k == "." or k == ":" then
        take()
        local k2, v2 = peek()
        local field = k2 == "name" and v2 or "..."
        fail("a global variable ('" .. value .. k .. field .. "') is not data", at)
      elseif k == "[" then
        fail("a global variable ('" .. value .. "[...]') is not data", at)
      end
      fail("a global variable ('" .. value .. "') is not data", at)
    end
    if kind == "eof" then fail("a value expected, got the end of the file", at) end
    if kind == "(" then fail("a parenthesised expression is not data", at) end
    if kind == "..." then fail("'...' is not data", at) end
    fail("an operator (" .. describe(kind, value) .. ") is not data", at)
  end

  local where = {}

  local value

  local function table_constructor(depth, open_line)
    if depth > M.MAX_DEPTH then fail("tables nested deeper than " .. M.MAX_DEPTH, open_line) end
    local out, seen, lines = {}, {}, {}
    where[out] = lines
    local index = 0
    while true do
      local kind, v, at = peek()
      if kind == "}" then
        take()
        return out
      end
      local key
      if kind == "[" then
        take()
        local k, kv, kat = take()
        if k == "-" and peek() == "number" then
          local _, num = take()
          k, kv = "number", -num
        end
        if k ~= "number" and k ~= "string" and not (k == "name" and (kv == "true"
          or kv == "false")) then
          if k == "name" and kv == "nil" then fail("a nil key", kat) end
          not_data(k, kv, kat)
        end
        if k == "name" then kv = kv == "true" end
        key = kv
        if take() ~= "]" then fail("']' expected after the key", kat) end
        if take() ~= "=" then fail("'=' expected after the key [" .. tostring(kv) .. "]", kat) end
      elseif kind == "name" and not KEYWORDS[v] then
        take()
        local k2 = peek()
        if k2 == "=" then
          take()
          key = v
        else
          not_data("name", v, at)
        end
      else
        index = index + 1
        key = index
      end
      if type(key) == "number" and key ~= key then fail("a NaN key", at) end
      if seen[key] then
        fail("key " .. (type(key) == "string" and "'" .. key .. "'" or "[" .. tostring(key) .. "]")
          .. " given twice (first on line " .. seen[key] .. ")", at)
      end
      seen[key] = at
      lines[key] = at
      out[key] = value(depth + 1)
      local sep, sv, sat = take()
      if sep == "}" then return out end
      if sep ~= "," and sep ~= ";" then
        if sep == "eof" then fail("table from line " .. open_line .. " not closed", sat) end
        if sep == "string" or sep == "number" or (sep == "name" and not KEYWORDS[sv])
          or sep == "{" then
          fail("',' or '}' expected, got " .. describe(sep, sv), sat)
        end
        not_data(sep, sv, sat)
      end
    end
  end

  value = function(depth)
    local kind, v, at = take()
    if kind == "number" or kind == "string" then return v end
    if kind == "{" then return table_constructor(depth, at) end
    if kind == "-" then
      local k2, v2 = take()
      if k2 == "number" then return -v2 end
      not_data("-", nil, at)
    end
    if kind == "name" then
      if v == "nil" then return nil end
      if v == "true" then return true end
      if v == "false" then return false end
    end
    not_data(kind, v, at)
  end

  -- the chunk: [shebang] return value [;]
  if byte(text, 1) == 35 then pos = (find(text, "[\r\n]") or n + 1) end
  local kind, v, at = take()
  if kind ~= "name" or v ~= "return" then
    if kind == "eof" then fail("the file is empty: 'return { ... }' expected", at) end
    if kind == "name" and KEYWORDS[v] == nil then
      local k2 = peek()
      if (k2 == "." or k2 == ":") then
        take()
        local k3, v3 = peek()
        v = v .. k2 .. (k3 == "name" and v3 or "...")
      end
      fail("an assignment or a call ('" .. v .. "') is not data: 'return { ... }' expected", at)
    end
    if kind == "name" and type(KEYWORDS[v]) == "string" then
      fail(KEYWORDS[v] .. " ('" .. v .. "') is not data: 'return { ... }' expected", at)
    end
    fail("'return { ... }' expected, got " .. describe(kind, v), at)
  end
  local _, _, value_line = peek()
  local result = value(1)
  if peek() == ";" then take() end
  kind, v, at = take()
  if kind ~= "eof" then
    if kind == "-" or kind == "+" or kind == "*" or kind == "/" or kind == ".." or kind == "^"
      or kind == "%" or kind == "==" or kind == "(" or kind == "[" or kind == "." then
      not_data(kind, v, at)
    end
    fail("unexpected " .. describe(kind, v) .. " after the returned value", at)
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
  if type(text) ~= "string" then
    error("bad argument #1 to 'decode' (string expected, got " .. type(text) .. ")", 2)
  end
  if name ~= nil and type(name) ~= "string" then
    error("bad argument #2 to 'decode' (string expected, got " .. type(name) .. ")", 2)
  end
  local ok, value, where, value_line = pcall(parse, text, name or "lua")
  if ok then return value, where, value_line end
  if getmetatable(value) == Failure then return nil, value.message end
  error(value, 0)
end

return M
