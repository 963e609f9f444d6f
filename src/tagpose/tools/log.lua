--- Corner logs, pose logs and camera files: the data formats of DESIGN.md.
--
-- * Corner log: CSV with a header naming at least `frame,tag,u1,v1,u2,v2,u3,v3,u4,v4`
--   (further columns are kept by name and otherwise ignored), one row per detection.
-- * Pose log: CSV `frame,tag,x,y,z,qw,qx,qy,qz,error,iterations`.
-- * Camera file: a Lua file returning `{fx =, fy =, cx =, cy =, distortion = ..., tag_size =}`.
--
-- Blank lines and lines starting with `#` are skipped. A malformed line is never dropped
-- silently: readers return it in a list of problems with its line number and the reason.
-- This module does file I/O, so it is for tools and replay, not for the solve path.
-- @module tagpose.tools.log

local compat = require("tagpose.compat")

local M = {}

--- Header of a corner log.
M.CORNER_COLUMNS = { "frame", "tag", "u1", "v1", "u2", "v2", "u3", "v3", "u4", "v4" }
--- Header of a pose log.
M.POSE_COLUMNS = { "frame", "tag", "x", "y", "z", "qw", "qx", "qy", "qz", "error", "iterations" }

local function split(line)
  local fields = {}
  for v in (line .. ","):gmatch("([^,]*),") do
    fields[#fields + 1] = v:match("^%s*(.-)%s*$")
  end
  return fields
end

local function lines_of(source)
  if type(source) == "string" then
    local f, err = io.open(source, "r")
    if not f then return nil, err end
    return f, nil, true
  end
  return source
end

--- Read a CSV table with a header line.
-- Numeric fields become numbers, empty fields `nil`, others stay strings.
-- @tparam string|file source a path or an open file
-- @tparam[opt] {string,...} required column names that must be in the header
-- @treturn {table,...} rows, each a table of fields by column name plus `line` (its line number)
-- @treturn {string,...} header column names
-- @treturn {{line=int, reason=string},...} problems: lines that could not be read
-- @return nil, string when the source cannot be opened or the header lacks a required column
function M.read_csv(source, required)
  local f, err, owned = lines_of(source)
  if not f then return nil, "log: " .. tostring(err) end
  local header, rows, problems = nil, {}, {}
  local n = 0
  for line in f:lines() do
    n = n + 1
    line = line:gsub("\r$", "")
    local blank = line:match("^%s*$") or line:match("^%s*#")
    if not blank and not header then
      header = split(line)
      for _, name in ipairs(required or {}) do
        local found = false
        for _, h in ipairs(header) do
          if h == name then found = true end
        end
        if not found then
          if owned then f:close() end
          return nil, "log: header has no column '" .. name .. "' (line " .. n .. ")"
        end
      end
    elseif not blank then
      local fields = split(line)
      if #fields < #header then
        problems[#problems + 1] = { line = n, reason = ("%d fields, header has %d"):format(#fields,
          #header) }
      else
        local row = { line = n }
        for i, name in ipairs(header) do
          local v = fields[i]
          if v ~= "" then row[name] = tonumber(v) or v end
        end
        rows[#rows + 1] = row
      end
    end
  end
  if owned then f:close() end
  if not header then return nil, "log: no header line" end
  return rows, header, problems
end

--- Read a corner log.
-- A row whose frame, tag or corner fields are missing or not numbers is reported in the
-- problems list and left out of the rows.
-- @tparam string|file source a path or an open file
-- @treturn {table,...} detections `{frame =, tag =, corners = {{u, v}, ...}, line =, fields =}`
--   in file order (`fields`: the whole row by column name)
-- @treturn {{line=int, reason=string},...} problems
-- @return nil, string when the file cannot be read or lacks a column
function M.read_corners(source)
  local rows, header, problems = M.read_csv(source, M.CORNER_COLUMNS)
  if not rows then return nil, header end
  local out = {}
  for _, row in ipairs(rows) do
    local bad
    for _, name in ipairs(M.CORNER_COLUMNS) do
      if type(row[name]) ~= "number" then
        bad = "column " .. name .. " is " .. (row[name] == nil and "empty" or "not a number")
        break
      end
    end
    if bad then
      problems[#problems + 1] = { line = row.line, reason = bad }
    else
      out[#out + 1] = {
        frame = row.frame,
        tag = row.tag,
        line = row.line,
        fields = row,
        corners = { { row.u1, row.v1 }, { row.u2, row.v2 }, { row.u3, row.v3 },
          { row.u4, row.v4 } },
      }
    end
  end
  table.sort(problems, function(a, b) return a.line < b.line end)
  return out, problems
end

local function num(v)
  if v == nil then return "" end
  if v == math.floor(v) and math.abs(v) < 2 ^ 53 then return ("%d"):format(v) end
  return ("%.17g"):format(v)
end

--- One pose-log line (without newline) for a frame, a tag and a pose (or `nil` for a row that
-- failed: its pose fields are left empty).
-- @tparam number frame
-- @tparam number tag
-- @tparam[opt] table pose a `tagpose.solve` result
-- @treturn string
function M.pose_line(frame, tag, pose)
  if not pose then return num(frame) .. "," .. num(tag) .. ",,,,,,,,," end
  local p, q = pose.position, pose.quaternion
  return table.concat({ num(frame), num(tag), num(p.x), num(p.y), num(p.z), num(q.w), num(q.x),
    num(q.y), num(q.z), num(pose.error), num(pose.iterations) }, ",")
end

--- Write a whole pose log: the header, then one line per entry, in the entries' order.
-- @tparam string|file target a path (created or truncated) or an open file (left open)
-- @tparam {table,...} entries `{frame =, tag =, pose =}` each; a `nil` pose is a row that
--   failed and keeps only its frame and tag
-- @treturn int the number of rows written
-- @return nil, string when the file cannot be written
function M.write_poses(target, entries)
  local f, owned = target, false
  if type(target) == "string" then
    local err
    f, err = io.open(target, "w")
    if not f then return nil, "log: " .. tostring(err) end
    owned = true
  end
  local lines = { table.concat(M.POSE_COLUMNS, ",") }
  for i = 1, #entries do
    local e = entries[i]
    lines[i + 1] = M.pose_line(e.frame, e.tag, e.pose)
  end
  lines[#lines + 1] = ""
  local ok, err = f:write(table.concat(lines, "\n"))
  if owned then
    local closed, cerr = f:close()
    if ok and not closed then ok, err = nil, cerr end
  end
  if not ok then return nil, "log: " .. tostring(err) end
  return #entries
end

local POSE_FIELDS = { "x", "y", "z", "qw", "qx", "qy", "qz" }

--- Read a pose log, or a truth file of the data sets (`frame,tag,x,y,z,qw,qx,qy,qz`: the
-- `error` and `iterations` columns are optional).
-- A row whose pose fields are all empty is a failed row: it is returned with `pose = nil`. A
-- row with some pose fields empty or not numbers, or without a numeric frame and tag, is
-- reported in the problems list and left out.
-- @tparam string|file source a path or an open file
-- @treturn {table,...} entries `{frame =, tag =, line =, pose =}` in file order, each `pose`
--   (or `nil`) shaped as a `tagpose.solve` result: `{position = {x, y, z},
--   quaternion = {w, x, y, z}, error =, iterations =}` (the quaternion as written, not
--   normalised)
-- @treturn {{line=int, reason=string},...} problems
-- @return nil, string when the file cannot be read or lacks a column
function M.read_poses(source)
  local required = { "frame", "tag" }
  for i = 1, #POSE_FIELDS do required[#required + 1] = POSE_FIELDS[i] end
  local rows, header, problems = M.read_csv(source, required)
  if not rows then return nil, header end
  local out = {}
  for _, row in ipairs(rows) do
    local bad, empty = nil, 0
    for _, name in ipairs(required) do
      local v = row[name]
      if v == nil then
        empty = empty + 1
        if name == "frame" or name == "tag" then bad = "column " .. name .. " is empty" end
      elseif type(v) ~= "number" then
        bad = bad or "column " .. name .. " is not a number"
      end
    end
    if not bad and empty > 0 and empty < #POSE_FIELDS then
      for _, name in ipairs(POSE_FIELDS) do
        if row[name] == nil then
          bad = "column " .. name .. " is empty"
          break
        end
      end
    end
    if bad then
      problems[#problems + 1] = { line = row.line, reason = bad }
    else
      local pose = nil
      if empty == 0 then
        local e, n = row.error, row.iterations
        pose = {
          position = { x = row.x, y = row.y, z = row.z },
          quaternion = { w = row.qw, x = row.qx, y = row.qy, z = row.qz },
          error = type(e) == "number" and e or nil,
          iterations = type(n) == "number" and n or nil,
        }
      end
      out[#out + 1] = { frame = row.frame, tag = row.tag, line = row.line, pose = pose }
    end
  end
  table.sort(problems, function(a, b) return a.line < b.line end)
  return out, problems
end

--- Read a camera file (a Lua file returning a table), without giving it access to anything.
-- @tparam string path
-- @treturn table the camera
-- @return nil, string when the file cannot be loaded or does not return a table
function M.read_camera(path)
  local f, err = io.open(path, "r")
  if not f then return nil, "log: " .. tostring(err) end
  local text = f:read("*a")
  f:close()
  local chunk
  chunk, err = compat.load_text(text, "=" .. path, {})
  if not chunk then return nil, "log: " .. tostring(err) end
  local ok, camera = pcall(chunk)
  if not ok then return nil, "log: " .. tostring(camera) end
  if type(camera) ~= "table" then return nil, "log: " .. path .. " does not return a table" end
  return camera
end

return M
