--- A small XML reader for the files users have (OpenCV FileStorage XML), with the line of every
-- element and text, and the line of what it refuses.
--
-- It reads the XML 1.0 that data files use: the `<?xml ...?>` declaration, one root element,
-- elements with attributes (`name="value"` or `'value'`), empty elements (`<a/>`), character
-- data with the references `&lt; &gt; &amp; &quot; &apos;` and `&#N;` / `&#xH;`, comments
-- and processing instructions (skipped). A UTF-8 byte-order mark is skipped.
--
-- Refused, with the line: a document type declaration (`<!DOCTYPE`, whose entities could make a
-- small file expand without bound), CDATA sections, an unknown entity or a bare `&`, a `<` in an
-- attribute value, an attribute given twice, an end tag that does not match, content after the
-- root element, names that are not ASCII, and nesting deeper than `MAX_DEPTH`.
--
-- An element is a table
--
--     { name = "camera_matrix", line = 5, attributes = { type_id = "opencv-matrix" },
--       lines = { 5, 6, ... },   -- the line on which each child starts
--       child, child, ... }      -- elements (tables) and text (strings), in document order
--
-- Attribute values are unescaped. Text is kept as written (its references checked, not
-- replaced; `unescape` replaces them), so that a format whose tokens are delimited by a
-- character that may also appear escaped (OpenCV quotes its strings with `"` and escapes a `"`
-- inside as `&quot;`) can split the text first. Text that is only white space between elements
-- is dropped. The reader runs in time linear in the text and calls no code it reads.
-- @module tagpose.formats.xml

local compat = require("tagpose.core.compat")
local failure = require("tagpose.formats.failure")

local byte, sub, find = string.byte, string.sub, string.find
local huge = math.huge
local utf8_char = compat.utf8_char

local M = {}

--- Deepest nesting of elements read (deeper input is refused).
M.MAX_DEPTH = 64

local NAMED = { lt = "<", gt = ">", amp = "&", quot = '"', apos = "'" }
local NAME = "^[%a_:][%w_:%.%-]*"

-- the line of a position: newlines are counted once each, as the reader moves forward
local function line_at(st, pos)
  local nl = st.next_nl
  while nl and nl < pos do
    st.line = st.line + 1
    nl = find(st.text, "\n", nl + 1, true)
  end
  st.next_nl = nl
  return st.line
end

local function fail(st, pos, reason)
  failure.raise(st.name .. ":" .. line_at(st, pos) .. ": " .. reason)
end

-- the text of a reference `&...;` (its inside given), or nil and why not
local function reference(ref)
  local named = NAMED[ref]
  if named then return named end
  local cp
  if find(ref, "^#x%x+$") then
    cp = #ref <= 8 and tonumber(sub(ref, 3), 16)
  elseif find(ref, "^#%d+$") then
    cp = #ref <= 8 and tonumber(sub(ref, 2))
  else
    return nil, "unknown entity reference '&" .. ref .. ";' (XML has &lt; &gt; &amp; &quot;"
      .. " &apos; and &#N;)"
  end
  if not cp or cp == 0 or cp > 0x10FFFF or (cp >= 0xD800 and cp <= 0xDFFF) then
    return nil, "'&" .. ref .. ";' is not a character"
  end
  return utf8_char(cp)
end

--- Replace the references of a text (`&lt;`, `&#10;`, ...) by their characters.
-- @tparam string s
-- @treturn string
-- @return nil, string when a reference is unknown or `&` starts none
function M.unescape(s)
  if not find(s, "&", 1, true) then return s end
  local out, n, i = {}, 0, 1
  while true do
    local a = find(s, "&", i, true)
    if not a then break end
    local ref = s:match("^&([#%w]+);", a)
    if not ref then return nil, "'&' that starts no reference (write &amp;)" end
    local c, why = reference(ref)
    if not c then return nil, why end
    n = n + 1; out[n] = sub(s, i, a - 1)
    n = n + 1; out[n] = c
    i = a + #ref + 2
  end
  n = n + 1; out[n] = sub(s, i)
  return table.concat(out)
end

-- the first `&` at or after pos, or nil: texts and values are checked in document order, so
-- the search resumes where the last one ended and each `&` is found once (a text of one long
-- line with no `&` is not scanned again for each of its values)
local function next_amp(st, pos)
  local amp = st.amp
  if pos < st.amp_from or (amp and amp < pos) then
    amp = find(st.text, "&", pos, true) or false
    st.amp, st.amp_from = amp, pos
  end
  return amp or nil
end

-- refuse a text (from..to) whose references are not all known
local function check_references(st, from, to)
  local text = st.text
  local a = next_amp(st, from)
  while a and a <= to do
    local ref = text:match("^&([#%w]+);", a)
    local why
    if not ref or a + #ref + 1 > to then
      why = "'&' that starts no reference (write &amp;)"
    else
      local _
      _, why = reference(ref)
    end
    if why then fail(st, a, why) end
    a = next_amp(st, a + #ref + 2)
  end
end

-- step over white space; the position of what follows
local function skip_space(st, pos)
  local _, e = find(st.text, "^[ \t\r\n]+", pos)
  return e and e + 1 or pos
end

-- a comment or processing instruction at pos; the position after it
local function skip_markup(st, pos)
  local text = st.text
  if sub(text, pos, pos + 3) == "<!--" then
    local _, e = find(text, "-->", pos + 4, true)
    if not e then fail(st, pos, "a comment is not closed ('-->' expected)") end
    return e + 1
  end
  if sub(text, pos, pos + 1) == "<?" then
    local _, e = find(text, "?>", pos + 2, true)
    if not e then fail(st, pos, "a processing instruction is not closed ('?>' expected)") end
    return e + 1
  end
  if sub(text, pos, pos + 8) == "<!DOCTYPE" then
    fail(st, pos, "a document type declaration (<!DOCTYPE) is not read")
  end
  if sub(text, pos, pos + 8) == "<![CDATA[" then
    fail(st, pos, "a CDATA section is not read: write the text with &lt; and &amp;")
  end
  fail(st, pos, "'" .. sub(text, pos, pos + 1) .. "' starts no element, comment or instruction")
end

-- the attributes of a start tag from pos (after its name); the table, the position after the
-- tag and whether the tag closes itself (`/>`)
local function read_attributes(st, pos)
  local text = st.text
  local attributes = {}
  while true do
    local after = skip_space(st, pos)
    local b = byte(text, after)
    if b == 62 then return attributes, after + 1, false end -- >
    if b == 47 and byte(text, after + 1) == 62 then return attributes, after + 2, true end -- />
    if after == pos then fail(st, pos, "white space, '>' or '/>' expected in a tag") end
    local _, e = find(text, NAME, after)
    if not e then fail(st, after, "an attribute name expected in a tag") end
    local name = sub(text, after, e)
    if attributes[name] ~= nil then fail(st, after, "attribute '" .. name .. "' given twice") end
    local _, eq = find(text, "^[ \t\r\n]*=[ \t\r\n]*", e + 1)
    if not eq then fail(st, e + 1, "'=' expected after attribute '" .. name .. "'") end
    local quote = sub(text, eq + 1, eq + 1)
    if quote ~= '"' and quote ~= "'" then
      fail(st, eq + 1, "the value of attribute '" .. name .. "' must be quoted")
    end
    local close = find(text, quote, eq + 2, true)
    if not close then fail(st, eq + 1, "the value of attribute '" .. name .. "' is not closed") end
    local value = sub(text, eq + 2, close - 1)
    local lt = find(value, "<", 1, true)
    if lt then fail(st, eq + 1 + lt, "'<' in the value of attribute '" .. name .. "'") end
    check_references(st, eq + 2, close - 1)
    attributes[name] = M.unescape(value)
    pos = close + 1
  end
end

-- the element whose start tag opens at pos; the element and the position after it
local function read_element(st, pos, depth)
  local text = st.text
  if depth >= st.max_depth then
    fail(st, pos, "nesting deeper than " .. st.max_depth .. " levels")
  end
  local _, e = find(text, NAME, pos + 1)
  if not e then fail(st, pos, "an element name expected after '<'") end
  local el = { name = sub(text, pos + 1, e), line = line_at(st, pos), lines = {} }
  local closed
  el.attributes, pos, closed = read_attributes(st, e + 1)
  if closed then return el, pos end
  local n = 0
  while true do
    local lt = find(text, "<", pos, true)
    if not lt then fail(st, #text + 1, "element <" .. el.name .. "> (line " .. el.line
      .. ") is not closed") end
    if lt > pos and find(text, "[^ \t\r\n]", pos) < lt then
      check_references(st, pos, lt - 1)
      n = n + 1
      el[n], el.lines[n] = sub(text, pos, lt - 1), line_at(st, pos)
    end
    local b = byte(text, lt + 1)
    if b == 47 then -- </
      local _, ne = find(text, NAME, lt + 2)
      local name = ne and sub(text, lt + 2, ne)
      if name ~= el.name then
        fail(st, lt, "</" .. tostring(name) .. "> does not close <" .. el.name .. "> (line "
          .. el.line .. ")")
      end
      local gt = skip_space(st, ne + 1)
      if byte(text, gt) ~= 62 then fail(st, gt, "'>' expected to end </" .. name) end
      return el, gt + 1
    elseif b == 33 or b == 63 then -- <! <?
      pos = skip_markup(st, lt)
    else
      n = n + 1
      el.lines[n] = line_at(st, lt)
      el[n], pos = read_element(st, lt, depth + 1)
    end
  end
end

-- the comments, instructions and white space before or after the root; the position after them
local function skip_misc(st, pos)
  local text = st.text
  while true do
    pos = skip_space(st, pos)
    local b, b2 = byte(text, pos), byte(text, pos + 1)
    if b ~= 60 or (b2 ~= 33 and b2 ~= 63) then return pos end
    pos = skip_markup(st, pos)
  end
end

local function parse(st)
  local text = st.text
  local pos = 1
  if sub(text, 1, 3) == "\239\187\191" then pos = 4 end
  pos = skip_misc(st, pos)
  if byte(text, pos) ~= 60 then
    if pos > #text then fail(st, pos, "no root element: the text is empty") end
    fail(st, pos, "an element ('<') expected, got '" .. sub(text, pos, pos) .. "'")
  end
  local root
  root, pos = read_element(st, pos, 0)
  pos = skip_misc(st, pos)
  if pos <= #text then
    fail(st, pos, "unexpected content after the root element <" .. root.name .. ">")
  end
  return root
end

--- Decode an XML document.
-- @tparam string text
-- @tparam[opt="xml"] string name the file's name, for messages
-- @treturn table the root element (see the module's header)
-- @return nil, string `"name:LINE: reason"` when the text is not XML this reader accepts
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
-- @usage
-- local root = xml.decode('<?xml version="1.0"?>\n<a k="v">1 2</a>', "f.xml")
-- print(root.name, root.attributes.k, root[1], root.lines[1]) --> a v 1 2 2
function M.decode(text, name)
  failure.check(text, name, true)
  local st = { text = text, name = name or "xml", line = 1, next_nl = find(text, "\n", 1, true),
    amp = false, amp_from = huge, max_depth = M.MAX_DEPTH }
  return failure.protect(parse, st)
end

return M
