--- Corner logs, pose logs and camera files (docs/conventions.md), read row by row.
--
-- * Corner log: CSV with a header naming at least `frame,tag,u1,v1,u2,v2,u3,v3,u4,v4`
--   (further columns are kept by name and otherwise ignored), one row per detection;
--   optionally `time`, the frame's time in seconds (then read as the frame and tag are).
-- * Pose log: CSV `frame,tag,x,y,z,qw,qx,qy,qz,error,iterations,confidence,sx,...,srz`.
-- * Camera file: see `tagpose.calibration` (a Lua camera file is read as data).
--
-- The CSV is read as RFC 4180 writes it and as spreadsheets save it, one row a line: fields
-- separated by commas, a field in double quotes may hold commas and `""` for a quote but not
-- a line end (no log has one in a field: a stray quote costs its own line); spaces and tabs
-- around a field are trimmed; lines end in LF, CRLF or CR alone; a UTF-8 byte-order mark
-- before the header is skipped. Blank lines and lines whose first character (after spaces)
-- is `#` are skipped. The header names every column once (a repeated or empty name is
-- refused). Every other row is either read exactly or reported with its line number and the
-- reason, the same way on every VM: a row with more or fewer fields than the header, a quote
-- inside an unquoted field or text after a closing quote, a quoted field not closed on its
-- line, a line longer than `MAX_RECORD` bytes.
--
-- Numbers are decimal numerals (`compat.decimal`: `12`, `-0.5`, `6.5e+02`), the same on every
-- VM; `nan`, `inf`, `-inf` and `infinity` (any case, as C and Python print them) are read as
-- the values they name, and a numeral out of range as ±infinity, so that they are reported, not
-- guessed: a `frame` that is not a finite number, or a `tag` that is not a tag id (a whole
-- number of magnitude below 2^53, as everywhere in tagpose), makes the row malformed; a corner
-- that is not finite is left to the solver to refuse. Anything else (hexadecimal, `1,5`,
-- text) is not a number.
--
-- Readers take a path or an open file and read it in chunks (`tagpose.tools.csv`): memory
-- holds one row at a time. This module does file I/O, so it is for tools and replay, not for
-- the solve path.
-- @module tagpose.tools.log

local compat = require("tagpose.core.compat")
local tagpose = require("tagpose")
local csv_table = require("tagpose.tools.csv")
local output = require("tagpose.formats.output")
local tag_id = require("tagpose.tools.tag_id")

local decimal = compat.decimal
local concat = table.concat
local floor, huge, sqrt = math.floor, math.huge, math.sqrt

local M = {}

--- Header of a corner log.
M.CORNER_COLUMNS = { "frame", "tag", "u1", "v1", "u2", "v2", "u3", "v3", "u4", "v4" }
--- Header of a pose log.
M.POSE_COLUMNS = { "frame", "tag", "x", "y", "z", "qw", "qx", "qy", "qz", "error", "iterations",
  "confidence", "sx", "sy", "sz", "srx", "sry", "srz" }
--- Longest line read, in bytes; a longer one is reported.
M.MAX_RECORD = 1048576
--- Most columns a header may name.
M.MAX_COLUMNS = 10000

--- The number a CSV field denotes, or nil: a decimal numeral, or `nan`, `inf`, `infinity`
-- (any case, optionally signed).
-- @tparam string s the field, trimmed
-- @treturn number|nil
function M.number(s)
  local v = decimal(s)
  if v ~= nil then return v end
  if #s > 9 then return nil end
  local sign, word = s:match("^([-+]?)(%a+)$")
  if not word then return nil end
  word = word:lower()
  if word == "nan" then return 0 / 0 end
  if word == "inf" or word == "infinity" then return sign == "-" and -huge or huge end
  return nil
end

local number_of = M.number

local function is_finite(v)
  return v == v and v < huge and v > -huge
end

--- Open a CSV table with a header line, to read it row by row (`tagpose.tools.csv`).
-- @tparam string|file source a path or an open file (left open by `close`)
-- @tparam[opt] {string,...} required column names that must be in the header
-- @treturn table the reader: `header` (the column names), `column` (name → index),
--   `header_line`, and the methods `read()` → `fields, line` (an array of strings, trimmed
--   and unquoted, one per column), `false, line, reason` for a malformed row, `nil` at the
--   end; and `close()`
-- @return nil, string when the source cannot be opened, has no header, or the header names a
--   column twice, leaves one unnamed, or lacks a required column
function M.csv_reader(source, required)
  local reader, err = csv_table.reader(source, required, M.MAX_RECORD, M.MAX_COLUMNS)
  if not reader then return nil, "log: " .. err end
  return reader
end

-- the fields of a row by column name: numbers, strings, nil for empty fields
local function by_name(csv, fields)
  local out = {}
  local header = csv.header
  for i = 1, #header do
    local v = fields[i]
    if v ~= "" then
      local n = number_of(v)
      if n == nil then out[header[i]] = v else out[header[i]] = n end
    end
  end
  return out
end

-- check a frame or tag field: the number, or nil and the reason
local function key_field(fields, i, name, n)
  local v = fields[i]
  if v == "" then return nil, "column " .. name .. " is empty" end
  if n == nil then n = number_of(v) end
  if type(n) ~= "number" then n = nil end
  if n == nil then return nil, "column " .. name .. " is not a number" end
  if not is_finite(n) then return nil, "column " .. name .. " is not finite (" .. v .. ")" end
  if name == "tag" and not tag_id.is(n) then
    return nil, "column tag is not a tag id (" .. v .. " is not " .. tag_id.ID .. ")"
  end
  return n
end

--- Read a whole CSV table with a header line.
-- Numeric fields become numbers, empty fields `nil`, others stay strings.
-- @tparam string|file source a path or an open file
-- @tparam[opt] {string,...} required column names that must be in the header
-- @treturn {table,...} rows, each a table of fields by column name
-- @treturn {string,...} header column names
-- @treturn {{line=int, reason=string},...} problems: lines that could not be read
-- @treturn {int,...} the line number of each row
-- @return nil, string when the source cannot be opened or the header is not usable
function M.read_csv(source, required)
  local csv, err = M.csv_reader(source, required)
  if not csv then return nil, err end
  local rows, problems, lines = {}, {}, {}
  while true do
    local fields, line, reason = csv:read()
    if fields == nil then break end
    if fields then
      rows[#rows + 1] = by_name(csv, fields)
      lines[#lines + 1] = line
    else
      problems[#problems + 1] = { line = line, reason = reason }
    end
  end
  csv:close()
  return rows, csv.header, problems, lines
end

local Corners = {}
Corners.__index = Corners

--- Open a corner log, to read it detection by detection.
-- @tparam string|file source a path or an open file
-- @treturn table the reader, with `read()` → a detection `{frame =, tag =, corners = {{u, v},
--   ...}, time =, line =, fields =}` (`time` when the log has a `time` column: a row whose
--   time is empty or not a finite number is malformed; `fields`: the whole row by column
--   name, numbers as numbers), `false, line, reason` for a malformed row, `nil` at the end;
--   `has_time` (the log has a `time` column), and `close()`
-- @return nil, string when the file cannot be read or its header lacks a column
-- @usage
-- local reader = assert(log.corner_reader("corners.csv"))
-- while true do
--   local det, line, reason = reader:read()
--   if det == nil then break end
--   if det then solve(det) else print(line, reason) end
-- end
-- reader:close()
function M.corner_reader(source)
  local csv, err = M.csv_reader(source, M.CORNER_COLUMNS)
  if not csv then return nil, err end
  local index = {}
  for k, name in ipairs(M.CORNER_COLUMNS) do index[k] = csv.column[name] end
  return setmetatable({ csv = csv, index = index, header = csv.header,
    time_column = csv.column.time, has_time = csv.column.time ~= nil }, Corners)
end

function Corners:read()
  local fields, line, reason = self.csv:read()
  if fields == nil then return nil end
  if fields == false then return false, line, reason end
  local index = self.index
  local named = by_name(self.csv, fields)
  local frame, why = key_field(fields, index[1], "frame", named.frame)
  if frame == nil then return false, line, why end
  local tag
  tag, why = key_field(fields, index[2], "tag", named.tag)
  if tag == nil then return false, line, why end
  local time
  if self.time_column then
    time, why = key_field(fields, self.time_column, "time", named.time)
    if time == nil then return false, line, why end
  end
  local c = {}
  for k = 3, 10 do
    local name = M.CORNER_COLUMNS[k]
    local n = named[name]
    if n == nil then return false, line, "column " .. name .. " is empty" end
    if type(n) ~= "number" then return false, line, "column " .. name .. " is not a number" end
    c[k - 2] = n
  end
  return { frame = frame, tag = tag, line = line, fields = named, time = time,
    corners = { { c[1], c[2] }, { c[3], c[4] }, { c[5], c[6] }, { c[7], c[8] } } }
end

function Corners:close()
  self.csv:close()
end

local function read_all(reader)
  local out, problems = {}, {}
  while true do
    local item, line, reason = reader:read()
    if item == nil then break end
    if item then
      out[#out + 1] = item
    else
      problems[#problems + 1] = { line = line, reason = reason }
    end
  end
  reader:close()
  return out, problems
end

--- Read a whole corner log.
-- A row whose frame, tag or corner fields are missing or not numbers is reported in the
-- problems list and left out of the rows.
-- @tparam string|file source a path or an open file
-- @treturn {table,...} detections `{frame =, tag =, corners = {{u, v}, ...}, line =, fields =}`
--   in file order (`fields`: the whole row by column name)
-- @treturn {{line=int, reason=string},...} problems, in file order
-- @return nil, string when the file cannot be read or lacks a column
function M.read_corners(source)
  local reader, err = M.corner_reader(source)
  if not reader then return nil, err end
  return read_all(reader)
end

local POSE_FIELDS = { "x", "y", "z", "qw", "qx", "qy", "qz" }

local Poses = {}
Poses.__index = Poses

--- Open a pose log, or a truth file of the data sets (`frame,tag,x,y,z,qw,qx,qy,qz`: the
-- `error` and `iterations` columns are optional), to read it row by row.
-- A row whose pose fields are all empty is a failed row: it is returned with `pose = nil`. A
-- row with some pose fields empty or not finite numbers, or without a finite frame and tag,
-- is malformed.
-- @tparam string|file source a path or an open file
-- @treturn table the reader, with `read()` → an entry `{frame =, tag =, line =, pose =,
--   track =}` (`pose` shaped as a `tagpose.solve` result: `{position = {x, y, z}, quaternion
--   = {w, x, y, z}, error =, iterations =}`, the quaternion as written, or `nil`; `track` a
--   `track` column's value, which tells apart the tags sharing an id as the data sets' truth
--   files do), `false, line, reason` for a malformed row, `nil` at the end; and `close()`
-- @return nil, string when the file cannot be read or lacks a column
function M.pose_reader(source)
  local required = { "frame", "tag" }
  for i = 1, #POSE_FIELDS do required[#required + 1] = POSE_FIELDS[i] end
  local csv, err = M.csv_reader(source, required)
  if not csv then return nil, err end
  local index = {}
  for k, name in ipairs(required) do index[k] = csv.column[name] end
  return setmetatable({ csv = csv, index = index, required = required,
    error_column = csv.column.error, iterations_column = csv.column.iterations,
    track_column = csv.column.track }, Poses)
end

function Poses:read()
  local fields, line, reason = self.csv:read()
  if fields == nil then return nil end
  if fields == false then return false, line, reason end
  local index = self.index
  local frame, why = key_field(fields, index[1], "frame")
  if frame == nil then return false, line, why end
  local tag
  tag, why = key_field(fields, index[2], "tag")
  if tag == nil then return false, line, why end
  local v, empty, bad = {}, 0, nil
  for k = 3, #self.required do
    local s = fields[index[k]]
    local name = self.required[k]
    if s == "" then
      empty = empty + 1
      bad = bad or ("column " .. name .. " is empty")
    else
      local n = number_of(s)
      if n == nil then
        return false, line, "column " .. name .. " is not a number"
      elseif not is_finite(n) then
        return false, line, "column " .. name .. " is not finite (" .. s .. ")"
      end
      v[k - 2] = n
    end
  end
  local track = self.track_column and fields[self.track_column] or ""
  track = track ~= "" and (number_of(track) or track) or nil
  if empty == #POSE_FIELDS then
    return { frame = frame, tag = tag, line = line, track = track }
  elseif empty > 0 then
    return false, line, bad
  end
  local e = self.error_column and number_of(fields[self.error_column])
  local it = self.iterations_column and number_of(fields[self.iterations_column])
  return { frame = frame, tag = tag, line = line, track = track, pose = {
    position = { x = v[1], y = v[2], z = v[3] },
    quaternion = { w = v[4], x = v[5], y = v[6], z = v[7] },
    error = e, iterations = it,
  } }
end

function Poses:close()
  self.csv:close()
end

--- Read a whole pose log, or a truth file (see `pose_reader`).
-- @tparam string|file source a path or an open file
-- @treturn {table,...} entries `{frame =, tag =, line =, pose =}` in file order
-- @treturn {{line=int, reason=string},...} problems, in file order
-- @return nil, string when the file cannot be read or lacks a column
function M.read_poses(source)
  local reader, err = M.pose_reader(source)
  if not reader then return nil, err end
  return read_all(reader)
end

local function num(v)
  if v == nil then return "" end
  if v == 0 then return "0" end
  if v == floor(v) and v > -2 ^ 53 and v < 2 ^ 53 then return ("%.0f"):format(v) end
  return ("%.17g"):format(v)
end

-- the standard deviation in a covariance's diagonal entry i, or nil
local function deviation(cov, i)
  local row = type(cov) == "table" and cov[i]
  local v = type(row) == "table" and row[i]
  if type(v) == "number" and v >= 0 then return sqrt(v) end
  return nil
end

--- One pose-log line (without newline) for a frame, a tag and a pose (or `nil` for a row that
-- failed: its pose fields are left empty). After the pose, its `confidence` and the standard
-- deviations of its `covariance` (position `sx, sy, sz` in the tag size's unit, rotation
-- `srx, sry, srz` in radians, camera frame); empty when the pose has none.
-- @tparam number frame
-- @tparam number tag
-- @tparam[opt] table pose a `tagpose.solve` result
-- @tparam[opt] number confidence written instead of the pose's (a smoother's)
-- @treturn string
function M.pose_line(frame, tag, pose, confidence)
  if not pose then return num(frame) .. "," .. num(tag) .. ",,,,,,,,,,,,,,,," end
  local p, q, cov = pose.position, pose.quaternion, pose.covariance
  return concat({ num(frame), num(tag), num(p.x), num(p.y), num(p.z), num(q.w), num(q.x),
    num(q.y), num(q.z), num(pose.error), num(pose.iterations), num(confidence or pose.confidence),
    num(deviation(cov, 1)), num(deviation(cov, 2)), num(deviation(cov, 3)),
    num(deviation(cov, 4)), num(deviation(cov, 5)), num(deviation(cov, 6)) }, ",")
end

local Writer = {}
Writer.__index = Writer

--- Open a pose log for writing row by row: the header now, a line per `write`. A path is
-- written whole or not at all (`tagpose.formats.output`: a temporary beside it renamed onto it
-- by `close`: the old file kept until the log is complete); a device, FIFO or pipe through.
-- @tparam string|file target a path (replaced by `close`) or an open file (left open, flushed
--   by `close`)
-- @treturn table the writer, with `write(frame, tag, pose[, confidence])` (as `pose_line`),
--   `close()` → the number of rows written, or `nil, string` when writing failed (the path
--   is then left as it was), and `abort()` (the path left as it was)
-- @return nil, string when the file cannot be written
function M.pose_writer(target)
  local f, out = target, nil
  if type(target) == "string" then
    local err
    out, err = output.open(target)
    if not out then return nil, "log: " .. err end
    f = out
  end
  local self = setmetatable({ f = f, out = out, n = 0, pending = {}, err = nil }, Writer)
  self.pending[1] = concat(M.POSE_COLUMNS, ",")
  return self
end

-- write the pending lines (once the target has failed, drop them: memory stays bounded)
function Writer:flush()
  local pending = self.pending
  if #pending == 0 then return end
  if not self.err then
    pending[#pending + 1] = ""
    local ok, err = self.f:write(concat(pending, "\n"))
    if not ok then self.err = tostring(err) end
  end
  self.pending = {}
end

function Writer:write(frame, tag, pose, confidence)
  local pending = self.pending
  pending[#pending + 1] = M.pose_line(frame, tag, pose, confidence)
  self.n = self.n + 1
  if #pending >= 512 then self:flush() end
end

function Writer:close()
  self:flush()
  local err = self.err
  if self.out then
    if err then
      self.out:abort()
    else
      local ok, cerr = self.out:commit()
      if not ok then err = cerr end
    end
  elseif not err then
    local ok, ferr = self.f:flush()
    if not ok then err = tostring(ferr) end
  end
  if err then return nil, "log: " .. err end
  return self.n
end

function Writer:abort()
  self.pending = {}
  if self.out then self.out:abort() end
end

--- Write a whole pose log: the header, then one line per entry, in the entries' order.
-- @tparam string|file target a path (written whole or not at all, as `pose_writer`) or an
--   open file (left open)
-- @tparam {table,...} entries `{frame =, tag =, pose =}` each; a `nil` pose is a row that
--   failed and keeps only its frame and tag
-- @treturn int the number of rows written
-- @return nil, string when the file cannot be written
function M.write_poses(target, entries)
  local writer, err = M.pose_writer(target)
  if not writer then return nil, err end
  for i = 1, #entries do
    local e = entries[i]
    writer:write(e.frame, e.tag, e.pose)
  end
  return writer:close()
end

--- Read a camera file: `tagpose.calibration.read` (a Lua camera file as data, ROS, OpenCV).
-- @tparam string path
-- @treturn table the camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table what else the file said (`tag_size`, `block_size`, `width`, `height`, ...)
-- @return nil, string when the file cannot be read or is refused
function M.read_camera(path)
  return tagpose.calibration.read(path)
end

return M
