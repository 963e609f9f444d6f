--- A small YAML reader for the calibration and layout files users have.
--
-- It reads exactly the YAML that ROS `camera_calibration` (`ost.yaml`), OpenCV's FileStorage
-- (`%YAML:1.0`, `!!opencv-matrix`) and apriltag_ros (`tags.yaml`) write, and refuses anything
-- else with the line number, so that nothing is read differently from what the file says:
--
-- * the `%YAML` directive (`%YAML 1.2` and OpenCV's `%YAML:1.0`), a `---` line before the
--   document and a `...` or `---` line after it; `#` comments;
-- * block mappings (nesting by indentation, spaces only) and block sequences (`- item`, also
--   at the indentation of the key that owns them);
-- * flow sequences `[a, b]` and flow mappings `{k: v}`, nested, across any number of lines,
--   with comments between their entries;
-- * plain scalars, `'single'` (`''` for a quote) and `"double"`-quoted scalars (escapes
--   `\\ \" \/ \b \f \n \r \t \0 \xHH \uHHHH \UHHHHHHHH`), each on one line;
-- * the tags `!!opencv-matrix` and `!!opencv-nd-matrix` on a mapping.
--
-- Refused, with the line: anchors and aliases, block scalars (`|`, `>`), complex keys (`?`),
-- other tags and directives, plain or quoted scalars continued on the next line, tabs in
-- indentation, duplicate keys, a second document, nesting deeper than `MAX_DEPTH`, the
-- YAML 1.1 booleans `yes/no/on/off` (unquoted: YAML 1.1 and 1.2 readers disagree on them), and
-- `.nan`, `.inf`, `-.inf` (a calibration never holds them; nothing downstream must meet them).
--
-- Values: a mapping is a Lua table by key, a sequence a Lua array, `null`, `~` and an empty
-- value are `NULL` (never `nil`, so that arrays have no holes and a key given without a value
-- is still seen), `true`/`false` (also `True`, `TRUE`, ...) booleans, and a plain scalar that is
-- a decimal number (`640`, `-0.`, `.5`, `6.5e+02`, `1E-3`) a Lua number, the same on every VM
-- (an integer of 16 digits or more, which Lua 5.3's integers would keep exact and doubles
-- round, is read as the nearest double everywhere); other scalars are strings. A plain key is
-- resolved the same way (`0: x` has the number key 0). A tagged mapping carries its tag name
-- without the `!!` under the key `TAG`.
--
-- The reader runs in time linear in the text and never calls back into Lua code it reads.
-- @module tagpose.yaml

local compat = require("tagpose.compat")

local decimal = compat.decimal
local floor = math.floor
local byte, sub, find, char, concat = string.byte, string.sub, string.find, string.char,
  table.concat

local M = {}

--- The value of `null`, `~` and empty values (a unique table; compare with `==`).
M.NULL = setmetatable({}, { __tostring = function() return "yaml.NULL" end })

--- The key under which a tagged mapping holds its tag (`"opencv-matrix"`): a unique table,
-- so it never collides with a key of the file; skip it when iterating with `pairs`.
M.TAG = setmetatable({}, { __tostring = function() return "yaml.TAG" end })

--- Deepest nesting of collections read (deeper input is refused).
M.MAX_DEPTH = 64

local TAGS = { ["opencv-matrix"] = true, ["opencv-nd-matrix"] = true }

local NULL, TAG = M.NULL, M.TAG

local SPACE, TAB, HASH, COLON, DASH = 32, 9, 35, 58, 45
local QUOTE1, QUOTE2 = 39, 34

-- the parse error raised inside, caught by decode
local Failure = {}

local function is_blank_byte(b)
  return b == SPACE or b == TAB
end

-- the last position of s before `j + 1` that is not a space or tab, at least i - 1 (linear)
local function rtrim_end(s, i, j)
  while j >= i and is_blank_byte(byte(s, j)) do j = j - 1 end
  return j
end


local function utf8_char(code)
  if code < 0x80 then return char(code) end
  if code < 0x800 then
    return char(0xC0 + floor(code / 0x40), 0x80 + code % 0x40)
  end
  if code < 0x10000 then
    return char(0xE0 + floor(code / 0x1000), 0x80 + floor(code / 0x40) % 0x40, 0x80 + code % 0x40)
  end
  return char(0xF0 + floor(code / 0x40000), 0x80 + floor(code / 0x1000) % 0x40,
    0x80 + floor(code / 0x40) % 0x40, 0x80 + code % 0x40)
end

local ESCAPES = { ["\\"] = "\\", ['"'] = '"', ["/"] = "/", b = "\b", f = "\f", n = "\n",
  r = "\r", t = "\t", ["0"] = "\0", [" "] = " " }
local HEX_LENGTH = { x = 2, u = 4, U = 8 }

local function parse(text, name)
  local lines, indent = {}, {} -- indent: spaces before the content; -1 blank or comment
  local line_no = 0 -- the line being read, for errors

  local function fail(reason, at)
    error(setmetatable({ message = name .. ":" .. (at or line_no) .. ": " .. reason }, Failure), 0)
  end

  -- split into lines at \r\n, \r or \n (linear: one find per line)
  do
    local pos, n = 1, #text
    if sub(text, 1, 3) == "\239\187\191" then pos = 4 end -- UTF-8 byte-order mark
    while pos <= n do
      local i = find(text, "[\r\n]", pos)
      if not i then
        lines[#lines + 1] = sub(text, pos)
        break
      end
      lines[#lines + 1] = sub(text, pos, i - 1)
      if byte(text, i) == 13 and byte(text, i + 1) == 10 then i = i + 1 end
      pos = i + 1
    end
  end
  local nlines = #lines

  -- indentation, directives and document markers
  local MARKER = -2 -- a line that is no content and must not be inside a flow collection
  local content_seen, ended = false, nil
  for i = 1, nlines do
    local s = lines[i]
    line_no = i
    local _, e = find(s, "^ *")
    local b = byte(s, e + 1)
    if b == nil or b == HASH or (b == TAB and find(s, "^[ \t]*$")) or (b == TAB
      and find(s, "^[ \t]*#")) then
      indent[i] = -1
    elseif b == TAB then
      fail("tab in indentation (YAML indents with spaces)")
    elseif e == 0 and b == 37 then -- %
      if content_seen then fail("a directive after the document's start") end
      if not (find(s, "^%%YAML[ :]1%.%d+[ \t]*$") or find(s, "^%%YAML[ :]1%.%d+[ \t]+#")) then
        fail("directive '" .. s .. "' is not supported (only %YAML 1.x)")
      end
      indent[i] = MARKER
    elseif e == 0 and (find(s, "^%-%-%-[ \t]*$") or find(s, "^%-%-%-[ \t]+#")) then
      if content_seen then
        ended = ended or i
      end
      indent[i] = MARKER
    elseif e == 0 and find(s, "^%-%-%-[ \t]") then
      fail("content on the '---' line is not supported")
    elseif e == 0 and (find(s, "^%.%.%.[ \t]*$") or find(s, "^%.%.%.[ \t]+#")) then
      ended = ended or i
      indent[i] = MARKER
    else
      if ended then
        fail("a second document (after line " .. ended .. ") is not supported")
      end
      content_seen = true
      indent[i] = e
    end
  end

  -- next content line at or after i (nil at the end)
  local next_content = {}
  do
    local nxt = nil
    for i = nlines, 1, -1 do
      if indent[i] >= 0 then nxt = i end
      next_content[i] = nxt
    end
  end
  local function content_from(i)
    if i > nlines then return nil end
    return next_content[i]
  end

  local where = {} -- container -> {key -> line}
  local function record(container, key, at)
    local w = where[container]
    if not w then
      w = {}
      where[container] = w
    end
    w[key] = at
  end

  local function check_depth(depth, at)
    if depth > M.MAX_DEPTH then fail("nesting deeper than " .. M.MAX_DEPTH, at) end
  end

  -- the value of a plain scalar
  local function resolve(s, at)
    local n = decimal(s)
    if n then
      if n ~= n or n == math.huge or n == -math.huge then
        fail("the number " .. s .. " is out of range", at)
      end
      return n
    end
    if s == "~" or s == "null" or s == "Null" or s == "NULL" then return NULL end
    if s == "true" or s == "True" or s == "TRUE" then return true end
    if s == "false" or s == "False" or s == "FALSE" then return false end
    local lower = s:lower()
    if lower == "yes" or lower == "no" or lower == "on" or lower == "off" then
      fail("'" .. s .. "' is true or false in YAML 1.1 but a string in YAML 1.2: write true,"
        .. " false or a quoted string", at)
    end
    if find(s, "^[-+]?%.[iI][nN][fF]$") or find(s, "^%.[nN][aA][nN]$") then
      fail("'" .. s .. "' (not a number or infinite) is refused", at)
    end
    return s
  end

  -- a quoted scalar starting at column p of line li; returns the string and the column after
  local function quoted(li, p)
    local s = lines[li]
    local q = byte(s, p)
    local parts = {}
    local pos = p + 1
    if q == QUOTE1 then
      while true do
        local i = find(s, "'", pos, true)
        if not i then fail("quoted scalar not closed on its line (multi-line scalars are not"
          .. " supported)", li) end
        parts[#parts + 1] = sub(s, pos, i - 1)
        if byte(s, i + 1) == QUOTE1 then
          parts[#parts + 1] = "'"
          pos = i + 2
        else
          return concat(parts), i + 1
        end
      end
    end
    while true do
      local i = find(s, '["\\]', pos)
      if not i then fail("quoted scalar not closed on its line (multi-line scalars are not"
        .. " supported)", li) end
      parts[#parts + 1] = sub(s, pos, i - 1)
      if byte(s, i) == QUOTE2 then return concat(parts), i + 1 end
      local e = sub(s, i + 1, i + 1)
      if ESCAPES[e] then
        parts[#parts + 1] = ESCAPES[e]
        pos = i + 2
      elseif HEX_LENGTH[e] then
        local n = HEX_LENGTH[e]
        local hex = sub(s, i + 2, i + 1 + n)
        if #hex ~= n or not find(hex, "^%x+$") then fail("bad escape \\" .. e .. hex, li) end
        local code = tonumber(hex, 16)
        if code > 0x10FFFF or (code >= 0xD800 and code <= 0xDFFF) then
          fail("escape \\" .. e .. hex .. " is not a Unicode character", li)
        end
        parts[#parts + 1] = utf8_char(code)
        pos = i + 2 + n
      else
        fail("escape \\" .. e .. " is not supported", li)
      end
    end
  end

  -- true when the rest of line li from column p is blank or a comment
  local function rest_blank(li, p)
    local s = lines[li]
    local q = find(s, "[^ \t]", p)
    return q == nil or (byte(s, q) == HASH and (q == 1 or is_blank_byte(byte(s, q - 1))))
  end

  local function expect_rest_blank(li, p)
    if not rest_blank(li, p) then
      local s = lines[li]
      local q = find(s, "[^ \t]", p)
      if byte(s, q) == COLON then
        fail("a mapping key here is not supported (a key must be a plain or quoted scalar)", li)
      end
      fail("unexpected '" .. sub(s, q, q + 19) .. "' after the value", li)
    end
  end

  local function refuse_indicator(b, li)
    if b == 38 or b == 42 then fail("anchors and aliases (& and *) are not supported", li) end
    if b == 124 or b == 62 then fail("block scalars (| and >) are not supported", li) end
    if b == 64 or b == 96 then fail("'" .. char(b) .. "' cannot start a plain scalar", li) end
    if b == 37 then fail("'%' cannot start a plain scalar", li) end
  end

  -- ------------------------------------------------------------------------------------------
  -- flow collections: a cursor (line, column) that crosses lines

  local flow_node

  -- skip spaces, tabs, comments and line ends; returns the line and column of the next token
  local function flow_skip(li, p, start_line)
    while true do
      if li > nlines then fail("flow collection from line " .. start_line .. " not closed",
        nlines) end
      if indent[li] == MARKER then
        fail("document marker inside the flow collection from line " .. start_line, li)
      end
      local s = lines[li]
      local q = find(s, "[^ \t]", p)
      if q and byte(s, q) == HASH and (q == 1 or is_blank_byte(byte(s, q - 1))) then q = nil end
      if q then return li, q end
      li, p = li + 1, 1
    end
  end

  local function tag_at(li, p)
    local s = lines[li]
    local e = find(s, "[ \t,%[%]{}]", p) or #s + 1
    local tag = sub(s, p, e - 1)
    local tname = tag:match("^!!(.+)$")
    if not (tname and TAGS[tname]) then
      fail("tag " .. tag .. " is not supported (only !!opencv-matrix)", li)
    end
    return tname, e
  end

  local function flow_plain(li, p)
    local s = lines[li]
    local pos = p
    local stop
    while true do
      local i = find(s, "[,%[%]{}:#]", pos)
      if not i then
        stop = #s + 1
        break
      end
      local b = byte(s, i)
      if b == COLON then
        local c = byte(s, i + 1)
        if c == nil or c == SPACE or c == TAB or c == 44 or c == 91 or c == 93 or c == 123
          or c == 125 then
          stop = i
          break
        end
        pos = i + 1
      elseif b == HASH then
        if is_blank_byte(byte(s, i - 1)) then
          stop = i
          break
        end
        pos = i + 1
      else
        stop = i
        break
      end
    end
    local e = rtrim_end(s, p, stop - 1)
    return resolve(sub(s, p, e), li), stop
  end

  local function flow_key(li, p)
    local s = lines[li]
    local b = byte(s, p)
    if b == QUOTE1 or b == QUOTE2 then return quoted(li, p) end
    if b == 91 or b == 123 or b == 63 then
      fail("complex mapping keys are not supported", li)
    end
    refuse_indicator(b, li)
    if b == 33 then fail("tags on keys are not supported", li) end
    local key, q = flow_plain(li, p)
    if key == NULL then fail("a null mapping key is not supported", li) end
    return key, q
  end

  local function flow_sequence(li, p, depth)
    check_depth(depth, li)
    local start = li
    local out = {}
    li, p = flow_skip(li, p + 1, start)
    if byte(lines[li], p) == 93 then return out, li, p + 1 end
    while true do
      local item
      local at = li
      item, li, p = flow_node(li, p, depth + 1, start)
      out[#out + 1] = item
      record(out, #out, at)
      li, p = flow_skip(li, p, start)
      local b = byte(lines[li], p)
      if b == 93 then return out, li, p + 1 end
      if b ~= 44 then
        fail("',' or ']' expected in the flow sequence from line " .. start .. ", got '"
          .. sub(lines[li], p, p + 19) .. "'", li)
      end
      li, p = flow_skip(li, p + 1, start)
      if byte(lines[li], p) == 93 then return out, li, p + 1 end -- a trailing comma
    end
  end

  local function flow_mapping(li, p, depth)
    check_depth(depth, li)
    local start = li
    local out = {}
    li, p = flow_skip(li, p + 1, start)
    if byte(lines[li], p) == 125 then return out, li, p + 1 end
    while true do
      local at = li
      local key
      key, p = flow_key(li, p)
      if out[key] ~= nil then
        fail("duplicate key '" .. tostring(key) .. "' (first on line " .. where[out][key] .. ")",
          li)
      end
      li, p = flow_skip(li, p, start)
      if byte(lines[li], p) ~= COLON then
        fail("':' expected after the key '" .. tostring(key) .. "' in the flow mapping from line "
          .. start, li)
      end
      li, p = flow_skip(li, p + 1, start)
      local b = byte(lines[li], p)
      local value
      if b == 44 or b == 125 then
        value = NULL
      else
        value, li, p = flow_node(li, p, depth + 1, start)
      end
      out[key] = value
      record(out, key, at)
      li, p = flow_skip(li, p, start)
      b = byte(lines[li], p)
      if b == 125 then return out, li, p + 1 end
      if b ~= 44 then
        fail("',' or '}' expected in the flow mapping from line " .. start .. ", got '"
          .. sub(lines[li], p, p + 19) .. "'", li)
      end
      li, p = flow_skip(li, p + 1, start)
      if byte(lines[li], p) == 125 then return out, li, p + 1 end
    end
  end

  -- a node inside a flow collection at (li, p), a token already
  flow_node = function(li, p, depth, start)
    local s = lines[li]
    local b = byte(s, p)
    if b == 91 then return flow_sequence(li, p, depth) end
    if b == 123 then return flow_mapping(li, p, depth) end
    if b == QUOTE1 or b == QUOTE2 then
      local v, q = quoted(li, p)
      return v, li, q
    end
    if b == HASH then fail("'#' cannot start a plain scalar", li) end
    if b == 44 or b == 93 or b == 125 then
      fail("empty entry in the flow collection from line " .. start, li)
    end
    if b == 33 then
      local tname, q = tag_at(li, p)
      local value
      li, q = flow_skip(li, q, start)
      value, li, q = flow_node(li, q, depth, start)
      if type(value) ~= "table" or value[1] ~= nil then
        fail("!!" .. tname .. " tags a mapping", li)
      end
      value[TAG] = tname
      return value, li, q
    end
    if b == 63 or (b == DASH and (byte(s, p + 1) == SPACE or byte(s, p + 1) == nil)) then
      fail("'" .. char(b) .. "' is not supported in a flow collection", li)
    end
    refuse_indicator(b, li)
    local v, q = flow_plain(li, p)
    return v, li, q
  end

  -- a flow collection as a block value: it ends its last line
  local function flow_block(li, p, depth)
    local value, e, q = flow_node(li, p, depth, li)
    expect_rest_blank(e, q)
    return value, e + 1
  end

  -- ------------------------------------------------------------------------------------------
  -- block collections

  local node_at, value_at

  local function is_entry(li, p) -- "- " or "-" at the end of line li, at column p
    local s = lines[li]
    if byte(s, p) ~= DASH then return false end
    local c = byte(s, p + 1)
    if c == TAB then fail("tab after '-' (YAML indents with spaces)", li) end
    return c == nil or c == SPACE
  end

  -- the key of a block mapping entry at (li, p), or nil: the key and the column after ':'
  local function block_key(li, p)
    local s = lines[li]
    local b = byte(s, p)
    if b == QUOTE1 or b == QUOTE2 then
      local key, q = quoted(li, p)
      local r = find(s, "[^ \t]", q)
      if r and byte(s, r) == COLON then
        local c = byte(s, r + 1)
        if c == nil or c == SPACE or c == TAB then return key, r + 1 end
      end
      return nil
    end
    if b == 91 or b == 123 then return nil end
    local colon = find(s, ":[ \t]", p) or (byte(s, #s) == COLON and #s or nil)
    if not colon then return nil end
    local comment = find(s, "[ \t]#", p)
    if comment and comment < colon then return nil end
    if b == 63 and (byte(s, p + 1) == SPACE or p == #s) then
      fail("complex mapping keys ('? ') are not supported", li)
    end
    refuse_indicator(b, li)
    if b == 33 then fail("tags on keys are not supported", li) end
    local e = rtrim_end(s, p, colon - 1)
    if e < p then fail("empty mapping key", li) end
    local key = resolve(sub(s, p, e), li)
    if key == NULL then fail("a null mapping key is not supported", li) end
    return key, colon + 1
  end

  local function block_sequence(li, ind, depth)
    check_depth(depth, li)
    local out = {}
    while true do
      line_no = li
      local s = lines[li]
      local p = find(s, "[^ ]", ind + 2)
      local item
      local at = li
      if p == nil or (byte(s, p) == HASH) then
        local ni = content_from(li + 1)
        if ni and indent[ni] > ind then
          item, li = node_at(ni, indent[ni] + 1, depth + 1)
        else
          item, li = NULL, li + 1
        end
      else
        if byte(s, p) == TAB then fail("tab after '-' (YAML indents with spaces)") end
        item, li = node_at(li, p, depth + 1)
      end
      out[#out + 1] = item
      record(out, #out, at)
      local ni = content_from(li)
      if not ni or indent[ni] < ind then return out, li end
      line_no = ni
      if indent[ni] > ind then fail("unexpected indentation") end
      if not is_entry(ni, ind + 1) then return out, ni end
      li = ni
    end
  end

  local function block_mapping(li, p, depth)
    check_depth(depth, li)
    local ind = p - 1
    local out = {}
    while true do
      line_no = li
      local key, q = block_key(li, p)
      if key == nil then fail("'key: value' expected") end
      if out[key] ~= nil then
        fail("duplicate key '" .. tostring(key) .. "' (first on line " .. where[out][key] .. ")")
      end
      local at = li
      local value
      value, li = value_at(li, q, ind, depth + 1)
      out[key] = value
      record(out, key, at)
      local ni = content_from(li)
      if not ni or indent[ni] < ind then return out, li end
      line_no = ni
      if indent[ni] > ind then fail("unexpected indentation") end
      if is_entry(ni, ind + 1) then
        fail("a sequence item where a key of the mapping at line " .. where[out][key]
          .. "'s indentation was expected")
      end
      li, p = ni, ind + 1
    end
  end

  -- the plain scalar at (li, p) to the end of the line or a comment
  local function block_plain(li, p)
    local s = lines[li]
    local comment = find(s, "[ \t]#", p)
    local e = rtrim_end(s, p, (comment or #s + 1) - 1)
    local scalar = sub(s, p, e)
    local colon = find(scalar, ":[ \t]") or (byte(scalar, #scalar) == COLON and #scalar)
    if colon then fail("a mapping key inside a value ('key: value' nested on one line)", li) end
    return resolve(scalar, li), li + 1
  end

  -- the node starting at column p of line li (the start of its content, or after "- ")
  node_at = function(li, p, depth)
    check_depth(depth, li)
    line_no = li
    local s = lines[li]
    local b = byte(s, p)
    if is_entry(li, p) then return block_sequence(li, p - 1, depth) end
    if block_key(li, p) ~= nil then return block_mapping(li, p, depth) end
    if b == 91 or b == 123 then return flow_block(li, p, depth) end
    if b == QUOTE1 or b == QUOTE2 then
      local v, q = quoted(li, p)
      expect_rest_blank(li, q)
      return v, li + 1
    end
    if b == 33 then
      return value_at(li, p, p - 2, depth)
    end
    if b == 63 and (byte(s, p + 1) == SPACE or p == #s) then
      fail("complex mapping keys ('? ') are not supported")
    end
    refuse_indicator(b, li)
    return block_plain(li, p)
  end

  -- the value after a key's ':' (column p of line li) of a mapping indented by `owner`
  value_at = function(li, p, owner, depth)
    check_depth(depth, li)
    line_no = li
    local s = lines[li]
    local q = find(s, "[^ \t]", p)
    local tname
    if q and byte(s, q) == 33 then
      tname, q = tag_at(li, q)
      q = find(s, "[^ \t]", q)
    end
    local value
    if q == nil or (byte(s, q) == HASH and is_blank_byte(byte(s, q - 1))) then
      -- on the following lines
      local ni = content_from(li + 1)
      if ni and indent[ni] > owner then
        value, li = node_at(ni, indent[ni] + 1, depth)
      elseif ni and indent[ni] == owner and owner >= 0 and is_entry(ni, owner + 1)
        and not tname then
        value, li = block_sequence(ni, owner, depth)
      else
        value, li = NULL, li + 1
      end
    else
      local b = byte(s, q)
      if b == 91 or b == 123 then
        value, li = flow_block(li, q, depth)
      elseif b == QUOTE1 or b == QUOTE2 then
        local v, e = quoted(li, q)
        expect_rest_blank(li, e)
        value, li = v, li + 1
      elseif is_entry(li, q) then
        fail("a sequence cannot start on the line of its key", li)
      else
        if b == 63 and (byte(s, q + 1) == SPACE or q == #s) then
          fail("complex mapping keys ('? ') are not supported", li)
        end
        refuse_indicator(b, li)
        if b == 33 then fail("two tags on one value", li) end
        value, li = block_plain(li, q)
      end
    end
    if tname then
      if type(value) ~= "table" or value[1] ~= nil then
        fail("!!" .. tname .. " tags a mapping", line_no)
      end
      value[TAG] = tname
    end
    return value, li
  end

  local first = content_from(1)
  if not first then return NULL, where end
  local root, li = node_at(first, indent[first] + 1, 1)
  local rest = content_from(li)
  if rest then
    line_no = rest
    fail("unexpected content after the document's top-level node")
  end
  return root, where
end

--- Decode a YAML document.
-- @tparam string text the document
-- @tparam[opt="yaml"] string name the file's name, for messages
-- @treturn any the value: a table for a mapping or sequence, a number, string, boolean or
--   `NULL`
-- @treturn table where each key was read: `lines[container][key]` is the line of a mapping's
--   key or of a sequence's item (`container` a table of the value)
-- @return nil, string `"name:LINE: reason"` when the text is not YAML this reader accepts
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
-- @usage
-- local doc, where = yaml.decode("camera_matrix: !!opencv-matrix\n  rows: 3\n", "cal.yaml")
-- print(doc.camera_matrix[yaml.TAG], doc.camera_matrix.rows) --> opencv-matrix 3
-- print(where[doc].camera_matrix)                            --> 1
function M.decode(text, name)
  if type(text) ~= "string" then
    error("bad argument #1 to 'decode' (string expected, got " .. type(text) .. ")", 2)
  end
  if name ~= nil and type(name) ~= "string" then
    error("bad argument #2 to 'decode' (string expected, got " .. type(name) .. ")", 2)
  end
  local ok, value, where = pcall(parse, text, name or "yaml")
  if ok then return value, where end
  if getmetatable(value) == Failure then return nil, value.message end
  error(value, 0)
end

return M
