--- A small JSON reader for the files users have (OpenCV FileStorage JSON, WPILib field maps),
-- with the line of every key and item, and the line of what it refuses.
--
-- It reads RFC 8259 JSON: objects, arrays, strings (escapes `\" \\ \/ \b \f \n \r \t
-- \uXXXX`, surrogate pairs joined into UTF-8), numbers, `true`, `false`, `null`. Two things
-- OpenCV's FileStorage writes in its JSON are read as well, since neither changes what any
-- JSON text means: `//` comments to the end of the line, and the escape `\'`. A UTF-8
-- byte-order mark before the value is skipped.
--
-- Refused, with the line: anything else (trailing commas, single quotes, unquoted keys,
-- control characters in strings, a lone surrogate, leading zeros), a key given twice in one
-- object, a number beyond the range of doubles, OpenCV's `.Nan` and `.Inf` (nothing downstream
-- must meet them), content after the value, and nesting deeper than `MAX_DEPTH`.
--
-- Values: an object is a Lua table by key (keys stay strings: `"1"` is not `1`), an array a
-- Lua array, `null` the value `NULL` (or the caller's own, so that arrays have no holes and a
-- key given as null is still seen), numbers Lua numbers, the same on every VM
-- (`tagpose.core.compat.decimal`). The reader runs in time linear in the text and calls no
-- code it reads.
-- @module tagpose.formats.json

local compat = require("tagpose.core.compat")
local failure = require("tagpose.formats.failure")

local byte, sub, find, char = string.byte, string.sub, string.find, string.char
local decimal, is_finite, utf8_char = compat.decimal, compat.is_finite, compat.utf8_char

local M = {}

--- The value of `null` (a unique table; compare with `==`), unless the caller gives another.
M.NULL = setmetatable({}, { __tostring = function() return "null" end })

--- Deepest nesting of objects and arrays read (deeper input is refused).
M.MAX_DEPTH = 64

-- the bytes the reader looks at
local QUOTE, BACKSLASH, SLASH, NEWLINE, CR = 34, 92, 47, 10, 13
local LBRACE, RBRACE, LBRACKET, RBRACKET, COLON, COMMA = 123, 125, 91, 93, 58, 44
local MINUS, PLUS, DOT, ZERO = 45, 43, 46, 48

local ESCAPES = { [34] = '"', [92] = "\\", [47] = "/", [98] = "\b", [102] = "\f",
  [110] = "\n", [114] = "\r", [116] = "\t", [39] = "'" }

local function fail(st, reason, at)
  failure.raise(st.name .. ":" .. (at or st.line) .. ": " .. reason)
end

-- a character of the text for a message
local function shown(st, pos)
  local c = sub(st.text, pos, pos)
  if c == "" then return "the end of the text" end
  if find(c, "^[%w%p]$") then return "'" .. c .. "'" end
  return ("byte %d"):format(byte(c))
end

-- step over white space and // comments, counting lines; the position of what follows
local function skip(st, pos)
  local text = st.text
  while true do
    local b = byte(text, pos)
    if b == NEWLINE then
      st.line = st.line + 1
      pos = pos + 1
    elseif b == CR then
      if byte(text, pos + 1) ~= NEWLINE then st.line = st.line + 1 end
      pos = pos + 1
    elseif b == 32 or b == 9 then
      local _, e = find(text, "^[ \t]+", pos)
      pos = e + 1
    elseif b == SLASH and byte(text, pos + 1) == SLASH then
      local e = find(text, "[\r\n]", pos + 2)
      pos = e or #text + 1
    else
      return pos
    end
  end
end

-- the code point of the \uXXXX at pos (the backslash), or a refusal
local function hex4(st, pos)
  local h = sub(st.text, pos + 2, pos + 5)
  if not find(h, "^%x%x%x%x$") then fail(st, "\\u needs four hexadecimal digits") end
  return tonumber(h, 16)
end

-- a string starting at the quote at pos; the string and the position after it
local function read_string(st, pos)
  local text = st.text
  local parts, n = {}, 0
  local i = pos + 1
  while true do
    local j = find(text, "[%c\"\\]", i)
    while j and byte(text, j) == 127 do j = find(text, "[%c\"\\]", j + 1) end -- DEL is text
    if not j then fail(st, "a string is not closed") end
    if j > i then n = n + 1; parts[n] = sub(text, i, j - 1) end
    local b = byte(text, j)
    if b == QUOTE then return table.concat(parts), j + 1 end
    if b ~= BACKSLASH then
      fail(st, ("control character (byte %d) in a string: escape it"):format(b))
    end
    local e = byte(text, j + 1)
    if e == 117 then -- u
      local cp = hex4(st, j)
      i = j + 6
      if cp >= 0xD800 and cp <= 0xDBFF then
        if sub(text, i, i + 1) ~= "\\u" then fail(st, "a lone UTF-16 surrogate in \\u") end
        local lo = hex4(st, i)
        if lo < 0xDC00 or lo > 0xDFFF then fail(st, "a lone UTF-16 surrogate in \\u") end
        cp = 0x10000 + (cp - 0xD800) * 0x400 + (lo - 0xDC00)
        i = i + 6
      elseif cp >= 0xDC00 and cp <= 0xDFFF then
        fail(st, "a lone UTF-16 surrogate in \\u")
      end
      n = n + 1; parts[n] = utf8_char(cp)
    else
      local c = e and ESCAPES[e]
      if not c then fail(st, "unknown escape \\" .. sub(text, j + 1, j + 1) .. " in a string") end
      n = n + 1; parts[n] = c
      i = j + 2
    end
  end
end

-- the digits of a number at pos: the position after them (refused when there are none)
local function digits(st, pos)
  local _, e = find(st.text, "^%d+", pos)
  if not e then fail(st, "a digit expected in a number, got " .. shown(st, pos)) end
  return e + 1
end

-- a number starting at pos; the number and the position after it
local function read_number(st, pos)
  local text = st.text
  local i = pos
  if byte(text, i) == MINUS then i = i + 1 end
  if sub(text, i, i + 3):lower() == ".inf" or sub(text, i, i + 3):lower() == ".nan" then
    fail(st, "'" .. sub(text, pos, i + 3) .. "' (not a number or infinite) is refused")
  end
  if byte(text, i) == ZERO then
    i = i + 1
    if find(text, "^%d", i) then fail(st, "a number with a leading zero") end
  else
    i = digits(st, i)
  end
  if byte(text, i) == DOT then i = digits(st, i + 1) end
  local b = byte(text, i)
  if b == 101 or b == 69 then -- e E
    i = i + 1
    b = byte(text, i)
    if b == PLUS or b == MINUS then i = i + 1 end
    i = digits(st, i)
  end
  local s = sub(text, pos, i - 1)
  local v = decimal(s)
  if not is_finite(v) then fail(st, "number " .. s .. " is beyond the range of doubles") end
  return v, i
end

local read_value

-- an object or array opening at pos; the table and the position after it
local function read_container(st, pos, depth)
  local text, where = st.text, st.where
  local object = byte(text, pos) == LBRACE
  local close = object and RBRACE or RBRACKET
  if depth >= st.max_depth then
    fail(st, "nesting deeper than " .. st.max_depth .. " levels")
  end
  local t, lines, n = {}, {}, 0
  where[t] = lines
  pos = skip(st, pos + 1)
  if byte(text, pos) == close then return t, pos + 1 end
  while true do
    local at, key = st.line
    if object then
      if byte(text, pos) ~= QUOTE then
        fail(st, "a key (a string in double quotes) expected, got " .. shown(st, pos))
      end
      key, pos = read_string(st, pos)
      if t[key] ~= nil then
        fail(st, "duplicate key '" .. key .. "' (first on line " .. lines[key] .. ")")
      end
      pos = skip(st, pos)
      if byte(text, pos) ~= COLON then fail(st, "':' expected, got " .. shown(st, pos)) end
      pos = skip(st, pos + 1)
      at = st.line
    else
      n = n + 1
      key = n
    end
    local v
    v, pos = read_value(st, pos, depth + 1)
    t[key], lines[key] = v, at
    pos = skip(st, pos)
    local b = byte(text, pos)
    if b == close then return t, pos + 1 end
    if b ~= COMMA then
      fail(st, "',' or '" .. char(close) .. "' expected, got " .. shown(st, pos))
    end
    pos = skip(st, pos + 1)
    if byte(text, pos) == close then fail(st, "a trailing comma before '" .. char(close) .. "'") end
  end
end

local LITERALS = { t = "true", f = "false", n = "null" }

-- the value starting at pos (no white space before it); the value and the position after it
function read_value(st, pos, depth)
  local text = st.text
  local b = byte(text, pos)
  if b == LBRACE or b == LBRACKET then return read_container(st, pos, depth) end
  if b == QUOTE then return read_string(st, pos) end
  if b == MINUS or b == DOT or (b and b >= ZERO and b <= ZERO + 9) then
    return read_number(st, pos)
  end
  local word = b and LITERALS[char(b)]
  if word and sub(text, pos, pos + #word - 1) == word then
    local v = true
    if word == "false" then v = false elseif word == "null" then v = st.null end
    return v, pos + #word
  end
  if b == nil then fail(st, "a value expected, got the end of the text") end
  local token = text:match("^[%w_.+-]+", pos)
  fail(st, "a value expected, got " .. (token and ("'" .. sub(token, 1, 40) .. "'")
    or shown(st, pos)))
end

--- Decode a JSON text.
-- @tparam string text
-- @tparam[opt="json"] string name the file's name, for messages
-- @param[opt=NULL] null the value `null` decodes to (not nil)
-- @treturn any the value: a table for an object or array, a string, number, boolean or `null`
-- @treturn table where each key was read: `where[container][key]` is the line of an object's
--   key or of an array's item (`container` a table of the value)
-- @return nil, string `"name:LINE: reason"` when the text is not JSON this reader accepts
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
-- @usage
-- local doc, where = json.decode('{"tags": [{"ID": 1}]}', "field.json")
-- print(doc.tags[1].ID, where[doc.tags][1]) --> 1 1
function M.decode(text, name, null)
  failure.check(text, name, true)
  if null == nil then null = M.NULL end
  local st = { text = text, name = name or "json", line = 1, where = {}, null = null,
    max_depth = M.MAX_DEPTH }
  return failure.protect(function()
    local pos = 1
    if sub(text, 1, 3) == "\239\187\191" then pos = 4 end
    pos = skip(st, pos)
    if pos > #text then fail(st, "no value: the text is empty") end
    local v
    v, pos = read_value(st, pos, 0)
    pos = skip(st, pos)
    if pos <= #text then
      fail(st, "unexpected content after the value: " .. shown(st, pos))
    end
    return v, st.where
  end)
end

return M
