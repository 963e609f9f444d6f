--- Cameras: intrinsics, the lens model, and the maps between pixels and normalised
-- coordinates.
--
-- A camera is a table `{fx =, fy =, cx =, cy =}` in pixels, with OpenCV's meaning:
-- `u = fx * xd + cx`, `v = fy * yd + cy`, pixel centres at integer coordinates, where
-- `(xd, yd)` are the distorted normalised coordinates of the point `(x / z, y / z)`.
-- Optionally `model` (`"pinhole"`, the default, or `"fisheye"`) and `distortion`, the lens
-- coefficients, named (`{k1 =, k2 =, p1 =, p2 =, k3 =, k4 =, k5 =, k6 =}`; fisheye
-- `{k1 =, k2 =, k3 =, k4 =}`) or in OpenCV's `distCoeffs` order (`{k1, k2, p1, p2}`,
-- `{k1, k2, p1, p2, k3}` or `{k1, k2, p1, p2, k3, k4, k5, k6}`; fisheye `{k1, k2, k3, k4}`);
-- the models are `tagpose.core.lens`'s. A camera may also carry `width`, `height` (pixels),
-- `name`, and the `tag_size` and `block_size` a camera file gives; any other key is refused,
-- so a misspelled one never passes silently.
-- @module tagpose.core.camera

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local lens = require("tagpose.core.lens")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe

local M = {}

--- A focal length (px) below this is not a camera's...
M.MIN_FOCAL = 1e-9
--- ... nor above this.
M.MAX_FOCAL = 1e12
--- A principal point coordinate (px) beyond ±this is not a camera's.
M.MAX_CENTRE = 1e12

local BROWN = { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
local FISHEYE = { "k1", "k2", "k3", "k4" }
local KEYS = { "fx", "fy", "cx", "cy", "model", "distortion", "width", "height", "name",
  "tag_size", "block_size" }
local checked = setmetatable({}, { __mode = "k" }) -- pinhole cameras found valid, and how

-- where a misplaced key most likely belongs
local MISPLACED = { D = "camera.distortion (or tagpose.camera.from_matrix(K, D))",
  d = "camera.distortion", dist = "camera.distortion", distCoeffs = "camera.distortion",
  dist_coeffs = "camera.distortion", distortion_coefficients = "camera.distortion",
  K = "tagpose.camera.from_matrix(K, D)", k = "tagpose.camera.from_matrix(K, D)",
  camera_matrix = "tagpose.camera.from_matrix(K, D)", distortion_model = "camera.model" }
for _, name in ipairs(BROWN) do MISPLACED[name] = "camera.distortion." .. name end

local function focal(name, v)
  if not is_positive(v) then return "camera." .. name .. ": positive number expected, got "
    .. describe(v) end
  if not (v >= M.MIN_FOCAL and v <= M.MAX_FOCAL) then
    return ("camera.%s: a focal length in pixels between %g and %g expected, got %s")
      :format(name, M.MIN_FOCAL, M.MAX_FOCAL, describe(v))
  end
end

local function centre(name, v)
  if not is_finite(v) then return "camera." .. name .. ": finite number expected, got "
    .. describe(v) end
  if not (v >= -M.MAX_CENTRE and v <= M.MAX_CENTRE) then
    return ("camera.%s: a principal point coordinate in pixels within %g expected, got %s")
      :format(name, M.MAX_CENTRE, describe(v))
  end
end

-- The keys of a camera: each known, and the optional ones well formed; or what is wrong.
local function check_keys(camera)
  local problem = args.unknown_keys(camera, KEYS, "camera", MISPLACED)
  if problem then return problem end
  for _, name in ipairs({ "width", "height", "tag_size", "block_size" }) do
    local v = camera[name]
    if v ~= nil and not is_positive(v) then
      return "camera." .. name .. ": positive number expected, got " .. describe(v)
    end
  end
  if camera.name ~= nil and type(camera.name) ~= "string" then
    return "camera.name: string expected, got " .. type(camera.name)
  end
end

-- The distortion coefficients of a model: named, or OpenCV's array; or what is wrong.
local function check_distortion(d, model)
  if type(d) ~= "table" then return "camera.distortion: table expected, got " .. type(d) end
  local fisheye = model == "fisheye"
  local names = fisheye and FISHEYE or BROWN
  if d[1] ~= nil then
    local n = 0
    while d[n + 1] ~= nil and n < 64 do n = n + 1 end
    for k in pairs(d) do
      if not (type(k) == "number" and k >= 1 and k <= n and k == math.floor(k)) then
        return "camera.distortion: an array of coefficients or a table of named ones expected, "
          .. "not both (key " .. describe(k) .. ")"
      end
    end
    if fisheye and n ~= 4 then
      return "camera.distortion: 4 fisheye coefficients {k1, k2, k3, k4} expected, got " .. n
    elseif not fisheye and not (n == 4 or n == 5 or n == 8) then
      return "camera.distortion: 4, 5 or 8 coefficients in OpenCV's order {k1, k2, p1, p2[, "
        .. "k3[, k4, k5, k6]]} expected, got " .. n
        .. ((n == 12 or n == 14) and " (the thin-prism and tilted models are not supported)"
          or "")
    end
    for i = 1, n do
      if not is_finite(d[i]) then
        return "camera.distortion[" .. i .. "] (" .. names[i] .. "): finite number expected, got "
          .. describe(d[i])
      end
    end
    return nil
  end
  local other = fisheye and { p1 = true, p2 = true, k5 = true, k6 = true } or {}
  for k, v in pairs(d) do
    local known = false
    for i = 1, #names do
      if k == names[i] then known = true end
    end
    if not known then
      if other[k] then
        return "camera.distortion." .. tostring(k) .. ": the fisheye model has no " .. k
          .. " (its coefficients are k1, k2, k3, k4)"
      end
      return args.unknown_key_message(k, names, "camera.distortion")
    end
    if not is_finite(v) then
      return "camera.distortion." .. k .. ": finite number expected, got " .. describe(v)
    end
  end
  return nil
end

-- The coefficients of a distortion table are those the cache saw (by position and by name).
local function same_coefficients(seen, d)
  for i = 1, 8 do
    if seen[6 + i] ~= d[i] or seen[14 + i] ~= d[BROWN[i]] then return false end
  end
  return true
end

--- Check a camera table; the entry points turn a message into a `bad argument` error.
-- @tparam any camera
-- @treturn[1] nil when the camera is usable
-- @treturn[2] string what is wrong, naming the field
--   (`camera.fx: positive number expected, got nil`)
function M.check(camera)
  if type(camera) ~= "table" then
    return "camera table expected, got " .. type(camera)
  end
  local fx, fy, cx, cy, d = camera.fx, camera.fy, camera.cx, camera.cy, camera.distortion
  -- a camera checked before and unchanged since passes at once (solve checks every call): the
  -- same intrinsics, model, distortion table and coefficients
  local seen = checked[camera]
  if seen and seen[1] == fx and seen[2] == fy and seen[3] == cx and seen[4] == cy
    and seen[5] == camera.model and seen[6] == d and (d == nil or same_coefficients(seen, d)) then
    return nil
  end
  local problem = focal("fx", fx) or focal("fy", fy) or centre("cx", cx) or centre("cy", cy)
    or check_keys(camera)
  if problem then return problem end
  local model = camera.model
  if model ~= nil and model ~= "pinhole" and model ~= "fisheye" then
    return "camera.model: 'pinhole' or 'fisheye' expected, got " .. describe(model)
  end
  if d ~= nil then
    problem = check_distortion(d, model)
    if problem then return problem end
  end
  seen = seen or {}
  seen[1], seen[2], seen[3], seen[4], seen[5], seen[6] = fx, fy, cx, cy, model, d
  if d ~= nil then
    for i = 1, 8 do seen[6 + i] = d[i] end
    for i = 1, 8 do seen[14 + i] = d[BROWN[i]] end
  end
  checked[camera] = seen
  return nil
end

--- Distorted normalised coordinates of an undistorted point, and the Jacobian of the map
-- (`tagpose.core.lens.distort`).
-- @function distort
M.distort = lens.distort

--- Undistorted normalised coordinates of a distorted normalised point, or `nil, message` where
-- the lens model cannot be inverted one-to-one (`tagpose.core.lens.undistort`).
-- @function undistort
M.undistort = lens.undistort

local distort, undistort, coefficients = lens.distort, lens.undistort, lens.coefficients

--- Normalised, undistorted image coordinates of a pixel.
-- @tparam table camera a checked camera
-- @tparam number u pixel column
-- @tparam number v pixel row
-- @treturn number x
-- @treturn number y
-- @return nil, string when the lens model cannot be inverted at the pixel
function M.normalise(camera, u, v)
  local xd, yd = (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
  if coefficients(camera) == 0 then return xd, yd end
  return undistort(camera, xd, yd)
end

--- Pixel of a point in the camera frame (through the lens model).
-- @tparam table camera a checked camera
-- @tparam number x
-- @tparam number y
-- @tparam number z (> 0)
-- @treturn number u
-- @treturn number v
function M.project(camera, x, y, z)
  local xd, yd = x / z, y / z
  if coefficients(camera) ~= 0 then xd, yd = distort(camera, xd, yd) end
  return camera.fx * xd + camera.cx, camera.fy * yd + camera.cy
end

local MODELS = {
  plumb_bob = "pinhole",
  rational_polynomial = "pinhole",
  pinhole = "pinhole",
  equidistant = "fisheye",
  fisheye = "fisheye",
}

--- A camera from a calibration as OpenCV and ROS print it.
-- @tparam {number,...}|table K the 3×3 camera matrix, nested (`K[row][col]`) or flat
--   row-major (9 numbers, as ROS `camera_info.k`)
-- @tparam[opt] {number,...} D distortion coefficients in OpenCV order: `k1, k2, p1, p2[, k3[,
--   k4, k5, k6]]` for `"plumb_bob"` / `"rational_polynomial"`, `k1, k2, k3, k4` for
--   `"equidistant"` (fisheye); nil or empty for none
-- @tparam[opt="plumb_bob"] string model `"plumb_bob"`, `"rational_polynomial"`,
--   `"equidistant"` (ROS names) or `"pinhole"`, `"fisheye"`
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @raise `bad argument` naming the field that is wrong
-- @usage
-- -- OpenCV: K, D from cv2.calibrateCamera
-- local cam = tagpose.camera.from_matrix({{600, 0, 320}, {0, 600, 240}, {0, 0, 1}},
--   {-0.28, 0.07, 5e-4, -3e-4, 0})
-- -- ROS sensor_msgs/CameraInfo
-- local cam = tagpose.camera.from_matrix(msg.k, msg.d, msg.distortion_model)
function M.from_matrix(K, D, model)
  local function bad(n, message) args.raise(n, "from_matrix", message, 3) end
  if type(K) ~= "table" then bad(1, "table expected for K, got " .. type(K)) end
  local k = {}
  if type(K[1]) == "table" then
    local rows, cols = #K, #K[1]
    if rows == 3 and cols == 4 then
      bad(1, "K: a 3x3 camera matrix expected, got 3x4: a projection matrix (ROS's P)? its"
        .. " first three columns are the camera matrix of the rectified image")
    elseif rows ~= 3 then
      bad(1, "K: a 3x3 camera matrix expected, got " .. rows .. " rows")
    end
    for row = 1, 3 do
      local r = K[row]
      if type(r) ~= "table" then bad(1, "K[" .. row .. "]: row table expected, got " .. type(r)) end
      if #r ~= 3 then bad(1, "K[" .. row .. "]: 3 numbers expected, got " .. #r) end
      for col = 1, 3 do k[(row - 1) * 3 + col] = r[col] end
    end
  else
    local n = #K
    if n == 12 then
      bad(1, "K: 9 numbers (a 3x3 camera matrix, row-major) expected, got 12: a 3x4 projection"
        .. " matrix (ROS's P)? its first three columns, {P[1], P[2], P[3], P[5], P[6], P[7],"
        .. " P[9], P[10], P[11]}, are the camera matrix of the rectified image")
    elseif n > 9 then
      bad(1, "K: 9 numbers (a 3x3 camera matrix, row-major) expected, got " .. n)
    end
    for i = 1, 9 do k[i] = K[i] end
  end
  for i = 1, 9 do
    if not is_finite(k[i]) then
      bad(1, "K: 9 finite numbers expected, entry " .. i .. " is " .. describe(k[i]))
    end
  end
  if not (k[1] > 0 and k[5] > 0) then
    bad(1, "K: positive focal lengths expected, got fx = " .. k[1] .. ", fy = " .. k[5])
  end
  if k[4] ~= 0 or k[7] ~= 0 or k[8] ~= 0 or k[9] ~= 1 then
    bad(1, "K: a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] expected")
  end
  if k[2] ~= 0 then bad(1, "K: skew is not supported (K[1][2] must be 0)") end
  local problem = focal("fx", k[1]) or focal("fy", k[5]) or centre("cx", k[3])
    or centre("cy", k[6])
  if problem then bad(1, "K: " .. (problem:gsub("^camera%.", ""))) end
  if model == nil then model = "plumb_bob" end
  local kind = MODELS[model]
  if not kind then
    bad(3, "distortion model 'plumb_bob', 'rational_polynomial' or 'equidistant' expected, got "
      .. describe(model))
  end
  local camera = { fx = k[1], fy = k[5], cx = k[3], cy = k[6], model = kind }
  if D ~= nil and type(D) ~= "table" then bad(2, "table of coefficients expected for D, got "
    .. type(D)) end
  local n = D and #D or 0
  if n > 0 then
    local names = kind == "fisheye" and FISHEYE or BROWN
    if kind == "fisheye" and n ~= 4 then
      bad(2, "4 coefficients k1, k2, k3, k4 expected for the equidistant model, got " .. n)
    elseif kind == "pinhole" and not (n == 4 or n == 5 or n == 8) then
      bad(2, "4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]) expected, got " .. n)
    end
    local d = {}
    for i = 1, n do
      if not is_finite(D[i]) then
        bad(2, "D: coefficient " .. i .. " (" .. names[i] .. ") is " .. describe(D[i]))
      end
      d[names[i]] = D[i]
    end
    local any = false
    for i = 1, n do
      if D[i] ~= 0 then any = true end
    end
    if any then camera.distortion = d end
  end
  return camera
end

--- A copy of a camera (its distortion table copied too), for a caller that keeps using it while
-- its owner may change the original (the tracker: `same` tells it when).
-- @tparam table camera a checked camera
-- @treturn table the copy
function M.copy(camera)
  local copy = {}
  for k, v in pairs(camera) do copy[k] = v end
  copy.fx, copy.fy, copy.cx, copy.cy = camera.fx, camera.fy, camera.cx, camera.cy
  copy.model, copy.distortion = camera.model, camera.distortion
  local d = camera.distortion
  if type(d) == "table" then
    copy.distortion = {}
    for k, v in pairs(d) do copy.distortion[k] = v end
  end
  return copy
end

--- Whether a camera still holds what `copy` was made of: its intrinsics, model and distortion
-- (a few reads, where `check` is a few hundred instructions).
-- @tparam table camera the camera
-- @tparam table copy what `M.copy` made of it
-- @treturn boolean
function M.same(camera, copy)
  if camera.fx ~= copy.fx or camera.fy ~= copy.fy or camera.cx ~= copy.cx
    or camera.cy ~= copy.cy or camera.model ~= copy.model then
    return false
  end
  local d, c = camera.distortion, copy.distortion
  if type(d) ~= "table" or type(c) ~= "table" then return d == c end
  for k, v in pairs(d) do
    if c[k] ~= v then return false end
  end
  for k in pairs(c) do
    if d[k] == nil then return false end
  end
  return true
end

return M
