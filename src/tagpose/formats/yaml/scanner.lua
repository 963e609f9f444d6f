--- The lines of a YAML document and the reading state that the parsers share.
--
-- `open` splits the text into lines (at `\r\n`, `\r` or `\n`; a UTF-8 byte-order mark
-- skipped), measures each line's indentation, reads the `%YAML` directive and the document
-- markers (`---`, `...`), and returns the state record that `tagpose.formats.yaml.block` and
-- `tagpose.formats.yaml.flow` pass between their functions:
--
--     {
--       name = string,         -- the file's name, for messages
--       lines = {string,...},  -- the physical lines, without their ends
--       nlines = int,
--       indent = {int,...},    -- spaces before the content; BLANK or MARKER for no content
--       next_content = {...},  -- next_content[i]: the first content line at or after i, or nil
--       line_no = int,         -- the line being read, for a message that names none
--       where = {},            -- where[container][key]: the line of a key or item
--       max_depth = int,       -- deepest nesting read
--     }
--
-- A refusal is raised as a `Failure` table `{message = "name:LINE: reason"}` and caught by
-- `tagpose.formats.yaml.decode`. Lines and columns are 1-based. Every function here is linear in
-- what it reads.
-- @module tagpose.formats.yaml.scanner

local failure = require("tagpose.formats.failure")

local byte, sub, find = string.byte, string.sub, string.find

local M = {}

-- the bytes the parsers look at
M.SPACE, M.TAB, M.HASH, M.COLON, M.DASH = 32, 9, 35, 58, 45
M.QUOTE1, M.QUOTE2 = 39, 34 -- ' "
M.COMMA, M.BANG, M.QUESTION = 44, 33, 63 -- , ! ?
M.LBRACKET, M.RBRACKET, M.LBRACE, M.RBRACE = 91, 93, 123, 125 -- [ ] { }
M.PERCENT = 37 -- %

--- `indent` of a blank or comment line.
M.BLANK = -1
--- `indent` of a directive or document marker: no content, and not allowed inside a flow
-- collection.
M.MARKER = -2

local SPACE, TAB, HASH, PERCENT = M.SPACE, M.TAB, M.HASH, M.PERCENT
local BLANK, MARKER = M.BLANK, M.MARKER

--- The metatable of the refusals raised while reading (`tagpose.formats.failure.Failure`).
M.Failure = failure.Failure

--- Refuse the document: raise `"name:LINE: reason"` (LINE `at`, or the line being read).
-- @tparam table st the state
-- @tparam string reason
-- @tparam[opt] int at the line
function M.fail(st, reason, at)
  failure.raise(st.name .. ":" .. (at or st.line_no) .. ": " .. reason)
end

local fail = M.fail

--- True for a space or a tab.
-- @tparam int|nil b a byte
-- @treturn boolean
function M.is_blank_byte(b)
  return b == SPACE or b == TAB
end

local is_blank_byte = M.is_blank_byte

--- The last position of s before `j + 1` that is not a space or tab, at least `i - 1` (linear).
-- @tparam string s
-- @tparam int i
-- @tparam int j
-- @treturn int
function M.rtrim_end(s, i, j)
  while j >= i and is_blank_byte(byte(s, j)) do j = j - 1 end
  return j
end

-- the lines of text at \r\n, \r or \n (linear: one find per line)
local function split_lines(text)
  local lines = {}
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
  return lines
end

-- indentation, directives and document markers of every line, into st.indent
local function classify(st)
  local lines, indent = st.lines, st.indent
  local content_seen, ended = false, nil
  for i = 1, st.nlines do
    local s = lines[i]
    st.line_no = i
    local _, e = find(s, "^ *")
    local b = byte(s, e + 1)
    if b == nil or b == HASH or (b == TAB and find(s, "^[ \t]*$")) or (b == TAB
      and find(s, "^[ \t]*#")) then
      indent[i] = BLANK
    elseif b == TAB then
      fail(st, "tab in indentation (YAML indents with spaces)")
    elseif e == 0 and b == PERCENT then
      if content_seen then fail(st, "a directive after the document's start") end
      if not (find(s, "^%%YAML[ :]1%.%d+[ \t]*$") or find(s, "^%%YAML[ :]1%.%d+[ \t]+#")) then
        fail(st, "directive '" .. s .. "' is not supported (only %YAML 1.x)")
      end
      indent[i] = MARKER
    elseif e == 0 and (find(s, "^%-%-%-[ \t]*$") or find(s, "^%-%-%-[ \t]+#")) then
      if content_seen then
        ended = ended or i
      end
      indent[i] = MARKER
    elseif e == 0 and find(s, "^%-%-%-[ \t]") then
      fail(st, "content on the '---' line is not supported")
    elseif e == 0 and (find(s, "^%.%.%.[ \t]*$") or find(s, "^%.%.%.[ \t]+#")) then
      ended = ended or i
      indent[i] = MARKER
    else
      if ended then
        fail(st, "a second document (after line " .. ended .. ") is not supported")
      end
      content_seen = true
      indent[i] = e
    end
  end
end

--- The state of a document to read, its lines classified (see the module's header).
-- @tparam string text the document
-- @tparam string name the file's name, for messages
-- @tparam int max_depth the deepest nesting read
-- @treturn table the state
-- @raise a `Failure` for a tab in indentation, an unsupported directive or a second document
function M.open(text, name, max_depth)
  local lines = split_lines(text)
  local st = { name = name, lines = lines, nlines = #lines, indent = {}, next_content = {},
    line_no = 0, where = {}, max_depth = max_depth }
  classify(st)
  local nxt, next_content, indent = nil, st.next_content, st.indent
  for i = st.nlines, 1, -1 do
    if indent[i] >= 0 then nxt = i end
    next_content[i] = nxt
  end
  return st
end

--- The first content line at or after line i, or nil at the end.
-- @tparam table st
-- @tparam int i
-- @treturn int|nil
function M.content_from(st, i)
  if i > st.nlines then return nil end
  return st.next_content[i]
end

--- Note the line of a key (or an item) of a container, for `where`.
-- @tparam table st
-- @tparam table container
-- @param key
-- @tparam int at
function M.record(st, container, key, at)
  local w = st.where[container]
  if not w then
    w = {}
    st.where[container] = w
  end
  w[key] = at
end

--- Refuse nesting deeper than the state's `max_depth`.
-- @tparam table st
-- @tparam int depth
-- @tparam int at the line
function M.check_depth(st, depth, at)
  if depth > st.max_depth then fail(st, "nesting deeper than " .. st.max_depth, at) end
end

--- True when the rest of line li from column p is blank or a comment.
-- @tparam table st
-- @tparam int li
-- @tparam int p
-- @treturn boolean
function M.rest_blank(st, li, p)
  local s = st.lines[li]
  local q = find(s, "[^ \t]", p)
  return q == nil or (byte(s, q) == HASH and (q == 1 or is_blank_byte(byte(s, q - 1))))
end

--- Refuse anything but a blank or a comment after a value on line li, from column p.
-- @tparam table st
-- @tparam int li
-- @tparam int p
function M.expect_rest_blank(st, li, p)
  if not M.rest_blank(st, li, p) then
    local s = st.lines[li]
    local q = find(s, "[^ \t]", p)
    if byte(s, q) == M.COLON then
      fail(st, "a mapping key here is not supported (a key must be a plain or quoted scalar)", li)
    end
    fail(st, "unexpected '" .. sub(s, q, q + 19) .. "' after the value", li)
  end
end

return M
