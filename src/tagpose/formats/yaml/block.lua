--- YAML block collections: mappings nested by indentation and sequences of `- item`.
--
-- A block mapping is a run of `key: value` lines at one indentation; a block sequence a run
-- of `- ` entries, which may also sit at the indentation of the key that owns them. A value
-- is on its key's line (a scalar, a quoted scalar, a flow collection of
-- `tagpose.formats.yaml.flow`, optionally tagged) or on the following, deeper lines. Functions
-- take the reading state of `tagpose.formats.yaml.scanner` and return the value with the line
-- after it; `document` reads the whole document.
-- @module tagpose.formats.yaml.block

local scanner = require("tagpose.formats.yaml.scanner")
local scalar = require("tagpose.formats.yaml.scalar")
local flow = require("tagpose.formats.yaml.flow")

local byte, sub, find = string.byte, string.sub, string.find
local fail, is_blank_byte, rtrim_end = scanner.fail, scanner.is_blank_byte, scanner.rtrim_end
local check_depth, record, content_from = scanner.check_depth, scanner.record,
  scanner.content_from
local resolve, quoted, refuse_indicator = scalar.resolve, scalar.quoted, scalar.refuse_indicator

local SPACE, TAB, HASH, COLON, DASH = scanner.SPACE, scanner.TAB, scanner.HASH, scanner.COLON,
  scanner.DASH
local QUOTE1, QUOTE2, BANG, QUESTION = scanner.QUOTE1, scanner.QUOTE2, scanner.BANG,
  scanner.QUESTION
local LBRACKET, LBRACE = scanner.LBRACKET, scanner.LBRACE
local NULL = scalar.NULL

local M = {}

-- true for "- " or "-" at the end of line li, at column p
local function is_entry(st, li, p)
  local s = st.lines[li]
  if byte(s, p) ~= DASH then return false end
  local c = byte(s, p + 1)
  if c == TAB then fail(st, "tab after '-' (YAML indents with spaces)", li) end
  return c == nil or c == SPACE
end

-- "? " at column p of s: a complex key
local function is_complex_key(s, p, b)
  return b == QUESTION and (byte(s, p + 1) == SPACE or p == #s)
end

-- the quoted key of a block mapping entry at (li, p), or nil: the key and the column after ':'
local function quoted_key(st, li, p)
  local s = st.lines[li]
  local key, q = quoted(st, li, p)
  local r = find(s, "[^ \t]", q)
  if r and byte(s, r) == COLON then
    local c = byte(s, r + 1)
    if c == nil or c == SPACE or c == TAB then return key, r + 1 end
  end
  return nil
end

-- the key of a block mapping entry at (li, p), or nil: the key and the column after ':'
local function key_at(st, li, p)
  local s = st.lines[li]
  local b = byte(s, p)
  if b == QUOTE1 or b == QUOTE2 then return quoted_key(st, li, p) end
  if b == LBRACKET or b == LBRACE then return nil end
  local colon = find(s, ":[ \t]", p) or (byte(s, #s) == COLON and #s or nil)
  if not colon then return nil end
  local comment = find(s, "[ \t]#", p)
  if comment and comment < colon then return nil end
  if is_complex_key(s, p, b) then
    fail(st, "complex mapping keys ('? ') are not supported", li)
  end
  refuse_indicator(st, b, li)
  if b == BANG then fail(st, "tags on keys are not supported", li) end
  local e = rtrim_end(s, p, colon - 1)
  if e < p then fail(st, "empty mapping key", li) end
  local key = resolve(st, sub(s, p, e), li)
  if key == NULL then fail(st, "a null mapping key is not supported", li) end
  return key, colon + 1
end

local node_at, value_at

-- the block sequence whose entries ("- ") are at indentation ind, from line li
local function sequence(st, li, ind, depth)
  check_depth(st, depth, li)
  local lines, indent = st.lines, st.indent
  local out = {}
  while true do
    st.line_no = li
    local s = lines[li]
    local p = find(s, "[^ ]", ind + 2)
    local item
    local at = li
    if p == nil or (byte(s, p) == HASH) then
      local ni = content_from(st, li + 1)
      if ni and indent[ni] > ind then
        item, li = node_at(st, ni, indent[ni] + 1, depth + 1)
      else
        item, li = NULL, li + 1
      end
    else
      if byte(s, p) == TAB then fail(st, "tab after '-' (YAML indents with spaces)") end
      item, li = node_at(st, li, p, depth + 1)
    end
    out[#out + 1] = item
    record(st, out, #out, at)
    local ni = content_from(st, li)
    if not ni or indent[ni] < ind then return out, li end
    st.line_no = ni
    if indent[ni] > ind then fail(st, "unexpected indentation") end
    if not is_entry(st, ni, ind + 1) then return out, ni end
    li = ni
  end
end

-- the block mapping whose first key is at (li, p)
local function mapping(st, li, p, depth)
  check_depth(st, depth, li)
  local indent = st.indent
  local ind = p - 1
  local out = {}
  while true do
    st.line_no = li
    local key, q = key_at(st, li, p)
    if key == nil then fail(st, "'key: value' expected") end
    if out[key] ~= nil then
      fail(st, "duplicate key '" .. tostring(key) .. "' (first on line " .. st.where[out][key]
        .. ")")
    end
    local at = li
    local value
    value, li = value_at(st, li, q, ind, depth + 1)
    out[key] = value
    record(st, out, key, at)
    local ni = content_from(st, li)
    if not ni or indent[ni] < ind then return out, li end
    st.line_no = ni
    if indent[ni] > ind then fail(st, "unexpected indentation") end
    if is_entry(st, ni, ind + 1) then
      fail(st, "a sequence item where a key of the mapping at line " .. st.where[out][key]
        .. "'s indentation was expected")
    end
    li, p = ni, ind + 1
  end
end

-- the plain scalar at (li, p) to the end of the line or a comment
local function plain(st, li, p)
  local s = st.lines[li]
  local comment = find(s, "[ \t]#", p)
  local e = rtrim_end(s, p, (comment or #s + 1) - 1)
  local scalar_text = sub(s, p, e)
  local colon = find(scalar_text, ":[ \t]") or (byte(scalar_text, #scalar_text) == COLON
    and #scalar_text)
  if colon then
    fail(st, "a mapping key inside a value ('key: value' nested on one line)", li)
  end
  return resolve(st, scalar_text, li), li + 1
end

-- the node starting at column p of line li (the start of its content, or after "- ")
node_at = function(st, li, p, depth)
  check_depth(st, depth, li)
  st.line_no = li
  local s = st.lines[li]
  local b = byte(s, p)
  if is_entry(st, li, p) then return sequence(st, li, p - 1, depth) end
  if key_at(st, li, p) ~= nil then return mapping(st, li, p, depth) end
  if b == LBRACKET or b == LBRACE then return flow.block_value(st, li, p, depth) end
  if b == QUOTE1 or b == QUOTE2 then
    local v, q = quoted(st, li, p)
    scanner.expect_rest_blank(st, li, q)
    return v, li + 1
  end
  if b == BANG then
    return value_at(st, li, p, p - 2, depth)
  end
  if is_complex_key(s, p, b) then
    fail(st, "complex mapping keys ('? ') are not supported")
  end
  refuse_indicator(st, b, li)
  return plain(st, li, p)
end

-- the value on the lines after line li, of a key of a mapping indented by `owner`
local function value_below(st, li, owner, depth, tagged)
  local indent = st.indent
  local ni = content_from(st, li + 1)
  if ni and indent[ni] > owner then
    return node_at(st, ni, indent[ni] + 1, depth)
  elseif ni and indent[ni] == owner and owner >= 0 and is_entry(st, ni, owner + 1)
    and not tagged then
    return sequence(st, ni, owner, depth)
  end
  return NULL, li + 1
end

-- the value on line li from its first character, at column q
local function value_inline(st, li, q, depth)
  local s = st.lines[li]
  local b = byte(s, q)
  if b == LBRACKET or b == LBRACE then return flow.block_value(st, li, q, depth) end
  if b == QUOTE1 or b == QUOTE2 then
    local v, e = quoted(st, li, q)
    scanner.expect_rest_blank(st, li, e)
    return v, li + 1
  end
  if is_entry(st, li, q) then fail(st, "a sequence cannot start on the line of its key", li) end
  if is_complex_key(s, q, b) then
    fail(st, "complex mapping keys ('? ') are not supported", li)
  end
  refuse_indicator(st, b, li)
  if b == BANG then fail(st, "two tags on one value", li) end
  return plain(st, li, q)
end

-- the value after a key's ':' (column p of line li) of a mapping indented by `owner`
value_at = function(st, li, p, owner, depth)
  check_depth(st, depth, li)
  st.line_no = li
  local s = st.lines[li]
  local q = find(s, "[^ \t]", p)
  local tname
  if q and byte(s, q) == BANG then
    tname, q = scalar.tag_at(st, li, q)
    q = find(s, "[^ \t]", q)
  end
  local value
  if q == nil or (byte(s, q) == HASH and is_blank_byte(byte(s, q - 1))) then
    value, li = value_below(st, li, owner, depth, tname)
  else
    value, li = value_inline(st, li, q, depth)
  end
  if tname then scalar.apply_tag(st, value, tname, st.line_no) end
  return value, li
end

--- Read a whole document.
-- @tparam table st the reading state of `tagpose.formats.yaml.scanner.open`
-- @return the document's value (`NULL` for a document without content)
-- @treturn table where each key was read (`st.where`)
function M.document(st)
  local first = content_from(st, 1)
  if not first then return NULL, st.where end
  local root, li = node_at(st, first, st.indent[first] + 1, 1)
  local rest = content_from(st, li)
  if rest then
    st.line_no = rest
    fail(st, "unexpected content after the document's top-level node")
  end
  return root, st.where
end

return M
