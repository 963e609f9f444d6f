-- Make the bundled example: a small robot (BuilderBot-like camera, 320x240) driving up to two
-- AprilTags, as its tag detector would have logged them.
--
--   lua5.4 examples/data/make_approach.lua [OUTDIR]
--
-- Writes, beside this script (or into OUTDIR), the same bytes on every Lua:
--   camera.lua          the camera file (intrinsics and tag size, metres)
--   approach.csv        the corner log: frame,tag,u1,v1,...,u4,v4,margin (margin: an extra
--                       column, as detectors log a decision margin; readers ignore it)
--   approach_truth.csv  the true poses of the same rows, in the pose-log format
--
-- Everything comes from geometry alone (nothing here calls tagpose) and from a Park-Miller
-- generator, so the files are the same on every run. The scene, in a world frame on the wall
-- (x right, y down, z into the wall, metres): tag 1 at x = -0.04 facing the robot, tag 2 at
-- x = +0.04 on a face turned 20 degrees about the vertical. The camera starts 0.6 m away and
-- 0.12 m to the left, 5 cm above the tags, and drives in over 200 frames (slowing down at both
-- ends) to 0.12 m, steering towards the tags with a lag, bobbing and rolling a little as a
-- small robot does. Corners get Gaussian noise of 0.25 px; a detection with a corner outside
-- the image is dropped, tag 2 is hidden in frames 70-84 (something passes in front of it) and
-- the detector misses about 2 % of the other detections.

local sqrt, sin, cos, atan, asin, pi = math.sqrt, math.sin, math.cos, math.atan, math.asin,
  math.pi

local FRAMES = 200
local CAMERA = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 }
local TAG_SIZE = 0.024
local SIGMA = 0.25 -- px

-- Park-Miller: exact in doubles, the same sequence on every VM
local seed = 20170
local function uniform()
  seed = (16807 * seed) % 2147483647
  return seed / 2147483647
end
local function normal()
  local u1, u2 = uniform(), uniform()
  return sqrt(-2 * math.log(u1)) * cos(2 * pi * u2)
end

-- quaternions {w, x, y, z}
local function qmul(a, b)
  return {
    a[1] * b[1] - a[2] * b[2] - a[3] * b[3] - a[4] * b[4],
    a[1] * b[2] + a[2] * b[1] + a[3] * b[4] - a[4] * b[3],
    a[1] * b[3] - a[2] * b[4] + a[3] * b[1] + a[4] * b[2],
    a[1] * b[4] + a[2] * b[3] - a[3] * b[2] + a[4] * b[1],
  }
end
local function conj(q) return { q[1], -q[2], -q[3], -q[4] } end
local function about(ax, ay, az, angle)
  local s = sin(angle / 2)
  return { cos(angle / 2), ax * s, ay * s, az * s }
end
-- rotate the vector v by the quaternion q
local function rotate(q, v)
  local r = qmul(qmul(q, { 0, v[1], v[2], v[3] }), conj(q))
  return { r[2], r[3], r[4] }
end

local TAGS = {
  { id = 1, centre = { -0.04, 0, 0 }, q = { 1, 0, 0, 0 } },
  { id = 2, centre = { 0.04, 0, 0 }, q = about(0, 1, 0, -20 * pi / 180) },
}
local H = TAG_SIZE / 2
local CORNERS = { { -H, H, 0 }, { H, H, 0 }, { H, -H, 0 }, { -H, -H, 0 } } -- c1..c4

local function smoothstep(s) return s * s * (3 - 2 * s) end

-- the camera at frame k: its position in the world and its rotation camera -> world
local function camera_pose(k)
  local s = k / (FRAMES - 1)
  local d = 0.12 + 0.48 * (1 - smoothstep(s))
  local c = { -0.12 * (1 - s) ^ 2 + 0.008 * sin(2 * pi * 3 * s), -0.05, -d }
  -- steer towards (dz > 0: the tags are always ahead) the pair of tags, with a lag; bob and roll
  local dx, dy, dz = -c[1], -c[2], -c[3]
  local n = sqrt(dx * dx + dy * dy + dz * dz)
  local yaw = atan(dx / dz) + 0.06 * sin(2 * pi * 2.5 * s + 0.3)
  local pitch = -asin(dy / n) + 0.02 * sin(2 * pi * 7 * s)
  local roll = 0.015 * sin(2 * pi * 5 * s + 1)
  -- camera axes x right, y down, z forward; yaw about y (down), pitch about x, roll about z
  local q = qmul(qmul(about(0, 1, 0, yaw), about(1, 0, 0, pitch)), about(0, 0, 1, roll))
  return c, q
end

local function fmt(v, decimals)
  local s = ("%." .. decimals .. "f"):format(v)
  if s:match("^%-0%.0*$") then s = s:sub(2) end
  return s
end

local dir = arg and arg[1] or (arg and arg[0] or ""):match("^(.*)/[^/]*$") or "."
local corners_out = {
  "# approach: a BuilderBot-like camera (320x240) driving up to tags 1 and 2.",
  "# Made by examples/data/make_approach.lua; camera and tag size in camera.lua.",
  "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,margin",
}
local truth_out = {
  "# approach: the true pose of every detection in approach.csv (made by make_approach.lua)",
  "frame,tag,x,y,z,qw,qx,qy,qz,error,iterations",
}
for k = 0, FRAMES - 1 do
  local c, qc = camera_pose(k)
  local world_to_camera = conj(qc)
  for _, tag in ipairs(TAGS) do
    -- tag -> camera: X_cam = R (X_tag) + t
    local q = qmul(world_to_camera, tag.q)
    local t = rotate(world_to_camera, { tag.centre[1] - c[1], tag.centre[2] - c[2],
      tag.centre[3] - c[3] })
    local px, inside = {}, true
    for i, corner in ipairs(CORNERS) do
      local p = rotate(q, corner)
      local x, y, z = p[1] + t[1], p[2] + t[2], p[3] + t[3]
      local u = CAMERA.fx * x / z + CAMERA.cx + SIGMA * normal()
      local v = CAMERA.fy * y / z + CAMERA.cy + SIGMA * normal()
      if not (z > 0 and u >= 1 and u <= CAMERA.width - 2 and v >= 1
        and v <= CAMERA.height - 2) then
        inside = false
      end
      px[2 * i - 1], px[2 * i] = fmt(u, 4), fmt(v, 4)
    end
    local width = CAMERA.fx * TAG_SIZE / t[3]
    local margin = fmt(20 + 1.5 * width + 3 * normal(), 1)
    local hidden = tag.id == 2 and k >= 70 and k <= 84
    local missed = uniform() < 0.02
    if inside and not hidden and not missed then
      corners_out[#corners_out + 1] = k .. "," .. tag.id .. "," .. table.concat(px, ",") .. ","
        .. margin
      if q[1] < 0 then q = { -q[1], -q[2], -q[3], -q[4] } end
      truth_out[#truth_out + 1] = table.concat({ k, tag.id, fmt(t[1], 7), fmt(t[2], 7),
        fmt(t[3], 7), fmt(q[1], 8), fmt(q[2], 8), fmt(q[3], 8), fmt(q[4], 8), "", "" }, ",")
    end
  end
end

local function write(name, text)
  local f = assert(io.open(dir .. "/" .. name, "w"))
  f:write(text)
  f:close()
  print("wrote " .. dir .. "/" .. name)
end

write("camera.lua", table.concat({
  "-- The camera of the bundled example (BuilderBot-like, 320x240): pixels, OpenCV's meaning.",
  "-- tag_size is the side of the tag's black square in metres, so poses come out in metres.",
  "return {",
  "  fx = 313.9,",
  "  fy = 313.9,",
  "  cx = 159.5,",
  "  cy = 119.5,",
  "  width = 320,",
  "  height = 240,",
  "  tag_size = 0.024,",
  "}",
  "",
}, "\n"))
write("approach.csv", table.concat(corners_out, "\n") .. "\n")
write("approach_truth.csv", table.concat(truth_out, "\n") .. "\n")
