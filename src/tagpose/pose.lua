--- Poses of a tag: its corners in the camera, their reprojection error, and the public result
-- table.
--
-- Internally a pose is a flat rotation `r` (row-major 3×3, tag → camera, see
-- `tagpose.rotation`) and a translation `tx, ty, tz` (the tag centre in the camera frame, in the
-- unit of the tag size). The tag's corners, in the detection order of DESIGN.md, are
-- `c1 = (-h, +h, 0)`, `c2 = (+h, +h, 0)`, `c3 = (+h, -h, 0)`, `c4 = (-h, -h, 0)`, `h` half the
-- side. Pixels are a flat array `{u1, v1, u2, v2, u3, v3, u4, v4}`.
-- @module tagpose.pose

local rotation = require("tagpose.rotation")
local camera_model = require("tagpose.camera")

local sqrt = math.sqrt
local project = camera_model.project
local to_quaternion = rotation.to_quaternion

local M = {}

-- x and y of the corners in the tag frame, per unit half side, in detection order
M.CORNER_X = { -1, 1, 1, -1 }
M.CORNER_Y = { 1, 1, -1, -1 }

local CX, CY = M.CORNER_X, M.CORNER_Y

--- RMS reprojection error, in pixels, of the four corners of a pose.
-- @tparam table camera a checked camera
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number half half the tag's side
-- @tparam {number,...} px the observed pixels, flat
-- @treturn number RMS over the corners of the distance between observed and projected pixel
--   (`math.huge` when a corner is not in front of the camera)
function M.reprojection_error(camera, r, tx, ty, tz, half, px)
  local pinhole = camera.distortion == nil
  local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
  local r1, r2, r4, r5, r7, r8 = r[1], r[2], r[4], r[5], r[7], r[8]
  local sum = 0
  for i = 1, 4 do
    local a, b = CX[i] * half, CY[i] * half
    local x = r1 * a + r2 * b + tx
    local y = r4 * a + r5 * b + ty
    local z = r7 * a + r8 * b + tz
    if not (z > 0) then return math.huge end
    local u, v
    if pinhole then
      u, v = fx * x / z + cx, fy * y / z + cy
    else
      u, v = project(camera, x, y, z)
    end
    local du, dv = u - px[2 * i - 1], v - px[2 * i]
    sum = sum + du * du + dv * dv
  end
  return sqrt(sum / 4)
end

--- Fill (or create) the public pose table of DESIGN.md from an internal pose.
-- A new table is built with table constructors (one allocation per table); `into` is filled in
-- place, reusing its sub-tables, so that a caller who passes the same table every frame
-- allocates nothing.
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number err RMS reprojection error (px)
-- @tparam int iterations solveQuad iterations
-- @tparam[opt] int refine_iterations refinement linearisations (refined method)
-- @tparam[opt] table into a pose table to fill and return instead of a new one
-- @tparam[opt] number qw the rotation's quaternion, when the caller has it already
-- @tparam[opt] number qx
-- @tparam[opt] number qy
-- @tparam[opt] number qz
-- @treturn table `{position =, rotation =, quaternion =, error =, iterations =,
--   refine_iterations =}`
function M.result(r, tx, ty, tz, err, iterations, refine_iterations, into, qw, qx, qy, qz)
  local w, x, y, z = qw, qx, qy, qz
  if w == nil then w, x, y, z = to_quaternion(r) end
  if not into then
    return {
      position = { x = tx, y = ty, z = tz },
      rotation = { { r[1], r[2], r[3] }, { r[4], r[5], r[6] }, { r[7], r[8], r[9] } },
      quaternion = { w = w, x = x, y = y, z = z },
      error = err,
      iterations = iterations,
      refine_iterations = refine_iterations,
    }
  end
  local p = into.position
  if type(p) ~= "table" then
    p = {}
    into.position = p
  end
  p.x, p.y, p.z = tx, ty, tz
  local rt = into.rotation
  if type(rt) ~= "table" then
    rt = {}
    into.rotation = rt
  end
  rotation.to_nested(r, rt)
  local qt = into.quaternion
  if type(qt) ~= "table" then
    qt = {}
    into.quaternion = qt
  end
  qt.w, qt.x, qt.y, qt.z = w, x, y, z
  into.error, into.iterations, into.refine_iterations = err, iterations, refine_iterations
  return into
end

return M
