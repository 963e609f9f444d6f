--- Cameras: intrinsics, lens distortion, and the maps between pixels and normalised coordinates.
--
-- A camera is a table `{fx =, fy =, cx =, cy =}` in pixels, with OpenCV's meaning:
-- `u = fx * xd + cx`, `v = fy * yd + cy`, pixel centres at integer coordinates, where
-- `(xd, yd)` are the distorted normalised coordinates of the point `(x / z, y / z)`.
--
-- Optional lens models, as OpenCV defines them:
--
-- * `model = "pinhole"` (default) with `distortion = {k1 =, k2 =, p1 =, p2 =, k3 =}` and
--   optionally the rational `k4 =, k5 =, k6 =` (Brown-Conrady; missing coefficients are 0):
--   `xd = x·R + 2·p1·x·y + p2·(r² + 2x²)`, `yd = y·R + p1·(r² + 2y²) + 2·p2·x·y`,
--   `R = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)`, `r² = x² + y²`;
-- * `model = "fisheye"` with `distortion = {k1 =, k2 =, k3 =, k4 =}` (equidistant
--   Kannala-Brandt, `cv::fisheye`): `θ = atan(r)`,
--   `θd = θ·(1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`, `(xd, yd) = (θd / r)·(x, y)`.
--
-- `undistort` inverts the lens map by Newton's method on the 2×2 system, to a residual of
-- `UNDISTORT_TOLERANCE` (normalised units), and refuses points the map cannot invert: those
-- outside the region, around the image centre, where the map is one-to-one.
-- @module tagpose.camera

local compat = require("tagpose.compat")
local args = require("tagpose.args")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local sqrt, atan, abs = math.sqrt, math.atan, math.abs

local M = {}

--- Residual (normalised units, relative to `1 + |xd| + |yd|`) at which the inverse of the lens
-- map has converged: about 1e-11 px for focal lengths under 10 000 px, a few units of
-- round-off. A Newton step below a tenth of it also ends the iteration (round-off reached).
M.UNDISTORT_TOLERANCE = 1e-15
--- Bound on the Newton steps of one inversion.
M.UNDISTORT_ITERATIONS = 50

local BROWN = { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
local checked = setmetatable({}, { __mode = "k" }) -- pinhole cameras found valid, and how
local FISHEYE = { "k1", "k2", "k3", "k4" }

--- Check a camera table; the entry points turn a message into a `bad argument` error.
-- @tparam any camera
-- @treturn[1] nil when the camera is usable
-- @treturn[2] string what is wrong, naming the field
--   (`camera.fx: positive number expected, got nil`)
function M.check(camera)
  if type(camera) ~= "table" then
    return "camera table expected, got " .. type(camera)
  end
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  -- a camera checked before and unchanged since passes at once (solve checks every call)
  local seen = checked[camera]
  if seen and seen[1] == fx and seen[2] == fy and seen[3] == cx and seen[4] == cy
    and seen[5] == camera.model and seen[6] == camera.distortion and seen[6] == nil then
    return nil
  end
  if not is_positive(fx) then return "camera.fx: positive number expected, got " .. describe(fx) end
  if not is_positive(fy) then return "camera.fy: positive number expected, got " .. describe(fy) end
  if not is_finite(cx) then return "camera.cx: finite number expected, got " .. describe(cx) end
  if not is_finite(cy) then return "camera.cy: finite number expected, got " .. describe(cy) end
  local model, d = camera.model, camera.distortion
  if model ~= nil and model ~= "pinhole" and model ~= "fisheye" then
    return "camera.model: 'pinhole' or 'fisheye' expected, got " .. describe(model)
  end
  if d == nil then
    seen = seen or {}
    seen[1], seen[2], seen[3], seen[4], seen[5], seen[6] = fx, fy, cx, cy, model, nil
    checked[camera] = seen
    return nil
  end
  if type(d) ~= "table" then
    return "camera.distortion: table expected, got " .. type(d)
  end
  local names = model == "fisheye" and FISHEYE or BROWN
  for i = 1, #names do
    local v = d[names[i]]
    if v ~= nil and not is_finite(v) then
      return "camera.distortion." .. names[i] .. ": finite number expected, got " .. describe(v)
    end
  end
  return nil
end

--- The lens model of a checked camera and its coefficients, for kernels that evaluate it many
-- times: `0` (none); `1, k1, k2, p1, p2, k3, k4, k5, k6` (Brown-Conrady, for `brown`);
-- `2, k1, k2, k3, k4` (fisheye, for `fisheye`).
-- @tparam table camera a checked camera
-- @treturn int kind
-- @treturn number,... the coefficients
local function lens(camera)
  local d = camera.distortion
  if d == nil then return 0 end
  if camera.model == "fisheye" then
    return 2, d.k1 or 0, d.k2 or 0, d.k3 or 0, d.k4 or 0
  end
  return 1, d.k1 or 0, d.k2 or 0, d.p1 or 0, d.p2 or 0, d.k3 or 0, d.k4 or 0, d.k5 or 0,
    d.k6 or 0
end

M.lens = lens

--- Brown-Conrady map on explicit coefficients: the distorted point and its Jacobian
-- (`d xd/d x, d xd/d y, d yd/d x, d yd/d y`).
-- @local
local function brown(x, y, k1, k2, p1, p2, k3, k4, k5, k6)
  local r2 = x * x + y * y
  local num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
  local den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
  local radial = num / den
  local dnum = k1 + r2 * (2 * k2 + r2 * 3 * k3)
  local dden = k4 + r2 * (2 * k5 + r2 * 3 * k6)
  local dr = (dnum * den - num * dden) / (den * den) -- d radial / d r²
  local xy = x * y
  local xd = x * radial + 2 * p1 * xy + p2 * (r2 + 2 * x * x)
  local yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * xy
  local cross = 2 * xy * dr + 2 * p1 * x + 2 * p2 * y
  return xd, yd,
    radial + 2 * x * x * dr + 2 * p1 * y + 6 * p2 * x, cross,
    cross, radial + 2 * y * y * dr + 6 * p1 * y + 2 * p2 * x
end

--- Kannala-Brandt fisheye map on explicit coefficients: the distorted point and its Jacobian.
-- @local
local function fisheye(x, y, k1, k2, k3, k4)
  local r2 = x * x + y * y
  local scale, dscale -- θd / r and (d scale / d r) / r
  if r2 < 1e-16 then
    scale, dscale = 1, 2 * (k1 - 1 / 3)
  else
    local r = sqrt(r2)
    local t = atan(r)
    local t2 = t * t
    local td = t * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    local dtd = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
    scale = td / r
    dscale = (dtd / (1 + r2) - scale) / r2
  end
  return scale * x, scale * y,
    scale + dscale * x * x, dscale * x * y,
    dscale * x * y, scale + dscale * y * y
end

M.brown, M.fisheye = brown, fisheye

--- Distorted normalised coordinates of an undistorted point, and the Jacobian of the map.
-- @tparam table camera a checked camera
-- @tparam number x
-- @tparam number y
-- @treturn number xd
-- @treturn number yd
-- @treturn number d xd / d x
-- @treturn number d xd / d y
-- @treturn number d yd / d x
-- @treturn number d yd / d y
function M.distort(camera, x, y)
  local kind, a, b, c, d, e, f, g, h = lens(camera)
  if kind == 0 then return x, y, 1, 0, 0, 1 end
  if kind == 1 then return brown(x, y, a, b, c, d, e, f, g, h) end
  return fisheye(x, y, a, b, c, d)
end

local distort = M.distort

--- Undistorted normalised coordinates of a distorted normalised point.
-- @tparam table camera a checked camera
-- @tparam number xd
-- @tparam number yd
-- @treturn number x
-- @treturn number y
-- @return nil, string when the point lies where the lens map cannot be inverted
function M.undistort(camera, xd, yd)
  if camera.distortion == nil then return xd, yd end
  if camera.model == "fisheye" then
    -- θd is (nearly) the angle off the optical axis; at 90 degrees x / z is infinite
    local _, k1, k2, k3, k4 = lens(camera)
    local t = 0.5 * math.pi
    local t2 = t * t
    local limit = t * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    if xd * xd + yd * yd >= limit * limit then
      return nil, "camera: the point is 90 degrees or more from the optical axis"
    end
  end
  local x, y = xd, yd
  local tol = M.UNDISTORT_TOLERANCE * (1 + abs(xd) + abs(yd))
  local converged = false
  for _ = 1, M.UNDISTORT_ITERATIONS do
    local fx, fy, a, b, c, d = distort(camera, x, y)
    local ex, ey = fx - xd, fy - yd
    if ex * ex + ey * ey <= tol * tol then
      converged = true
      break
    end
    local det = a * d - b * c
    if not (det > 0) then break end -- folded: no inverse here
    local sx, sy = (d * ex - b * ey) / det, (a * ey - c * ex) / det
    if sx * sx + sy * sy <= 0.01 * tol * tol then
      converged = true
      break
    end
    -- damp a step that would more than double the radius (the map is steep there)
    local n2, s2 = x * x + y * y, sx * sx + sy * sy
    if s2 > 4 * n2 + 1 then
      local k = sqrt((4 * n2 + 1) / s2)
      sx, sy = sx * k, sy * k
    end
    x, y = x - sx, y - sy
    if not (abs(x) + abs(y) < 1e150) then break end
  end
  if not converged then
    return nil, "camera: the lens model cannot be inverted at this point"
  end
  -- the solution must be reached from the centre through the region where the map is
  -- one-to-one: the Jacobian stays positive along the ray to it
  for k = 1, 8 do
    local s = k / 8
    local _, _, a, b, c, d = distort(camera, s * x, s * y)
    if not (a * d - b * c > 0) then
      return nil, "camera: the point is outside the region where the lens model is one-to-one"
    end
  end
  return x, y
end

--- Normalised, undistorted image coordinates of a pixel.
-- @tparam table camera a checked camera
-- @tparam number u pixel column
-- @tparam number v pixel row
-- @treturn number x
-- @treturn number y
-- @return nil, string when the lens model cannot be inverted at the pixel
function M.normalise(camera, u, v)
  local xd, yd = (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
  if camera.distortion == nil then return xd, yd end
  return M.undistort(camera, xd, yd)
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
  if camera.distortion ~= nil then xd, yd = distort(camera, xd, yd) end
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
    for row = 1, 3 do
      local r = K[row]
      if type(r) ~= "table" then bad(1, "K[" .. row .. "]: row table expected, got " .. type(r)) end
      for col = 1, 3 do k[(row - 1) * 3 + col] = r[col] end
    end
  else
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

return M
