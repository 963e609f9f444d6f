--- Kalibr camera chains (`camchain.yaml`, `camchain-imucam.yaml`), the output of Kalibr's
-- camera and camera-IMU calibrations:
--
--     cam0:
--       camera_model: pinhole
--       intrinsics: [fu, fv, pu, pv]
--       distortion_model: radtan        # or equidistant, none
--       distortion_coeffs: [k1, k2, r1, r2]
--       resolution: [width, height]
--       rostopic: /cam0/image_raw
--       T_cam_imu: [[...], [...], [...], [...]]   # camchain-imucam.yaml
--       T_cn_cnm1: [[...], ...]                    # cam1 and on: from the previous camera
--       timeshift_cam_imu: 0.0
--       cam_overlaps: [1]
--     cam1: ...
--
-- One camera is read (`cam0` unless another is named). `radtan` is OpenCV's Brown-Conrady
-- model with `k1, k2, p1, p2` (ROS's `plumb_bob`), `equidistant` the Kannala-Brandt fisheye of
-- `cv::fisheye` (`k1..k4`), `none` no distortion. The other camera models (`omni`, `eucm`,
-- `ds`) and `fov` distortion are refused, as is any key not listed above. Functions raise the
-- `Failure` of `tagpose.calibration.common`.
-- @module tagpose.formats.calibration.kalibr

local compat = require("tagpose.core.compat")
local common = require("tagpose.formats.calibration.common")
local entries = require("tagpose.formats.calibration.entries")

local concat = table.concat
local describe, key_name, sorted_keys = common.describe, common.key_name, common.sorted_keys
local is_integer = common.is_integer
local fail, line, is_mapping, numbers = entries.fail, entries.line, entries.is_mapping,
  entries.numbers

local M = {}

local KEYS = { "camera_model", "intrinsics", "distortion_model", "distortion_coeffs",
  "resolution", "rostopic", "T_cn_cnm1", "T_cam_imu", "timeshift_cam_imu", "cam_overlaps" }
local KNOWN = {}
for _, k in ipairs(KEYS) do KNOWN[k] = true end

-- Kalibr's distortion models: the ROS name of the lens and the number of coefficients
local DISTORTION = { radtan = { "plumb_bob", 4 }, equidistant = { "equidistant", 4 },
  none = { "plumb_bob", 0 } }
local OTHER_CAMERAS = { omni = true, eucm = true, ds = true }

-- the cameras of the chain, in order (cam2 before cam10); anything else at the top is refused
local function cameras(y)
  local names = {}
  for _, k in ipairs(sorted_keys(y.doc)) do
    if type(k) ~= "string" or not k:match("^cam%d+$") then
      fail(y, y.top[k], "unknown key " .. key_name(k) .. " (a Kalibr camchain has cam0, cam1,"
        .. " ...)")
    end
    if not is_mapping(y.doc[k]) then
      fail(y, y.top[k], k .. ": a mapping of the camera's calibration expected, got "
        .. describe(y.doc[k]))
    end
    names[#names + 1] = k
  end
  table.sort(names, function(a, b) return tonumber(a:sub(4)) < tonumber(b:sub(4)) end)
  return names
end

local function refuse_unknown(y, cam, which, at)
  local suggest = common.suggester(KEYS)
  for _, k in ipairs(sorted_keys(cam)) do
    if not KNOWN[k] then
      local hint = suggest(k)
      fail(y, line(y, cam, k) or at, which .. ": unknown key " .. key_name(k) .. (hint
        and (" (did you mean " .. hint .. "?)") or (" (a Kalibr camera has " .. concat(KEYS, ", ")
        .. ")")))
    end
  end
end

-- a 4x4 transformation as Kalibr writes it (four rows of four numbers): flat, row-major
local function transform(y, cam, key, which)
  local rows = cam[key]
  local at = line(y, cam, key)
  if not entries.is_sequence(rows) or #rows ~= 4 then
    fail(y, at, which .. "." .. key .. ": 4 rows of 4 numbers expected, got " .. describe(rows))
  end
  local flat = {}
  for i = 1, 4 do
    local row = numbers(y, rows[i], line(y, rows, i) or at, which .. "." .. key .. "[" .. i .. "]",
      4)
    for j = 1, 4 do flat[(i - 1) * 4 + j] = row[j] end
  end
  return flat
end

-- the entries that are not the lens: resolution, rostopic, extrinsics, time shift, overlaps
local function read_info(y, cam, which, info)
  local w = which .. "."
  if cam.resolution ~= nil then
    local at = line(y, cam, "resolution")
    local r = numbers(y, cam.resolution, at, w .. "resolution", 2)
    if not (is_integer(r[1], 1) and is_integer(r[2], 1)) then
      fail(y, at, w .. "resolution: [width, height] in whole pixels expected")
    end
    info.width, info.height = r[1], r[2]
  end
  if cam.rostopic ~= nil then
    if type(cam.rostopic) ~= "string" then
      fail(y, line(y, cam, "rostopic"), w .. "rostopic: string expected, got "
        .. describe(cam.rostopic))
    end
    info.rostopic = cam.rostopic
  end
  for _, key in ipairs({ "T_cam_imu", "T_cn_cnm1" }) do
    if cam[key] ~= nil then info[key] = transform(y, cam, key, which) end
  end
  if cam.timeshift_cam_imu ~= nil then
    if not compat.is_finite(cam.timeshift_cam_imu) then
      fail(y, line(y, cam, "timeshift_cam_imu"), w .. "timeshift_cam_imu: number expected, got "
        .. describe(cam.timeshift_cam_imu))
    end
    info.timeshift_cam_imu = cam.timeshift_cam_imu
  end
  if cam.cam_overlaps ~= nil then
    local at = line(y, cam, "cam_overlaps")
    local o = numbers(y, cam.cam_overlaps, at, w .. "cam_overlaps")
    for i = 1, #o do
      if not is_integer(o[i], 0) then
        fail(y, line(y, o, i) or at, w .. "cam_overlaps[" .. i .. "]: a camera number expected,"
          .. " got " .. describe(o[i]))
      end
    end
    info.cam_overlaps = o
  end
end

-- the lens: the ROS name of the model, and the coefficients
local function lens(y, cam, which, at)
  local w = which .. "."
  local model = cam.camera_model
  if model == nil then fail(y, at, w .. "camera_model: none given ('pinhole' expected)") end
  if model ~= "pinhole" then
    fail(y, line(y, cam, "camera_model"), w .. "camera_model: " .. (OTHER_CAMERAS[model]
      and ("the " .. model .. " model is not supported (tagpose has the pinhole camera with"
        .. " radtan or equidistant distortion)") or ("'pinhole' expected, got "
        .. describe(model))))
  end
  local dm = cam.distortion_model
  local kind = DISTORTION[dm]
  if not kind then
    local dat = line(y, cam, "distortion_model") or at
    if dm == nil then fail(y, at, w .. "distortion_model: none given (radtan, equidistant or"
      .. " none)") end
    fail(y, dat, w .. "distortion_model: " .. (dm == "fov" and "the fov model is not supported"
      .. " (radtan, equidistant or none)" or ("radtan, equidistant or none expected, got "
        .. describe(dm))))
  end
  local coeffs = cam.distortion_coeffs
  if coeffs == nil then
    if kind[2] > 0 then fail(y, at, w .. "distortion_coeffs: none given (" .. dm .. " has "
      .. kind[2] .. ")") end
    return kind[1], {}
  end
  local cat = line(y, cam, "distortion_coeffs")
  local d = numbers(y, coeffs, cat, w .. "distortion_coeffs")
  if #d ~= kind[2] then
    fail(y, cat, w .. "distortion_coeffs: distortion_model " .. dm .. " has " .. kind[2]
      .. " coefficients, the file gives " .. #d)
  end
  return kind[1], d
end

--- Read one camera of a Kalibr camera chain.
-- @tparam table y the file's record of `tagpose.calibration.entries`
-- @tparam table info filled with `camera` (its name), `cameras` (the chain's, in order),
--   `width`, `height`, `rostopic`, `T_cam_imu`, `T_cn_cnm1` (flat 4x4, row-major),
--   `timeshift_cam_imu`, `cam_overlaps` (what the file gives of them)
-- @tparam[opt="cam0"] string which the camera to read
-- @treturn {number,...} K, flat 3x3
-- @treturn {number,...} the coefficients (OpenCV order)
-- @treturn string the distortion model's ROS name (`plumb_bob` or `equidistant`)
function M.read(y, info, which)
  which = which or "cam0"
  local names = cameras(y)
  info.cameras = names
  local cam = y.doc[which]
  if cam == nil then
    fail(y, 1, "no camera " .. which .. " in the chain (it has " .. concat(names, ", ") .. ")")
  end
  info.camera = which
  local at = y.top[which]
  refuse_unknown(y, cam, which, at)
  local model, d = lens(y, cam, which, at)
  if cam.intrinsics == nil then
    fail(y, at, which .. ".intrinsics: none given ([fu, fv, pu, pv])")
  end
  local k = numbers(y, cam.intrinsics, line(y, cam, "intrinsics"), which .. ".intrinsics", 4)
  read_info(y, cam, which, info)
  return { k[1], 0, k[3], 0, k[2], k[4], 0, 0, 1 }, d, model
end

return M
