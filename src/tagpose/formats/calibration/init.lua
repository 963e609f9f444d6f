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
-- * **OpenCV FileStorage** YAML (`%YAML:1.0`, `!!opencv-matrix` entries), XML
--   (`<opencv_storage>`, `type_id="opencv-matrix"`) or JSON (`"type_id": "opencv-matrix"`),
--   under the names OpenCV's calibration samples write (`camera_matrix`,
--   `distortion_coefficients`, `image_width`, `image_height`, `fisheye_model`: the tutorial's
--   `out_camera_data.xml`) or the short `K` / `D` (also `cameraMatrix` / `distCoeffs`);
-- * a **Kalibr camchain** (`camchain.yaml`, `camchain-imucam.yaml`): `cam0`, `cam1`, ... each
--   with `camera_model: pinhole`, `intrinsics: [fu, fv, pu, pv]`, `distortion_model` `radtan`
--   (= `plumb_bob`), `equidistant` (the fisheye) or `none`, `distortion_coeffs`, `resolution`,
--   ...; `cam0` is read unless `read(path, "cam1")` names another.
--
-- The format is told by the file's name: `.lua` Lua, `.yaml` or `.yml` YAML, `.xml` XML, `.json`
-- JSON; another name by its text (`return` or `--` first: Lua; `<`: XML; `{`: JSON; else YAML).
-- Anything not understood is refused with its line: an unknown key (naming the likely intended
-- one), a missing or malformed entry, a distortion model or coefficient count tagpose does not
-- have, a camera no later call would take (`fx = 1e-320`). In OpenCV files, whose samples
-- store much else (`avg_reprojection_error`, `extrinsic_parameters`, ...), unknown keys are
-- listed in `info.ignored` instead, unless they look like a misspelling of a key that is read.
--
-- The camera is that of the image the calibration was made on (`K`, `D`): corners detected
-- on a rectified image (`image_rect`) belong instead to `info.projection` without distortion.
--
-- The formats are read by `tagpose.calibration.lua_file`, `tagpose.calibration.ros`,
-- `tagpose.calibration.opencv` (YAML through `tagpose.calibration.entries`, XML and JSON
-- through `tagpose.calibration.storage`) and `tagpose.calibration.kalibr`, with the messages,
-- suggestions and lens models of `tagpose.calibration.common`. The XML, JSON and Kalibr readers
-- are loaded when a file of theirs is first read.
-- @module tagpose.formats.calibration

local common = require("tagpose.formats.calibration.common")
local entries = require("tagpose.formats.calibration.entries")
local lua_file = require("tagpose.formats.calibration.lua_file")
local ros = require("tagpose.formats.calibration.ros")
local opencv = require("tagpose.formats.calibration.opencv")
local output = require("tagpose.formats.output")
local failure = require("tagpose.formats.failure")

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

local READERS = { ros = ros.calibration, camera_info = ros.camera_info, opencv = opencv.read,
  kalibr = function(y, info, which) return require("tagpose.formats.calibration.kalibr").read(y,
    info, which) end }

-- the record of a YAML, XML or JSON file (XML and JSON are OpenCV's FileStorage; their reader is
-- loaded when first needed)
local RECORDS = { yaml = entries.open,
  xml = function(text, name) return require("tagpose.formats.calibration.storage").xml(text,
    name) end,
  json = function(text, name) return require("tagpose.formats.calibration.storage").json(text,
    name) end }

-- the camera of a YAML, XML or JSON file
local function data_camera(kind, text, name, which)
  local y = RECORDS[kind](text, name)
  if which ~= nil and y.format ~= "kalibr" then
    entries.fail(y, nil, "camera '" .. which .. "' named, but this is not a Kalibr camchain (an "
      .. y.format .. " file has one camera)")
  end
  local info = { format = y.format, path = name }
  local k, d, model = READERS[y.format](y, info, which)
  info.distortion_model = model
  local top = y.top
  local at = top.camera_matrix or top.K or top.k or top.cameraMatrix
  if y.format == "kalibr" then at = entries.line(y, y.doc[info.camera], "intrinsics") end
  local camera = common.build(k, d, model, function(reason) entries.fail(y, at, reason) end)
  return camera, info
end

-- the format of a file: by its name's ending, else by how its text starts
local function kind_of(text, name)
  local ext = (name:match("%.(%w+)$") or ""):lower()
  if ext == "lua" then return "lua" end
  if ext == "yaml" or ext == "yml" then return "yaml" end
  if ext == "xml" or ext == "json" then return ext end
  local first = text:match("^\239\187\191") and text:match("^...%s*(%S%S?)")
    or text:match("^%s*(%S%S?)") -- "re"turn or "--"
  if first == "--" or (first == "re" and text:match("^%s*return[%s{]") ~= nil) then return "lua" end
  if first and first:sub(1, 1) == "<" then return "xml" end
  if first and first:sub(1, 1) == "{" then return "json" end
  return "yaml"
end

--- Read a calibration from its text.
-- @tparam string text the file's text
-- @tparam string name the file's name: its ending (`.lua`, `.yaml`, `.yml`, `.xml`, `.json`)
--   tells the format, and it names the file in messages
-- @tparam[opt] string camera for a Kalibr camchain, the camera to read (default `"cam0"`)
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info: `format` (`"lua"`, `"ros"`, `"camera_info"`, `"opencv"` or
--   `"kalibr"`), `path`, and what the file gives of `width`, `height` (pixels), `name`,
--   `distortion_model` (the ROS name of the lens model read), `rectification` (flat 3x3),
--   `projection` (flat 3x4), `ignored` (OpenCV keys not read), from a Kalibr camchain `camera`,
--   `cameras`, `rostopic`, `T_cam_imu`, `T_cn_cnm1` (flat 4x4), `timeshift_cam_imu`,
--   `cam_overlaps`, and from a Lua file `tag_size` (a number or `{[id] = size, default =
--   size}`), `block_size`, `unit` (the name of the unit of `tag_size`)
-- @return nil, string `"calibration: NAME:LINE: reason"`
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string, or `camera`
--   neither nil nor a string
function M.decode(text, name, camera)
  failure.check(text, name)
  if camera ~= nil and type(camera) ~= "string" then
    error("bad argument #3 to 'decode' (string expected for the camera's name, got "
      .. type(camera) .. ")", 2)
  end
  local kind = kind_of(text, name)
  if kind == "lua" then
    if camera ~= nil then
      return nil, "calibration: " .. name .. ": camera '" .. camera .. "' named, but this is not"
        .. " a Kalibr camchain (a Lua camera file has one camera)"
    end
    return failure.protect(lua_file.read, text, name)
  end
  return failure.protect(data_camera, kind, text, name, camera)
end

--- Read a calibration file (a Lua camera file, ROS YAML, OpenCV YAML, XML or JSON, a Kalibr
-- camchain; see the module's header).
-- @tparam string path
-- @tparam[opt] string camera for a Kalibr camchain, the camera to read (default `"cam0"`)
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info (see `decode`)
-- @return nil, string `"calibration: PATH:LINE: reason"` (or `"calibration: PATH: reason"`
--   when the file cannot be read)
-- @raise `bad argument #n to 'read' (...)` when `path` is not a string, or `camera` neither
--   nil nor a string
-- @usage
-- local camera, info = assert(tagpose.calibration.read("ost.yaml"))
-- local pose = tagpose.solve(corners, camera, 0.024)
-- local right = assert(tagpose.calibration.read("camchain.yaml", "cam1"))
function M.read(path, camera)
  if type(path) ~= "string" then
    error("bad argument #1 to 'read' (string expected, got " .. type(path) .. ")", 2)
  end
  if camera ~= nil and type(camera) ~= "string" then
    error("bad argument #2 to 'read' (string expected for the camera's name, got "
      .. type(camera) .. ")", 2)
  end
  local text, err = output.read_text(path, M.MAX_BYTES, "a calibration is a few lines")
  if not text then return nil, "calibration: " .. err end
  return M.decode(text, path, camera)
end

return M
