--- The localizer's result tables: a robot → field pose with its covariance, and a heading
-- put on a rotation.
-- @module tagpose.localizer.result

local fit = require("tagpose.localizer.fit")
local rotation = require("tagpose.core.rotation")

local sqrt, cos, sin = math.sqrt, math.cos, math.sin

local M = {}

-- A nested 6×6 from a flat one.
local function nested(c)
  local out = {}
  for i = 1, 6 do
    out[i] = { c[(i - 1) * 6 + 1], c[(i - 1) * 6 + 2], c[(i - 1) * 6 + 3], c[(i - 1) * 6 + 4],
      c[(i - 1) * 6 + 5], c[(i - 1) * 6 + 6] }
  end
  return out
end

-- The result table of a pose (r flat robot → field, t) and a flat covariance.
local function result(time, cam, r, t, cov, used, rejected)
  local q = {}
  q.w, q.x, q.y, q.z = rotation.to_quaternion(r)
  local C = nested(cov)
  return {
    time = time, camera = cam,
    position = { x = t[1], y = t[2], z = t[3] },
    rotation = rotation.to_nested(r, {}),
    quaternion = q,
    yaw = fit.yaw(r),
    covariance = C,
    sigma = { x = sqrt(C[1][1]), y = sqrt(C[2][2]), yaw = sqrt(C[6][6]) },
    tags = used, rejected = rejected,
  }
end

-- A rotation of heading yaw with the roll and pitch of r (or none).
local function with_yaw(r, yaw)
  -- R = Rz(yaw − yaw(r)) · r keeps r's tilt
  local d = yaw - (r and fit.yaw(r) or 0)
  local c, s = cos(d), sin(d)
  if not r then return { c, -s, 0, s, c, 0, 0, 0, 1 } end
  return { c * r[1] - s * r[4], c * r[2] - s * r[5], c * r[3] - s * r[6],
    s * r[1] + c * r[4], s * r[2] + c * r[5], s * r[3] + c * r[6], r[7], r[8], r[9] }
end


M.nested, M.result, M.with_yaw = nested, result, with_yaw

return M
