--- YAML flow collections: `[a, b]` and `{k: v}`, nested, across any number of lines.
--
-- A cursor (line `li`, column `p`) crosses lines; spaces, tabs, comments and line ends
-- between tokens are skipped, a document marker inside a collection or its missing close
-- is refused. A trailing comma is allowed; an empty entry, a complex key (`?`, or a
-- collection as key) and a block entry (`- `) are not. Functions take the reading state of
-- `tagpose.formats.yaml.scanner` and return the value with the cursor after it.
-- @module tagpose.formats.yaml.flow

local scanner = require("tagpose.formats.yaml.scanner")
local scalar = require("tagpose.formats.yaml.scalar")

local byte, sub, find, char = string.byte, string.sub, string.find, string.char
local fail, is_blank_byte, rtrim_end = scanner.fail, scanner.is_blank_byte, scanner.rtrim_end
local check_depth, record = scanner.check_depth, scanner.record
local resolve, quoted, refuse_indicator = scalar.resolve, scalar.quoted, scalar.refuse_indicator

local SPACE, TAB, HASH, COLON, DASH = scanner.SPACE, scanner.TAB, scanner.HASH, scanner.COLON,
  scanner.DASH
local QUOTE1, QUOTE2, COMMA, BANG, QUESTION = scanner.QUOTE1, scanner.QUOTE2, scanner.COMMA,
  scanner.BANG, scanner.QUESTION
local LBRACKET, RBRACKET, LBRACE, RBRACE = scanner.LBRACKET, scanner.RBRACKET, scanner.LBRACE,
  scanner.RBRACE
local MARKER, NULL = scanner.MARKER, scalar.NULL

local M = {}

-- skip spaces, tabs, comments and line ends from (li, p); the line and column of the next
-- token of the collection opened on line start_line
local function skip(st, li, p, start_line)
  local lines, indent, nlines = st.lines, st.indent, st.nlines
  while true do
    if li > nlines then
      fail(st, "flow collection from line " .. start_line .. " not closed", nlines)
    end
    if indent[li] == MARKER then
      fail(st, "document marker inside the flow collection from line " .. start_line, li)
    end
    local s = lines[li]
    local q = find(s, "[^ \t]", p)
    if q and byte(s, q) == HASH and (q == 1 or is_blank_byte(byte(s, q - 1))) then q = nil end
    if q then return li, q end
    li, p = li + 1, 1
  end
end

-- where the plain scalar from column p of s ends: a flow indicator, ': ' or ' #'
local function plain_stop(s, p)
  local pos = p
  while true do
    local i = find(s, "[,%[%]{}:#]", pos)
    if not i then return #s + 1 end
    local b = byte(s, i)
    if b == COLON then
      local c = byte(s, i + 1)
      if c == nil or c == SPACE or c == TAB or c == COMMA or c == LBRACKET or c == RBRACKET
        or c == LBRACE or c == RBRACE then
        return i
      end
    elseif b == HASH then
      if is_blank_byte(byte(s, i - 1)) then return i end
    else
      return i
    end
    pos = i + 1
  end
end

-- the plain scalar at (li, p): its value and the column after it
local function plain(st, li, p)
  local s = st.lines[li]
  local stop = plain_stop(s, p)
  local e = rtrim_end(s, p, stop - 1)
  return resolve(st, sub(s, p, e), li), stop
end

-- a key of a flow mapping at (li, p): the key and the column after it
local function key_at(st, li, p)
  local b = byte(st.lines[li], p)
  if b == QUOTE1 or b == QUOTE2 then return quoted(st, li, p) end
  if b == LBRACKET or b == LBRACE or b == QUESTION then
    fail(st, "complex mapping keys are not supported", li)
  end
  refuse_indicator(st, b, li)
  if b == BANG then fail(st, "tags on keys are not supported", li) end
  local key, q = plain(st, li, p)
  if key == NULL then fail(st, "a null mapping key is not supported", li) end
  return key, q
end

local node

local function sequence(st, li, p, depth)
  check_depth(st, depth, li)
  local lines = st.lines
  local start = li
  local out = {}
  li, p = skip(st, li, p + 1, start)
  if byte(lines[li], p) == RBRACKET then return out, li, p + 1 end
  while true do
    local item
    local at = li
    item, li, p = node(st, li, p, depth + 1, start)
    out[#out + 1] = item
    record(st, out, #out, at)
    li, p = skip(st, li, p, start)
    local b = byte(lines[li], p)
    if b == RBRACKET then return out, li, p + 1 end
    if b ~= COMMA then
      fail(st, "',' or ']' expected in the flow sequence from line " .. start .. ", got '"
        .. sub(lines[li], p, p + 19) .. "'", li)
    end
    li, p = skip(st, li, p + 1, start)
    if byte(lines[li], p) == RBRACKET then return out, li, p + 1 end -- a trailing comma
  end
end

local function mapping(st, li, p, depth)
  check_depth(st, depth, li)
  local lines = st.lines
  local start = li
  local out = {}
  li, p = skip(st, li, p + 1, start)
  if byte(lines[li], p) == RBRACE then return out, li, p + 1 end
  while true do
    local at = li
    local key
    key, p = key_at(st, li, p)
    if out[key] ~= nil then
      fail(st, "duplicate key '" .. tostring(key) .. "' (first on line " .. st.where[out][key]
        .. ")", li)
    end
    li, p = skip(st, li, p, start)
    if byte(lines[li], p) ~= COLON then
      fail(st, "':' expected after the key '" .. tostring(key) .. "' in the flow mapping from line "
        .. start, li)
    end
    li, p = skip(st, li, p + 1, start)
    local b = byte(lines[li], p)
    local value
    if b == COMMA or b == RBRACE then
      value = NULL
    else
      value, li, p = node(st, li, p, depth + 1, start)
    end
    out[key] = value
    record(st, out, key, at)
    li, p = skip(st, li, p, start)
    b = byte(lines[li], p)
    if b == RBRACE then return out, li, p + 1 end
    if b ~= COMMA then
      fail(st, "',' or '}' expected in the flow mapping from line " .. start .. ", got '"
        .. sub(lines[li], p, p + 19) .. "'", li)
    end
    li, p = skip(st, li, p + 1, start)
    if byte(lines[li], p) == RBRACE then return out, li, p + 1 end
  end
end

-- a node inside the flow collection opened on line start, at (li, p), a token already; the
-- value, then the line and column after it
node = function(st, li, p, depth, start)
  local s = st.lines[li]
  local b = byte(s, p)
  if b == LBRACKET then return sequence(st, li, p, depth) end
  if b == LBRACE then return mapping(st, li, p, depth) end
  if b == QUOTE1 or b == QUOTE2 then
    local v, q = quoted(st, li, p)
    return v, li, q
  end
  if b == HASH then fail(st, "'#' cannot start a plain scalar", li) end
  if b == COMMA or b == RBRACKET or b == RBRACE then
    fail(st, "empty entry in the flow collection from line " .. start, li)
  end
  if b == BANG then
    local tname, q = scalar.tag_at(st, li, p)
    local value
    li, q = skip(st, li, q, start)
    value, li, q = node(st, li, q, depth, start)
    return scalar.apply_tag(st, value, tname, li), li, q
  end
  if b == QUESTION or (b == DASH and (byte(s, p + 1) == SPACE or byte(s, p + 1) == nil)) then
    fail(st, "'" .. char(b) .. "' is not supported in a flow collection", li)
  end
  refuse_indicator(st, b, li)
  local v, q = plain(st, li, p)
  return v, li, q
end

--- A flow collection as a block value, at (li, p) on its `[` or `{`: it must end its last
-- line.
-- @tparam table st the reading state
-- @tparam int li
-- @tparam int p
-- @tparam int depth its nesting depth
-- @return the value
-- @treturn int the line after it
function M.block_value(st, li, p, depth)
  local value, e, q = node(st, li, p, depth, li)
  scanner.expect_rest_blank(st, e, q)
  return value, e + 1
end

return M
