--- Camera intrinsics: checks, and the map between pixels and normalised image coordinates.
--
-- A camera is a table `{fx =, fy =, cx =, cy =}` in pixels (pinhole model, OpenCV's meaning:
-- `u = fx * x / z + cx`, `v = fy * y / z + cy`, pixel centres at integer coordinates).
-- Normalised coordinates are `(x / z, y / z)`.
-- @module tagpose.camera

local compat = require("tagpose.compat")
local args = require("tagpose.args")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe

local M = {}

--- Check a camera table; the facade turns a message into a `bad argument` error.
-- @tparam any camera
-- @treturn[1] nil when the camera is usable
-- @treturn[2] string what is wrong, naming the field
--   (`camera.fx: positive number expected, got nil`)
function M.check(camera)
  if type(camera) ~= "table" then
    return "camera table expected, got " .. type(camera)
  end
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  if not is_positive(fx) then return "camera.fx: positive number expected, got " .. describe(fx) end
  if not is_positive(fy) then return "camera.fy: positive number expected, got " .. describe(fy) end
  if not is_finite(cx) then return "camera.cx: finite number expected, got " .. describe(cx) end
  if not is_finite(cy) then return "camera.cy: finite number expected, got " .. describe(cy) end
  return nil
end

--- Normalised image coordinates of a pixel.
-- @tparam table camera a checked camera
-- @tparam number u pixel column
-- @tparam number v pixel row
-- @treturn number x
-- @treturn number y
function M.normalise(camera, u, v)
  return (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
end

--- Pixel of a point in the camera frame.
-- @tparam table camera a checked camera
-- @tparam number x
-- @tparam number y
-- @tparam number z (> 0)
-- @treturn number u
-- @treturn number v
function M.project(camera, x, y, z)
  return camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy
end

return M
