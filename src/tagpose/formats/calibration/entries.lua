--- The entries of a YAML calibration file: which format it is, and readers of its typed
-- entries (numbers, `{rows, cols, data}` matrices, sizes) that refuse what is malformed with
-- its line.
--
-- `open` returns the record the format readers (`tagpose.calibration.ros`,
-- `tagpose.calibration.opencv`) pass to these functions:
--
--     { name = string, doc = table, where = table, top = table, format = string }
--
-- (`doc` the decoded mapping, `where` the lines of `tagpose.formats.yaml.decode`, `top` the lines
-- of `doc`'s keys, `format` `"ros"`, `"camera_info"`, `"opencv"` or `"kalibr"`; OpenCV's XML and
-- JSON give the same record, `tagpose.calibration.storage`). Functions raise the `Failure` of
-- `tagpose.calibration.common`.
-- @module tagpose.formats.calibration.entries

local compat = require("tagpose.core.compat")
local yaml = require("tagpose.formats.yaml")
local common = require("tagpose.formats.calibration.common")

local is_finite = compat.is_finite
local concat = table.concat
local describe, key_name, sorted_keys = common.describe, common.key_name, common.sorted_keys
local is_integer, suggest = common.is_integer, common.suggest

local NULL, TAG = yaml.NULL, yaml.TAG

local M = {}

--- The names an OpenCV file gives its camera matrix.
M.CV_MATRIX = { "camera_matrix", "cameraMatrix", "K" }

--- Refuse the file at a line.
-- @tparam table y the file's record
-- @tparam int|nil at
-- @tparam string reason
function M.fail(y, at, reason)
  common.fail(y.name, at, reason)
end

local fail = M.fail

--- The line of a key of a container of the document, or nil.
-- @tparam table y
-- @tparam table container
-- @param key
-- @treturn int|nil
function M.line(y, container, key)
  local w = y.where[container]
  return w and w[key]
end

local line = M.line

--- True for a mapping (not `NULL`, no array part).
-- @param v
-- @treturn boolean
function M.is_mapping(v)
  return type(v) == "table" and v ~= NULL and v[1] == nil
end

--- True for a sequence (or an empty collection), untagged.
-- @param v
-- @treturn boolean
function M.is_sequence(v)
  return type(v) == "table" and v ~= NULL and (v[1] ~= nil or next(v) == nil) and v[TAG] == nil
end

local is_mapping, is_sequence = M.is_mapping, M.is_sequence

-- which format: an !!opencv-matrix, ROS's camera_matrix, CameraInfo's K, Kalibr's cam0
local function format_of(y)
  local doc = y.doc
  for _, k in ipairs(M.CV_MATRIX) do
    if type(doc[k]) == "table" and doc[k][TAG] then return "opencv" end
  end
  if doc.camera_matrix ~= nil then return "ros" end
  if doc.K ~= nil or doc.k ~= nil then return "camera_info" end
  for k, v in pairs(doc) do -- a Kalibr camchain: cam0, cam1, ... mappings
    if type(k) == "string" and k:match("^cam%d+$") and is_mapping(v) then return "kalibr" end
  end
  local suggest_matrix = common.suggester({ "camera_matrix", "K" })
  for _, k in ipairs(sorted_keys(doc)) do
    local hint = suggest_matrix(k)
    if hint then fail(y, y.top[k], "unknown key " .. key_name(k) .. " (did you mean " .. hint
      .. "?)") end
  end
  fail(y, 1, "no camera matrix: not a ROS camera_calibration file (camera_matrix), a"
    .. " CameraInfo message (K), an OpenCV FileStorage file (camera_matrix: !!opencv-matrix) or"
    .. " a Kalibr camchain (cam0: {camera_model, intrinsics, ...})")
end

--- Decode a YAML calibration file and tell its format.
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table the file's record
function M.open(text, name)
  local doc, where = yaml.decode(text, name)
  if doc == nil then common.refuse("calibration: " .. where) end
  local y = { name = name, doc = doc, where = where }
  if not is_mapping(doc) or next(doc) == nil then
    fail(y, 1, "a mapping of calibration entries expected (camera_matrix, distortion_model, ...)")
  end
  y.top = where[doc]
  y.format = format_of(y)
  return y
end

--- A sequence of finite numbers (of `count` of them, when given).
-- @tparam table y
-- @param seq the entry
-- @tparam int|nil at its line
-- @tparam string what its name, for messages
-- @tparam[opt] int count
-- @treturn {number,...} seq
function M.numbers(y, seq, at, what, count)
  if not is_sequence(seq) then
    fail(y, at, what .. ": a sequence of numbers expected, got " .. describe(seq))
  end
  for i = 1, #seq do
    if not is_finite(seq[i]) then
      fail(y, line(y, seq, i) or at, what .. "[" .. i .. "]: number expected, got "
        .. describe(seq[i]))
    end
  end
  if count and #seq ~= count then
    fail(y, at, what .. ": " .. count .. " numbers expected, got " .. #seq)
  end
  return seq
end

-- the fields of the matrix m under key: all there, no other
local function check_fields(y, m, key, at, tagged)
  local fields = tagged and { "rows", "cols", "dt", "data" } or { "rows", "cols", "data" }
  local set = {}
  for _, f in ipairs(fields) do
    set[f] = true
    if m[f] == nil then fail(y, at, key .. ": no " .. f) end
  end
  for _, f in ipairs(sorted_keys(m)) do
    if not set[f] then
      local hint = type(f) == "string" and suggest(f, fields)
      fail(y, line(y, m, f) or at, key .. ": unknown key " .. key_name(f) .. " (" .. (hint
        and ("did you mean " .. hint .. "?") or ("a matrix has " .. concat(fields, ", "))) .. ")")
    end
  end
end

--- A `{rows, cols, data}` matrix (with `dt` too, and `!!opencv-matrix`, when tagged).
-- @tparam table y
-- @tparam table parent the mapping that holds it
-- @param key its key there
-- @tparam[opt] boolean tagged
-- @treturn {number,...} data
-- @treturn int rows
-- @treturn int cols
function M.matrix(y, parent, key, tagged)
  local m = parent[key]
  local at = line(y, parent, key)
  if tagged then
    if type(m) ~= "table" or m[TAG] ~= "opencv-matrix" then
      fail(y, at, key .. ": an opencv-matrix expected, got " .. describe(m))
    end
  elseif not is_mapping(m) then
    fail(y, at, key .. ": a mapping {rows, cols, data} expected, got " .. describe(m))
  end
  check_fields(y, m, key, at, tagged)
  local rows, cols = m.rows, m.cols
  if not is_integer(rows, 0) then
    fail(y, line(y, m, "rows"), key .. ".rows: whole number expected, got " .. describe(rows))
  end
  if not is_integer(cols, 0) then
    fail(y, line(y, m, "cols"), key .. ".cols: whole number expected, got " .. describe(cols))
  end
  if tagged and m.dt ~= "d" and m.dt ~= "f" then
    fail(y, line(y, m, "dt"), key .. ".dt: 'd' or 'f' (one channel of doubles or floats)"
      .. " expected, got " .. describe(m.dt))
  end
  local data = M.numbers(y, m.data, line(y, m, "data"), key .. ".data")
  if #data ~= rows * cols then
    fail(y, line(y, m, "data"), key .. ": " .. rows .. "x" .. cols .. " = " .. rows * cols
      .. " numbers expected, got " .. #data)
  end
  return data, rows, cols
end

--- A matrix's data, refused unless it is r x c.
-- @tparam table y
-- @tparam {number,...} data
-- @tparam int rows
-- @tparam int cols
-- @tparam int r
-- @tparam int c
-- @tparam string key the entry's key, for messages
-- @treturn {number,...} data
function M.shape(y, data, rows, cols, r, c, key)
  if rows ~= r or cols ~= c then
    fail(y, line(y, y.doc, key), key .. ": a " .. r .. "x" .. c .. " matrix expected, got "
      .. rows .. "x" .. cols)
  end
  return data
end

--- A matrix's data, refused unless it is one row or one column.
-- @tparam table y
-- @tparam {number,...} data
-- @tparam int rows
-- @tparam int cols
-- @tparam string key
-- @treturn {number,...} data
function M.vector(y, data, rows, cols, key)
  if rows ~= 1 and cols ~= 1 and #data > 0 then
    fail(y, line(y, y.doc, key), key .. ": one row or one column expected, got " .. rows .. "x"
      .. cols)
  end
  return data
end

--- An image size in pixels, or nil when it is not given (or 0: CameraInfo's "not set").
-- @tparam table y
-- @tparam string key
-- @treturn int|nil
function M.size(y, key)
  local v = y.doc[key]
  if v == nil or v == NULL then return nil end
  if not is_integer(v, 0) then
    fail(y, y.top[key], key .. ": whole number of pixels expected, got " .. describe(v))
  end
  if v == 0 then return nil end -- CameraInfo's "not set"
  return v
end

return M
