--- Poses of a tag: its corners in the camera and their reprojection error (the public result
-- table is `tagpose.result.pose`'s).
--
-- Internally a pose is a flat rotation `r` (row-major 3×3, tag → camera, see
-- `tagpose.rotation`) and a translation `tx, ty, tz` (the tag centre in the camera frame, in the
-- unit of the tag size). The tag's corners, in the detection order (docs/conventions.md), are
-- `c1 = (-h, +h, 0)`, `c2 = (+h, +h, 0)`, `c3 = (+h, -h, 0)`, `c4 = (-h, -h, 0)`, `h` half the
-- side. Pixels are a flat array `{u1, v1, u2, v2, u3, v3, u4, v4}`.
-- @module tagpose.core.pose

local lsq = require("tagpose.core.lsq")

local sqrt = math.sqrt
local residual = lsq.residual

local M = {}

-- x and y of the corners in the tag frame, per unit half side, in detection order
M.CORNER_X = { -1, 1, 1, -1 }
M.CORNER_Y = { 1, 1, -1, -1 }

local CX, CY = M.CORNER_X, M.CORNER_Y

--- RMS reprojection error, in pixels, of the four corners of a pose.
-- @tparam table C a packed camera (`tagpose.core.lsq.pack`)
-- @tparam {number,...} r flat rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number half half the tag's side
-- @tparam {number,...} px the observed pixels, flat
-- @treturn number RMS over the corners of the distance between observed and projected pixel
--   (`math.huge` when a corner is not in front of the camera)
function M.reprojection_error(C, r, tx, ty, tz, half, px)
  local r1, r2, r4, r5, r7, r8 = r[1], r[2], r[4], r[5], r[7], r[8]
  local pinhole, fx, fy, cx, cy = C.lens == 0, C.fx, C.fy, C.cx, C.cy
  local sum = 0
  for i = 1, 4 do
    local a, b = CX[i] * half, CY[i] * half
    local x, y, z = r1 * a + r2 * b + tx, r4 * a + r5 * b + ty, r7 * a + r8 * b + tz
    local du, dv
    if pinhole and z > 0 then
      -- (the pinhole written out: the seed method's last step)
      du, dv = fx * (x / z) + cx - px[2 * i - 1], fy * (y / z) + cy - px[2 * i]
    else
      du, dv = residual(C, x, y, z, px[2 * i - 1], px[2 * i])
    end
    sum = sum + du * du + dv * dv
  end
  return sqrt(sum / 4)
end

--- True when a candidate pose and its error are finite.
-- @tparam table cand a candidate record
-- @tparam number err its error
-- @treturn boolean
function M.is_finite(cand, err)
  local r = cand.r
  local s = cand.tx + cand.ty + cand.tz + err
  -- (a loop, on purpose: on LuaJIT it ends the caller's trace here, which would otherwise run
  -- on through the result with too many values live to compile)
  for i = 1, 9 do s = s + r[i] end
  return s == s and s < math.huge and s > -math.huge
end

return M
