--- YAML scalars: what a plain scalar means, quoted scalars, the tags read, and the
-- characters that cannot start a plain scalar.
--
-- A plain scalar is `NULL` (`null`, `~`), a boolean (`true`, `False`, ...), a decimal number
-- (`compat.decimal`, the same on every VM) or else a string; the YAML 1.1 booleans
-- (`yes/no/on/off`) and `.nan`/`.inf` are refused. Quoted scalars (`'...'` with `''`,
-- `"..."` with escapes) end on their line. Functions take the reading state of
-- `tagpose.formats.yaml.scanner` (for the file's name and its lines) and raise its `Failure`.
-- @module tagpose.formats.yaml.scalar

local compat = require("tagpose.core.compat")
local scanner = require("tagpose.formats.yaml.scanner")

local decimal, utf8_char = compat.decimal, compat.utf8_char
local huge = math.huge
local byte, sub, find, char, concat = string.byte, string.sub, string.find, string.char,
  table.concat
local fail = scanner.fail

local QUOTE1, QUOTE2 = scanner.QUOTE1, scanner.QUOTE2

local M = {}

--- The value of `null`, `~` and empty values (a unique table; compare with `==`).
M.NULL = setmetatable({}, { __tostring = function() return "yaml.NULL" end })

--- The key under which a tagged mapping holds its tag (a unique table).
M.TAG = setmetatable({}, { __tostring = function() return "yaml.TAG" end })

--- The tags read (without their `!!`).
M.TAGS = { ["opencv-matrix"] = true, ["opencv-nd-matrix"] = true }

local NULL, TAGS = M.NULL, M.TAGS

local ESCAPES = { ["\\"] = "\\", ['"'] = '"', ["/"] = "/", b = "\b", f = "\f", n = "\n",
  r = "\r", t = "\t", ["0"] = "\0", [" "] = " " }
local HEX_LENGTH = { x = 2, u = 4, U = 8 }

--- The value of a plain scalar.
-- @tparam table st the reading state
-- @tparam string s the scalar, trimmed
-- @tparam int at its line
-- @return a number, `NULL`, a boolean or the string
function M.resolve(st, s, at)
  local n = decimal(s)
  if n then
    if n ~= n or n == huge or n == -huge then
      fail(st, "the number " .. s .. " is out of range", at)
    end
    return n
  end
  if s == "~" or s == "null" or s == "Null" or s == "NULL" then return NULL end
  if s == "true" or s == "True" or s == "TRUE" then return true end
  if s == "false" or s == "False" or s == "FALSE" then return false end
  local lower = s:lower()
  if lower == "yes" or lower == "no" or lower == "on" or lower == "off" then
    fail(st, "'" .. s .. "' is true or false in YAML 1.1 but a string in YAML 1.2: write true,"
      .. " false or a quoted string", at)
  end
  if find(s, "^[-+]?%.[iI][nN][fF]$") or find(s, "^%.[nN][aA][nN]$") then
    fail(st, "'" .. s .. "' (not a number or infinite) is refused", at)
  end
  return s
end

local function not_closed(st, li)
  fail(st, "quoted scalar not closed on its line (multi-line scalars are not supported)", li)
end

-- the single-quoted scalar whose text starts at column pos of line li
local function single_quoted(st, li, pos)
  local s = st.lines[li]
  local parts = {}
  while true do
    local i = find(s, "'", pos, true)
    if not i then not_closed(st, li) end
    parts[#parts + 1] = sub(s, pos, i - 1)
    if byte(s, i + 1) == QUOTE1 then
      parts[#parts + 1] = "'"
      pos = i + 2
    else
      return concat(parts), i + 1
    end
  end
end

-- the escape \e at column i of s (and its hexadecimal digits): its text and the column after
local function escape(st, li, s, i)
  local e = sub(s, i + 1, i + 1)
  if ESCAPES[e] then return ESCAPES[e], i + 2 end
  local n = HEX_LENGTH[e]
  if not n then fail(st, "escape \\" .. e .. " is not supported", li) end
  local hex = sub(s, i + 2, i + 1 + n)
  if #hex ~= n or not find(hex, "^%x+$") then fail(st, "bad escape \\" .. e .. hex, li) end
  local code = tonumber(hex, 16)
  if code > 0x10FFFF or (code >= 0xD800 and code <= 0xDFFF) then
    fail(st, "escape \\" .. e .. hex .. " is not a Unicode character", li)
  end
  return utf8_char(code), i + 2 + n
end

-- the double-quoted scalar whose text starts at column pos of line li
local function double_quoted(st, li, pos)
  local s = st.lines[li]
  local parts = {}
  while true do
    local i = find(s, '["\\]', pos)
    if not i then not_closed(st, li) end
    parts[#parts + 1] = sub(s, pos, i - 1)
    if byte(s, i) == QUOTE2 then return concat(parts), i + 1 end
    local text
    text, pos = escape(st, li, s, i)
    parts[#parts + 1] = text
  end
end

--- A quoted scalar whose quote is at column p of line li.
-- @tparam table st the reading state
-- @tparam int li
-- @tparam int p
-- @treturn string the scalar
-- @treturn int the column after its closing quote
function M.quoted(st, li, p)
  if byte(st.lines[li], p) == QUOTE1 then return single_quoted(st, li, p + 1) end
  return double_quoted(st, li, p + 1)
end

--- Refuse the characters that cannot start a plain scalar here (anchors, aliases, block
-- scalars, reserved indicators).
-- @tparam table st the reading state
-- @tparam int|nil b the first byte
-- @tparam int li its line
function M.refuse_indicator(st, b, li)
  if b == 38 or b == 42 then fail(st, "anchors and aliases (& and *) are not supported", li) end
  if b == 124 or b == 62 then fail(st, "block scalars (| and >) are not supported", li) end
  if b == 64 or b == 96 then fail(st, "'" .. char(b) .. "' cannot start a plain scalar", li) end
  if b == scanner.PERCENT then fail(st, "'%' cannot start a plain scalar", li) end
end

--- The tag at column p of line li (`!!opencv-matrix`).
-- @tparam table st the reading state
-- @tparam int li
-- @tparam int p
-- @treturn string its name without `!!`
-- @treturn int the column after it
function M.tag_at(st, li, p)
  local s = st.lines[li]
  local e = find(s, "[ \t,%[%]{}]", p) or #s + 1
  local tag = sub(s, p, e - 1)
  local tname = tag:match("^!!(.+)$")
  if not (tname and TAGS[tname]) then
    fail(st, "tag " .. tag .. " is not supported (only !!opencv-matrix)", li)
  end
  return tname, e
end

--- Put a tag on the value it tags, refusing anything but a mapping (an empty value too: it
-- is the one `NULL` of every document, which must never carry a tag).
-- @tparam table st the reading state
-- @param value
-- @tparam string tname
-- @tparam int at the line, for the refusal
-- @treturn table the value
function M.apply_tag(st, value, tname, at)
  if type(value) ~= "table" or value == NULL or value[1] ~= nil then
    fail(st, "!!" .. tname .. " tags a mapping", at)
  end
  value[M.TAG] = tname
  return value
end

return M
