--- CSV tables with a header line, read row by row in chunks (one row in memory at a time).
--
-- The CSV is read as RFC 4180 writes it and as spreadsheets save it, one record a line: fields
-- separated by commas, a field in double quotes may hold commas and `""` for a quote (not a
-- line end: no log has one in a field, so a stray quote costs its own line, never the rest of
-- the file); spaces and tabs around a field are trimmed; lines end in LF, CRLF or CR alone; a
-- UTF-8 byte-order mark before the header is skipped. Blank lines and lines whose first
-- character (after spaces) is `#` are skipped. The header names every column once. A row is
-- read exactly or reported with its line and the reason: more or fewer fields than the
-- header, a quote inside an unquoted field or text after a closing quote, a quoted field not
-- closed on its line, a line longer than the reader's `max_record` bytes.
--
-- This is the reader underneath `tagpose.tools.log` (whose `csv_reader` documents the
-- reader's fields and methods); it does file I/O, so it is for the tools, not the solve path.
-- @module tagpose.tools.csv

local byte, sub, find, gmatch, concat = string.byte, string.sub, string.find, string.gmatch,
  table.concat

local M = {}

local CHUNK = 65536
local QUOTE, COMMA, HASH, SPACE, TAB, CR, LF = 34, 44, 35, 32, 9, 13, 10

-- physical lines, read in chunks

local Lines = {}
Lines.__index = Lines

local function open_lines(source, max_record)
  local f, owned = source, false
  if type(source) == "string" then
    local err
    f, err = io.open(source, "rb")
    if not f then return nil, err end
    owned = true
  end
  return setmetatable({ f = f, owned = owned, buf = "", pos = 1, line = 0, eof = false,
    started = false, pending_cr = false, max_record = max_record }, Lines)
end

-- the next chunk into buf (the byte-order mark and a pending CR's LF skipped); false at the end
function Lines:load()
  if self.eof then return false end
  local chunk, err = self.f:read(CHUNK)
  if chunk == nil or chunk == "" then
    self.eof = true
    self.err = err
    self.buf, self.pos = "", 1
    return false
  end
  self.buf, self.pos = chunk, 1
  if not self.started then
    self.started = true
    if sub(chunk, 1, 3) == "\239\187\191" then self.pos = 4 end
  end
  if self.pending_cr then
    self.pending_cr = false
    if byte(chunk, self.pos) == LF then self.pos = self.pos + 1 end
  end
  return true
end

-- the next line without its end: a string, false for a line longer than max_record (read
-- through), or nil at the end; self.line is its number
function Lines:next()
  local parts, size, max_record = nil, 0, self.max_record
  while true do
    if self.pos > #self.buf and not self:load() then
      if parts == nil then return nil end
      self.line = self.line + 1
      if size > max_record then return false end
      return concat(parts)
    end
    local buf, pos = self.buf, self.pos
    local i = find(buf, "[\r\n]", pos)
    if not i then
      -- the line goes on in the next chunk
      size = size + #buf - pos + 1
      if size <= max_record then
        parts = parts or {}
        parts[#parts + 1] = sub(buf, pos)
      end
      self.pos = #buf + 1
    else
      local j = i
      if byte(buf, i) == CR then
        if i == #buf then
          self.pending_cr = true
        elseif byte(buf, i + 1) == LF then
          j = i + 1
        end
      end
      self.pos = j + 1
      self.line = self.line + 1
      size = size + i - pos
      if size > max_record then return false end
      if parts == nil then return sub(buf, pos, i - 1) end
      parts[#parts + 1] = sub(buf, pos, i - 1)
      return concat(parts)
    end
  end
end

function Lines:close()
  if self.owned and self.f then self.f:close() end
  self.f = nil
end

-- fields of a record

-- the last position before j + 1 that is not a space or tab, at least i - 1 (linear)
local function rtrim_end(s, i, j)
  while j >= i do
    local b = byte(s, j)
    if b ~= SPACE and b ~= TAB then break end
    j = j - 1
  end
  return j
end

-- a line without quotes split at its commas: fields (the first `limit` kept), their count
local function split_plain(s, limit)
  local fields, count = {}, 0
  for field in gmatch(s .. ",", "([^,]*),") do
    count = count + 1
    if count <= limit then
      local b, e = byte(field, 1), byte(field, -1)
      if b == SPACE or b == TAB or e == SPACE or e == TAB then
        local q = find(field, "[^ \t]")
        field = q and sub(field, q, rtrim_end(field, q, #field)) or ""
      end
      fields[count] = field
    end
  end
  return fields, count
end

-- the quoted field whose quote is at column q of line s: its text and the column of the
-- closing quote; false when it does not close on its line (no field of a log spans lines: a
-- stray quote costs its own line, not the rest of the file)
local function quoted_field(s, q)
  local parts, pos = {}, q + 1
  while true do
    local i = find(s, '"', pos, true)
    if not i then return false end
    if byte(s, i + 1) == QUOTE then
      parts[#parts + 1] = sub(s, pos, i)
      pos = i + 2
    else
      parts[#parts + 1] = sub(s, pos, i - 1)
      return concat(parts), i
    end
  end
end

-- the unquoted field from column p (its first non-blank at q, or nil) of a line with quotes:
-- its text, or nil and the reason when it holds a quote; and the column of its end
local function unquoted_field(s, p, q, count)
  local e = find(s, '[,"]', p)
  if e and byte(s, e) == QUOTE then
    return nil, "a quote inside field " .. (count + 1) .. " (quote the whole field, with"
      .. " \"\" for a quote)"
  end
  e = e or #s + 1
  if q == nil or q >= e then return "", e end
  local last = byte(s, e - 1)
  return sub(s, q, (last == SPACE or last == TAB) and rtrim_end(s, q, e - 1) or e - 1), e
end

-- a record whose line s (line start) has quotes: as Csv:record
local function split_quoted(s, start, limit)
  local fields, count, p, bad = {}, 0, 1, nil
  while true do
    local q, b = p, byte(s, p)
    if b == SPACE or b == TAB then
      q = find(s, "[^ \t]", p)
      b = q and byte(s, q)
    end
    if b == QUOTE then
      local text, close = quoted_field(s, q)
      if text == false then
        return false, start, "quoted field " .. (count + 1) .. " not closed on its line"
      end
      count = count + 1
      if count <= limit then fields[count] = text end
      local r = find(s, "[^ \t]", close + 1)
      if r == nil then break end
      if byte(s, r) ~= COMMA then
        bad = bad or ("text after the closing quote of field " .. count)
        break
      end
      p = r + 1
    else
      local text, e = unquoted_field(s, p, q, count)
      if text == nil then
        bad = bad or e
        break
      end
      count = count + 1
      if count <= limit then fields[count] = text end
      if e > #s then break end
      p = e + 1
    end
  end
  if bad then return false, start, bad end
  return fields, start, count
end

local Csv = {}
Csv.__index = Csv

-- the next record: fields (at most `limit` kept), its first line and the number of fields;
-- false, line, reason for a malformed one; nil at the end
function Csv:record(limit)
  local lines = self.lines
  local s
  while true do
    s = lines:next()
    if s == nil then return nil end
    if s == false then
      return false, lines.line, "line longer than " .. lines.max_record .. " bytes"
    end
    local q = find(s, "[^ \t]")
    if q and byte(s, q) ~= HASH then break end
  end
  local start = lines.line
  if not find(s, '"', 1, true) then
    local fields, count = split_plain(s, limit)
    return fields, start, count
  end
  return split_quoted(s, start, limit)
end

-- the reason a header is refused (it names a column twice, leaves one unnamed, lacks a
-- required one), or nil; and the columns by name
local function check_header(header, count, line, required)
  local column = {}
  for i = 1, count do
    local name = header[i]
    if name == "" then return "header column " .. i .. " has no name (line " .. line .. ")" end
    if column[name] then
      return ("header names column '%s' twice (columns %d and %d, line %d)"):format(name,
        column[name], i, line)
    end
    column[name] = i
  end
  for _, name in ipairs(required or {}) do
    if not column[name] then
      local hint = ""
      if count == 1 then
        local sep = header[1]:match("[;\t|]")
        if sep then
          hint = ": its fields are separated by '" .. (sep == "\t" and "\\t" or sep)
            .. "', not commas"
        end
      end
      return "header has no column '" .. name .. "' (line " .. line .. ")" .. hint
    end
  end
  return nil, column
end

--- Open a CSV table with a header line, to read it row by row.
-- @tparam string|file source a path or an open file (left open by `close`)
-- @tparam[opt] {string,...} required column names that must be in the header
-- @tparam int max_record the longest line read, in bytes
-- @tparam int max_columns the most columns the header may name
-- @treturn table the reader: `header`, `column` (name → index), `header_line`, `width`;
--   `read()` → `fields, line`, `false, line, reason` or `nil` at the end; `close()`
-- @return nil, string the reason (without a module's prefix) when the source cannot be
--   opened, has no header or the header is refused
function M.reader(source, required, max_record, max_columns)
  local lines, err = open_lines(source, max_record)
  if not lines then return nil, tostring(err) end
  local self = setmetatable({ lines = lines }, Csv)
  local header, line, count = self:record(max_columns)
  local problem, column
  if header == false then
    problem = "header: " .. count .. " (line " .. line .. ")"
  elseif header == nil then
    problem = lines.err and tostring(lines.err) or "no header line"
  elseif count > max_columns then
    problem = "header has " .. count .. " columns, more than " .. max_columns .. " (line " .. line
      .. ")"
  else
    problem, column = check_header(header, count, line, required)
  end
  if problem then
    lines:close()
    return nil, problem
  end
  self.header, self.column, self.header_line = header, column, line
  self.width = count
  return self
end

function Csv:read()
  local fields, line, count = self:record(self.width)
  if fields == nil then return nil end
  if fields == false then return false, line, count end
  if count ~= self.width then
    return false, line, ("%d fields, header has %d"):format(count, self.width)
  end
  return fields, line
end

function Csv:close()
  self.lines:close()
end

return M
