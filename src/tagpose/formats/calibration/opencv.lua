--- OpenCV FileStorage calibration files: YAML (`%YAML:1.0`, `!!opencv-matrix` entries), and XML
-- and JSON as `tagpose.calibration.storage` reads them into the same record.
--
-- The entries read are those OpenCV's calibration samples write (`camera_matrix`,
-- `distortion_coefficients`, `image_width`, `image_height`, `fisheye_model`) or the short
-- `K` / `D` (also `cameraMatrix` / `distCoeffs` / `dist_coeffs`). The samples store much else
-- (`avg_reprojection_error`, `extrinsic_parameters`, ...): unknown keys are listed in
-- `info.ignored`, unless they look like a misspelling of a key that is read.
-- @module tagpose.formats.calibration.opencv

local common = require("tagpose.formats.calibration.common")
local entries = require("tagpose.formats.calibration.entries")

local key_name = common.key_name
local fail = entries.fail

local M = {}

local CV_DISTORTION = { "distortion_coefficients", "distCoeffs", "dist_coeffs", "D" }
local CV_READ = { "camera_matrix", "cameraMatrix", "K", "distortion_coefficients", "distCoeffs",
  "dist_coeffs", "D", "image_width", "image_height", "fisheye_model" }

-- which of the names the file uses (two are refused), or nil
local function one_of(y, names, what)
  local doc, top = y.doc, y.top
  local found = {}
  for _, n in ipairs(names) do
    if doc[n] ~= nil then found[#found + 1] = n end
  end
  table.sort(found, function(a, b) return top[a] < top[b] end)
  if found[2] then
    fail(y, top[found[2]], "two " .. what .. ": " .. found[1] .. " (line " .. top[found[1]]
      .. ") and " .. found[2])
  end
  return found[1]
end

-- the keys not read, refusing those that look like a misspelling of one that is
local function ignored_keys(y)
  local read = {}
  for _, n in ipairs(CV_READ) do read[n] = true end
  local ignored = {}
  local suggest = common.suggester(CV_READ) -- once per file: a file may hold many keys
  for _, key in ipairs(common.sorted_keys(y.doc)) do
    if not read[key] then
      local hint = suggest(key)
      if hint and #key > 2 then
        fail(y, y.top[key], "unknown key " .. key_name(key) .. " (did you mean " .. hint .. "?)")
      end
      ignored[#ignored + 1] = tostring(key)
    end
  end
  return ignored
end

--- Read an OpenCV FileStorage file.
-- @tparam table y the file's record of `tagpose.calibration.entries`
-- @tparam table info filled with `ignored`, `width`, `height`
-- @treturn {number,...} K, flat 3x3
-- @treturn {number,...} the coefficients (OpenCV order)
-- @treturn string the distortion model (`plumb_bob`, `rational_polynomial` or `equidistant`)
function M.read(y, info)
  local doc = y.doc
  local mk = one_of(y, entries.CV_MATRIX, "camera matrices")
  local dk = one_of(y, CV_DISTORTION, "sets of distortion coefficients")
  info.ignored = ignored_keys(y)
  if not mk then
    fail(y, 1, "no camera matrix (camera_matrix, cameraMatrix or K, an opencv-matrix)")
  end
  local data, rows, cols = entries.matrix(y, doc, mk, true)
  local k = entries.shape(y, data, rows, cols, 3, 3, mk)
  if not dk then
    fail(y, 1, "no distortion_coefficients (or D): write a 5x1 matrix of zeros for none")
  end
  data, rows, cols = entries.matrix(y, doc, dk, true)
  local d = entries.vector(y, data, rows, cols, dk)
  local fisheye = doc.fisheye_model
  if fisheye ~= nil and fisheye ~= 0 and fisheye ~= 1 and fisheye ~= true
    and fisheye ~= false then
    fail(y, y.top.fisheye_model, "fisheye_model: 0 or 1 expected, got "
      .. common.describe(fisheye))
  end
  local model = (fisheye == 1 or fisheye == true) and "equidistant" or "pinhole"
  info.width, info.height = entries.size(y, "image_width"), entries.size(y, "image_height")
  local at = y.top[dk]
  d = common.opencv_coefficients(d, common.MODELS[model], function(reason)
    fail(y, at, dk .. ": " .. reason)
  end)
  if model == "pinhole" then model = #d == 8 and "rational_polynomial" or "plumb_bob" end
  return k, d, model
end

return M
