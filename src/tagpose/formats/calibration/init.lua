--- Calibration files: the camera (and the tag sizes) of the files users have.
--
-- `read` takes a file in one of these formats and returns a plain tagpose camera
-- `{fx =, fy =, cx =, cy =, model =, distortion =}`, built by `tagpose.camera.from_matrix`,
-- and what else the file said:
--
-- * a **Lua camera file**, read as data (`tagpose.formats.luadata`: nothing in it runs):
--   `return { fx =, fy =, cx =, cy =, model =, distortion =, width =, height =, name =,
--   tag_size =, block_size =, unit = }`; `distortion` named (`{k1 =, k2 =, p1 =, p2 =, k3 =}`,
--   `k4..k6` for the rational model, `k1..k4` with `model = "fisheye"`) or an array in OpenCV's
--   `distCoeffs` order; `tag_size` a number or `{[id] = size, default = size}`;
-- * **ROS `camera_calibration`** YAML (`ost.yaml`; also what `camera_info_manager` writes):
--   `image_width, image_height, camera_name, camera_matrix {rows, cols, data},
--   distortion_model, distortion_coefficients, rectification_matrix, projection_matrix`;
-- * a **ROS `CameraInfo` message** as `rostopic echo` / `ros2 topic echo` print it (`height,
--   width, distortion_model, D, K, R, P, binning_x, binning_y, roi, header`, or lower case
--   `d, k, r, p`);
-- * **OpenCV FileStorage** YAML (`%YAML:1.0`) with `!!opencv-matrix` entries, under the names
--   OpenCV's calibration samples write (`camera_matrix`, `distortion_coefficients`,
--   `image_width`, `image_height`, `fisheye_model`) or the short `K` / `D` (also `cameraMatrix` /
--   `distCoeffs`).
--
-- A Lua file is told by its name ending in `.lua`, a YAML file by `.yaml` or `.yml`; another
-- name by its text (`return` or `--` first: Lua). Anything not understood is refused with its
-- line: an unknown key (naming the likely intended one), a missing or malformed entry, a
-- distortion model or coefficient count tagpose does not have. In OpenCV files, whose
-- samples store much else (`avg_reprojection_error`, `extrinsic_parameters`, ...), unknown
-- keys are listed in `info.ignored` instead, unless they look like a misspelling of a key that
-- is read.
--
-- The camera is that of the image the calibration was made on (`K`, `D`): corners detected
-- on a rectified image (`image_rect`) belong instead to `info.projection` without distortion.
--
-- The formats are read by `tagpose.calibration.lua_file`, `tagpose.calibration.ros` and
-- `tagpose.calibration.opencv` (the YAML entries by `tagpose.calibration.entries`), with the
-- messages, suggestions and lens models of `tagpose.calibration.common`.
-- @module tagpose.formats.calibration

local common = require("tagpose.formats.calibration.common")
local entries = require("tagpose.formats.calibration.entries")
local lua_file = require("tagpose.formats.calibration.lua_file")
local ros = require("tagpose.formats.calibration.ros")
local opencv = require("tagpose.formats.calibration.opencv")

local M = {}

--- Largest calibration file read, in bytes (a calibration is a few hundred).
M.MAX_BYTES = 1048576

--- The candidate a mistyped key most likely meant (differing in case only, or by one edit
-- for a key of up to 4 characters, two for a longer one; an edit is an insertion, a deletion,
-- a substitution or a swap of neighbours), or nil.
-- @function suggest
-- @tparam string key
-- @tparam {string,...} candidates
-- @treturn string|nil
M.suggest = common.suggest

local READERS = { ros = ros.calibration, camera_info = ros.camera_info, opencv = opencv.read }

local function yaml_camera(text, name)
  local y = entries.open(text, name)
  local info = { format = y.format, path = name }
  local k, d, model = READERS[y.format](y, info)
  info.distortion_model = model
  local top = y.top
  local at = top.camera_matrix or top.K or top.k or top.cameraMatrix
  local camera = common.build(k, d, model, function(reason) entries.fail(y, at, reason) end)
  return camera, info
end

local function is_lua(text, name)
  if name:match("%.[lL][uU][aA]$") then return true end
  if name:match("%.[yY][aA]?[mM][lL]$") then return false end
  local first = text:match("^%s*(%S%S?)") -- "re"turn or "--"
  return first == "--" or (first == "re" and text:match("^%s*return[%s{]") ~= nil)
end

--- Read a calibration from its text.
-- @tparam string text the file's text
-- @tparam string name the file's name: its ending (`.lua`, `.yaml`, `.yml`) tells the format,
--   and it names the file in messages
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info: `format` (`"lua"`, `"ros"`, `"camera_info"` or `"opencv"`), `path`,
--   and what the file gives of `width`, `height` (pixels), `name`, `distortion_model`,
--   `rectification` (flat 3x3), `projection` (flat 3x4), `ignored` (OpenCV keys not read) and,
--   from a Lua file, `tag_size` (a number or `{[id] = size, default = size}`), `block_size`,
--   `unit` (the name of the unit of `tag_size`)
-- @return nil, string `"calibration: NAME:LINE: reason"`
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
function M.decode(text, name)
  if type(text) ~= "string" then
    error("bad argument #1 to 'decode' (string expected, got " .. type(text) .. ")", 2)
  end
  if type(name) ~= "string" then
    error("bad argument #2 to 'decode' (string expected, got " .. type(name) .. ")", 2)
  end
  local ok, camera, info = pcall(is_lua(text, name) and lua_file.read or yaml_camera, text, name)
  if ok then return camera, info end
  if getmetatable(camera) == common.Failure then return nil, camera.message end
  error(camera, 0)
end

--- Read a calibration file (Lua camera file, ROS or OpenCV YAML; see the module's header).
-- @tparam string path
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info (see `decode`)
-- @return nil, string `"calibration: PATH:LINE: reason"` (or `"calibration: PATH: reason"`
--   when the file cannot be read)
-- @raise `bad argument #1 to 'read' (...)` when `path` is not a string
-- @usage
-- local camera, info = assert(tagpose.calibration.read("ost.yaml"))
-- local pose = tagpose.solve(corners, camera, 0.024)
function M.read(path)
  if type(path) ~= "string" then
    error("bad argument #1 to 'read' (string expected, got " .. type(path) .. ")", 2)
  end
  local f, err = io.open(path, "rb")
  if not f then return nil, "calibration: " .. tostring(err) end
  local text, rerr = f:read(M.MAX_BYTES + 1)
  f:close()
  if text == nil then
    if rerr then return nil, "calibration: " .. path .. ": " .. tostring(rerr) end
    text = ""
  end
  if #text > M.MAX_BYTES then
    return nil, "calibration: " .. path .. ": larger than " .. M.MAX_BYTES .. " bytes (a"
      .. " calibration is a few lines)"
  end
  return M.decode(text, path)
end

return M
