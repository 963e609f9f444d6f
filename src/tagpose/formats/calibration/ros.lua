--- ROS calibration files: `camera_calibration`'s YAML (`ost.yaml`, also what
-- `camera_info_manager` writes) and a `CameraInfo` message as `rostopic echo` or
-- `ros2 topic echo` print it.
--
-- * `camera_calibration`: `image_width, image_height, camera_name, camera_matrix {rows, cols,
--   data}, distortion_model, distortion_coefficients, rectification_matrix,
--   projection_matrix`;
-- * `CameraInfo`: `height, width, distortion_model, D, K, R, P, binning_x, binning_y, roi,
--   header`, or lower case `d, k, r, p`; binned images and a region of interest are refused.
--
-- Each reader takes the file's record of `tagpose.calibration.entries` and the `info` table
-- to fill, and returns the flat K, the coefficients and the distortion model's name.
-- @module tagpose.formats.calibration.ros

local yaml = require("tagpose.formats.yaml")
local common = require("tagpose.formats.calibration.common")
local entries = require("tagpose.formats.calibration.entries")

local concat = table.concat
local describe, key_name, sorted_keys = common.describe, common.key_name, common.sorted_keys
local fail, line, is_mapping = entries.fail, entries.line, entries.is_mapping
local matrix, shape, numbers, size = entries.matrix, entries.shape, entries.numbers, entries.size

local NULL = yaml.NULL

local M = {}

local ROS_KEYS = { "image_width", "image_height", "camera_name", "camera_matrix",
  "distortion_model", "distortion_coefficients", "rectification_matrix", "projection_matrix" }
local INFO_KEYS = { "header", "height", "width", "distortion_model", "D", "K", "R", "P",
  "binning_x", "binning_y", "roi" }
local INFO_KEYS_LOWER = { "header", "height", "width", "distortion_model", "d", "k", "r", "p",
  "binning_x", "binning_y", "roi" }
local COUNTS = { plumb_bob = { 5, 4 }, rational_polynomial = { 8 }, equidistant = { 4 },
  fisheye = { 4 }, pinhole = { 4, 5, 8 } }

local function refuse_unknown(y, known)
  local set = {}
  for _, k in ipairs(known) do set[k] = true end
  for _, k in ipairs(sorted_keys(y.doc)) do
    if not set[k] then
      local hint = type(k) == "string" and common.suggest(k, known)
      fail(y, y.top[k], "unknown key " .. key_name(k) .. (hint and (" (did you mean " .. hint
        .. "?)") or (" (a " .. (y.format == "ros" and "ROS camera_calibration file" or
        "CameraInfo message") .. " has " .. concat(known, ", ") .. ")")))
    end
  end
end

-- the distortion model named under key, or nil when none is given
local function model_of(y, key)
  local v = y.doc[key]
  if v == nil or v == NULL then return nil end
  if not common.MODELS[v] then
    fail(y, y.top[key], key .. ": 'plumb_bob', 'rational_polynomial' or 'equidistant' expected,"
      .. " got " .. describe(v))
  end
  return v
end

-- refuse n coefficients that the model does not have
local function check_count(y, model, n, at)
  if n == 0 then return end
  local want = COUNTS[model]
  for _, w in ipairs(want) do
    if n == w then return end
  end
  fail(y, at, "distortion_model " .. model .. " has " .. concat(want, " or ")
    .. " coefficients, the file gives " .. n)
end

--- Read a ROS `camera_calibration` file.
-- @tparam table y the file's record
-- @tparam table info filled with `width`, `height`, `name`, `rectification`, `projection`
-- @treturn {number,...} K, flat 3x3
-- @treturn {number,...} the coefficients
-- @treturn string the distortion model
function M.calibration(y, info)
  local doc = y.doc
  refuse_unknown(y, ROS_KEYS)
  local data, rows, cols = matrix(y, doc, "camera_matrix")
  local k = shape(y, data, rows, cols, 3, 3, "camera_matrix")
  if doc.distortion_coefficients == nil then
    fail(y, 1, "no distortion_coefficients (rows: 1, cols: 0, data: [] for none)")
  end
  data, rows, cols = matrix(y, doc, "distortion_coefficients")
  local d = entries.vector(y, data, rows, cols, "distortion_coefficients")
  local model = model_of(y, "distortion_model")
  if model == nil then
    if #d > 0 then
      fail(y, 1, "no distortion_model (plumb_bob, rational_polynomial or equidistant) for the "
        .. #d .. " coefficients")
    end
    model = "plumb_bob"
  end
  check_count(y, model, #d, line(y, doc, "distortion_coefficients"))
  info.width, info.height = size(y, "image_width"), size(y, "image_height")
  local cn = doc.camera_name
  if cn ~= nil and cn ~= NULL then
    if type(cn) ~= "string" and type(cn) ~= "number" then
      fail(y, y.top.camera_name, "camera_name: string expected, got " .. describe(cn))
    end
    info.name = tostring(cn)
  end
  if doc.rectification_matrix ~= nil then
    local r, rr, rc = matrix(y, doc, "rectification_matrix")
    info.rectification = shape(y, r, rr, rc, 3, 3, "rectification_matrix")
  end
  if doc.projection_matrix ~= nil then
    local p, pr, pc = matrix(y, doc, "projection_matrix")
    info.projection = shape(y, p, pr, pc, 3, 4, "projection_matrix")
  end
  return k, d, model
end

-- refuse binning and a region of interest: the corners would not be those of the full image
local function refuse_binning_and_roi(y)
  local doc, top = y.doc, y.top
  for _, b in ipairs({ "binning_x", "binning_y" }) do
    local v = doc[b]
    if v ~= nil and v ~= NULL and v ~= 0 and v ~= 1 then
      fail(y, top[b], b .. " " .. describe(v) .. ": binned images are not supported (the"
        .. " camera matrix is that of the full image)")
    end
  end
  local roi = doc.roi
  if roi ~= nil and roi ~= NULL then
    if not is_mapping(roi) then
      fail(y, top.roi, "roi: mapping expected, got " .. describe(roi))
    end
    for _, o in ipairs({ "x_offset", "y_offset" }) do
      local v = roi[o]
      if v ~= nil and v ~= NULL and v ~= 0 then
        fail(y, line(y, roi, o), "roi." .. o .. " " .. describe(v) .. ": a region of interest"
          .. " is not supported (the corners would need its offset)")
      end
    end
  end
end

--- Read a ROS `CameraInfo` message.
-- @tparam table y the file's record
-- @tparam table info filled with `width`, `height`, `name` (the header's `frame_id`),
--   `rectification`, `projection`
-- @treturn {number,...} K, flat 3x3
-- @treturn {number,...} the coefficients
-- @treturn string the distortion model
function M.camera_info(y, info)
  local doc, top = y.doc, y.top
  local upper = doc.K ~= nil
  refuse_unknown(y, upper and INFO_KEYS or INFO_KEYS_LOWER)
  local K, D, R, P = "K", "D", "R", "P"
  if not upper then K, D, R, P = "k", "d", "r", "p" end
  local k = numbers(y, doc[K], top[K], K, 9)
  if doc[D] == nil then
    fail(y, 1, "no " .. D .. " (the distortion coefficients; [] for none)")
  end
  local d = numbers(y, doc[D], top[D], D)
  local model = model_of(y, "distortion_model")
  if model == nil then
    if #d > 0 then fail(y, 1, "no distortion_model for the " .. #d .. " coefficients") end
    model = "plumb_bob"
  end
  check_count(y, model, #d, top[D])
  info.width, info.height = size(y, "width"), size(y, "height")
  refuse_binning_and_roi(y)
  if is_mapping(doc.header) and type(doc.header.frame_id) == "string" then
    info.name = doc.header.frame_id
  end
  if doc[R] ~= nil then info.rectification = numbers(y, doc[R], top[R], R, 9) end
  if doc[P] ~= nil then info.projection = numbers(y, doc[P], top[P], P, 12) end
  return k, d, model
end

return M
