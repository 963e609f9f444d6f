-- tagpose.localizer with a camera that moves on the robot (a camera on a lift, as on a
-- BuilderBot): the frame's own mount given to update. Ground truth from geometry: a robot
-- standing before a wall of tags, its camera raised from 0.2 m to 0.9 m over the frames, the
-- corners projected through the true mount of each frame.
local tagpose = require("tagpose")
local G = require("support.geometry")

local sqrt, sin, cos = math.sqrt, math.sin, math.cos
local S = 0.1651

-- a wall at x = 4 facing -x: tag x = field -y, tag y (down) = field -z, tag z (into) = field +x
local R_TAG = { 0, 0, 1, -1, 0, 0, 0, -1, 0 }
local TAGS = { { 1, 4, 0.6, 0.5 }, { 2, 4, -0.5, 0.9 }, { 3, 4, 0.1, 1.3 }, { 4, 4, -1.2, 0.4 } }

local function quaternion(m)
  local w = sqrt(math.max(0, 1 + m[1] + m[5] + m[9])) / 2
  return { w = w, x = (m[8] - m[6]) / (4 * w), y = (m[3] - m[7]) / (4 * w),
    z = (m[4] - m[2]) / (4 * w) }
end

local function map()
  local tags = {}
  for _, t in ipairs(TAGS) do
    tags[t[1]] = { size = S, position = { x = t[2], y = t[3], z = t[4] },
      quaternion = quaternion(R_TAG) }
  end
  return { tags = tags }
end

-- camera optical -> robot: looking along robot +x, level (x right = -y robot, y down = -z)
local R_MOUNT = { 0, 0, 1, -1, 0, 0, 0, -1, 0 }
local function mount(z)
  return { position = { x = 0.2, y = 0, z = z }, quaternion = quaternion(R_MOUNT) }
end

local CAMERA = { fx = 800, fy = 800, cx = 640, cy = 400, width = 1280, height = 800 }

-- the corners of every tag seen by the camera at height z on the robot at (x, y, yaw)
local function detections(rng, x, y, yaw, z)
  local c, s = cos(yaw), sin(yaw)
  local R = { c, -s, 0, s, c, 0, 0, 0, 1 }
  local Rfc = G.mul(R, R_MOUNT)
  local cx = x + R[1] * 0.2 + R[2] * 0 + R[3] * z
  local cy = y + R[4] * 0.2 + R[5] * 0 + R[6] * z
  local cz = z
  local out = {}
  for _, t in ipairs(TAGS) do
    local corners = {}
    local h = S / 2
    for k, p in ipairs({ { -h, h }, { h, h }, { h, -h }, { -h, -h } }) do
      local px = t[2] + R_TAG[1] * p[1] + R_TAG[2] * p[2]
      local py = t[3] + R_TAG[4] * p[1] + R_TAG[5] * p[2]
      local pz = t[4] + R_TAG[7] * p[1] + R_TAG[8] * p[2]
      local d1, d2, d3 = px - cx, py - cy, pz - cz
      local X = Rfc[1] * d1 + Rfc[4] * d2 + Rfc[7] * d3
      local Y = Rfc[2] * d1 + Rfc[5] * d2 + Rfc[8] * d3
      local Z = Rfc[3] * d1 + Rfc[6] * d2 + Rfc[9] * d3
      corners[k] = { CAMERA.fx * X / Z + CAMERA.cx + 0.3 * rng.normal(),
        CAMERA.fy * Y / Z + CAMERA.cy + 0.3 * rng.normal() }
    end
    out[#out + 1] = { id = t[1], corners = corners }
  end
  return out
end

describe("tagpose.localizer with a camera on a lift", function()
  local function run(per_frame)
    local cam = {}
    for k, v in pairs(CAMERA) do cam[k] = v end
    cam.mount = mount(0.2)
    local loc = tagpose.localizer.new(map(), { lift = cam }, { mode = "single" })
    local rng = G.rng(5)
    local worst, lost = 0, 0
    for k = 0, 40 do
      local t = k / 20
      local z = 0.2 + 0.7 * k / 40
      local x, y, yaw = 0.5, 0.1, 0.05
      loc:gyro(t, yaw + 1.0)
      local est = loc:update("lift", detections(rng, x, y, yaw, z), t,
        per_frame and mount(z) or nil)
      if est.position then
        local e = sqrt((est.position.x - x) ^ 2 + (est.position.y - y) ^ 2)
        if e > worst then worst = e end
      else
        lost = lost + 1
      end
    end
    return worst, lost
  end

  -- (3.5 m from the wall, four tags, 0.3 px of noise: a frame alone is good to a few cm)
  it("places the robot with each frame's own mount", function()
    local worst, lost = run(true)
    assert.equal(0, lost)
    assert.is_true(worst < 0.04, ("worst planar error %.4f m"):format(worst))
  end)

  it("is off without it (the check can fail): the camera's height taken for a lifted, tilted "
    .. "robot, refused by the floor or placed elsewhere", function()
      local with = run(true)
      local without, lost = run(false)
      assert.is_true(lost > 10 or without > 5 * with, ("%.4f m with the frame's mount; %.4f m "
        .. "and %d frames of 41 lost without"):format(with, without, lost))
    end)

  it("refuses a mount that is not one, at the caller's line", function()
    local cam = {}
    for k, v in pairs(CAMERA) do cam[k] = v end
    cam.mount = mount(0.2)
    local loc = tagpose.localizer.new(map(), { lift = cam })
    local ok, err = pcall(loc.update, loc, "lift", {}, 0, { position = { x = 0 } })
    assert.is_false(ok)
    assert.matches("bad argument #4 to 'update'", err, 1, true)
  end)
end)
