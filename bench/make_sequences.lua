-- Synthetic tracking sequences, for choosing and checking the tracking filter beyond the dev
-- set's eight.
--
--   lua5.4 bench/make_sequences.lua OUT_DIR [SEQUENCES [SEED]] [--sigma PX] [--camera dev|random]
--     [--kinds NAME,NAME,...] [--frames N] [--jitter J] [--drop P] [--tags K]
--   lua5.4 examples/accuracy.lua OUT_DIR --track
--
-- Writes OUT_DIR/corners.csv, truth.csv, camera.lua and meta.json in the format of
-- bench/dev (frame = sequence * 1000 + k): SEQUENCES (default 70) trajectories of up
-- to N (default 250) frames each, cycling through the kinds (default: all of KINDS below) with
-- random parameters, corners with Gaussian noise of σ = PX pixels (default 0.5); frames whose
-- corners leave the image are dropped (a gap in the track).
--
-- * `--camera dev` (default): the dev set's 640x480 camera, fx = fy = 883.98, a 24 mm tag;
--   `--camera random`: a camera drawn from the seed (fx 500..1100, fy within 3 % of fx, the
--   principal point up to 30 px off the centre, 640x480 or 1280x720) and a tag of 16..60 mm.
-- * Time: frames are nominally 1/30 s apart; `corners.csv` has a column `time` (seconds).
--   `--jitter J` moves each frame's time by up to ±J frame intervals (uniform; default 0),
--   `--drop P` leaves out frames at random (probability P each, and half as often a burst of
--   2..6 missed frames; default 0): the frame number k counts nominal frames, so a missed
--   frame is a gap in k.
-- * `--tags K` (default 1): K tags in view at once in every sequence, each on its own
--   trajectory, all with id 0 (as the lab's tags are); `truth.csv` has a column `track` that
--   says which physical tag a row is.
--
-- Deterministic for a SEED (default 777). Run from the repository root (it uses
-- spec/support/geometry.lua).

package.path = "./spec/?.lua;./src/?.lua;./src/?/init.lua;" .. package.path
local G = require("support.geometry")
local rotation = require("tagpose.core.rotation")
local compat = require("tagpose.core.compat")

local sin, cos, pi, rad, sqrt, floor = math.sin, math.cos, math.pi, math.rad,
  math.sqrt, math.floor
local atan2 = compat.atan2

--- The kinds of trajectory, in the order sequences cycle through them.
local KINDS = { "approach", "far_hover", "far_wobble", "orbit", "spin", "drive_by",
  "enter_turning", "crossing", "far_crossing", "slow_crossing", "hover_frontal", "pan", "shake",
  "tumble", "robot_approach" }

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua bench/make_sequences.lua OUT_DIR "
    .. "[SEQUENCES [SEED]] [--sigma PX] [--camera dev|random] [--kinds A,B] [--frames N] "
    .. "[--jitter J] [--drop P] [--tags K]\n")
  os.exit(2)
end

local opt = { count = 70, seed = 777, sigma = 0.5, camera = "dev", frames = 250, jitter = 0,
  drop = 0, tags = 1, kinds = KINDS }
do
  local positional, i = {}, 1
  while i <= #arg do
    local a = arg[i]
    local function value()
      i = i + 1
      return arg[i] or usage(a .. " needs a value")
    end
    if a == "--sigma" then
      opt.sigma = tonumber(value()) or usage("--sigma: number expected")
    elseif a == "--camera" then
      opt.camera = value()
      if opt.camera ~= "dev" and opt.camera ~= "random" then usage("--camera: dev or random") end
    elseif a == "--kinds" then
      opt.kinds = {}
      for name in value():gmatch("[^,]+") do
        local known = false
        for _, k in ipairs(KINDS) do known = known or k == name end
        if not known then usage("unknown kind " .. name) end
        opt.kinds[#opt.kinds + 1] = name
      end
    elseif a == "--frames" then
      opt.frames = tonumber(value()) or usage("--frames: number expected")
    elseif a == "--jitter" then
      opt.jitter = tonumber(value()) or usage("--jitter: number expected")
    elseif a == "--drop" then
      opt.drop = tonumber(value()) or usage("--drop: number expected")
    elseif a == "--tags" then
      opt.tags = tonumber(value()) or usage("--tags: number expected")
    elseif a:sub(1, 2) == "--" then
      usage("unknown option " .. a)
    else
      positional[#positional + 1] = a
    end
    i = i + 1
  end
  opt.out = positional[1] or usage()
  opt.count = tonumber(positional[2] or opt.count) or usage("SEQUENCES: number expected")
  opt.seed = tonumber(positional[3] or opt.seed) or usage("SEED: number expected")
  if opt.frames > 999 then usage("--frames: at most 999") end
end

local rng = G.rng(opt.seed)
-- Park-Miller's first draws from a small seed are small: warm it up
for _ = 1, 20 do rng.uniform() end
local FRAME = 1 / 30 -- nominal frame interval, seconds

local camera, size
if opt.camera == "dev" then
  camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }
  size = 0.024
else
  local wide = rng.uniform() < 0.3
  local w, h = wide and 1280 or 640, wide and 720 or 480
  local fx = rng.uniform(500, 1100) * (wide and 1.6 or 1)
  camera = { fx = fx, fy = fx * rng.uniform(0.97, 1.03), cx = w / 2 - 0.5 + rng.uniform(-30, 30),
    cy = h / 2 - 0.5 + rng.uniform(-30, 30), width = w, height = h }
  size = rng.uniform(0.016, 0.06)
end
-- the apparent width (px) of the tag at distance d (m) on the dev camera, and the distance that
-- gives the same apparent width on this one: trajectories are written for the dev camera
local function distance(d)
  return d * (camera.fx / 883.98) * (size / 0.024)
end
local function pixel(u, v)
  return (u - 320) * camera.width / 640 + camera.width / 2,
    (v - 240) * camera.height / 480 + camera.height / 2
end

-- the pose of kind at fraction f (0..1) of the sequence, given random parameters P (uniform
-- 0..1) and phases h: distance (m, for the dev camera), the tilt vector (τx, τy) (radians: the
-- tag's normal turned by |τ| from the line of sight, about the axis (τx, τy, 0) of the line of
-- sight's frame; the two poses of the planar ambiguity have opposite τ), in-plane roll, pixel
-- (u, v) on a 640x480 image
local function trajectory(kind, f, P, h)
  local function polar(tilt, azimuth)
    return tilt * cos(azimuth), tilt * sin(azimuth)
  end
  if kind == "approach" then
    local tx, ty = polar(rad(5 + 40 * P[1] + 5 * sin(2 * pi * f + h[1])),
      h[2] + 0.3 * sin(pi * f))
    return 0.8 - 0.7 * f, tx, ty, h[3] + 0.5 * f, 320 + 150 * (P[4] - 0.5) * (1 - f),
      240 + 100 * (P[5] - 0.5)
  elseif kind == "far_hover" then
    local tx, ty = polar(rad(8 + 7 * sin(2 * pi * (1 + 2 * P[2]) * f + h[2])),
      h[3] + sin(2 * pi * f * P[4] + h[4]))
    return 0.9 + 0.6 * P[1] + 0.03 * sin(2 * pi * f + h[1]), tx, ty,
      h[5] + 0.2 * sin(2 * pi * f), 320 + 200 * (P[6] - 0.5) + 20 * sin(2 * pi * f + h[6]),
      240 + 150 * (P[7] - 0.5)
  elseif kind == "far_wobble" then
    -- the tilt swings through face-on along one line: the two poses cross
    local tx, ty = polar(rad(20 * sin(2 * pi * (1 + 2 * P[2]) * f + h[2])), h[3])
    return 0.5 + 0.4 * P[1], tx, ty, h[5] + 0.3 * sin(2 * pi * f), 320 + 200 * (P[6] - 0.5),
      240 + 150 * (P[7] - 0.5)
  elseif kind == "orbit" then
    local tx, ty = polar(rad(30 + 30 * sin(2 * pi * f + h[2])), h[3] + 2 * pi * f)
    return 0.3 + 0.2 * P[1], tx, ty, h[5], 320 + 100 * (P[6] - 0.5), 240 + 80 * (P[7] - 0.5)
  elseif kind == "spin" then
    local tx, ty = polar(rad(10 + 30 * P[2]), h[3])
    return 0.2 + 0.2 * P[1], tx, ty, h[5] + 4 * pi * f, 320 + 100 * (P[6] - 0.5),
      240 + 80 * (P[7] - 0.5)
  elseif kind == "drive_by" then
    local tx, ty = polar(rad(50 * (2 * f - 1)), h[3])
    return 0.4 + 0.3 * P[1], tx, ty, h[5], 60 + 520 * f, 240 + 100 * (P[7] - 0.5)
  elseif kind == "enter_turning" then
    local tx, ty = polar(rad(15 + 35 * f), h[3] + f)
    return 0.25 + 0.1 * P[1], tx, ty, h[5] + f, 600 - 400 * f, 240 + 100 * (P[7] - 0.5)
  elseif kind == "crossing" or kind == "far_crossing" or kind == "slow_crossing" then
    -- a straight line through the tilt plane, passing face-on at a distance of 0..3°, swung
    -- back and forth (1..3 passes); apparent width 25..80 px (far: 10..30 px)
    local width = kind == "far_crossing" and 10 + 20 * P[1] or 25 + 55 * P[1]
    local amplitude = kind == "slow_crossing" and rad(4 + 6 * P[2]) or rad(10 + 25 * P[2])
    local passes = 1 + floor(3 * P[3])
    local s = amplitude * sin(pi * passes * (f - 0.5) + (P[4] - 0.5))
    local offset = rad(3 * P[5])
    local a = h[1]
    local tx, ty = s * cos(a) - offset * sin(a), s * sin(a) + offset * cos(a)
    return 0.024 * 883.98 / width, tx, ty, h[5] + 0.4 * sin(2 * pi * f + h[6]),
      320 + 300 * (P[6] - 0.5) + 40 * sin(2 * pi * f + h[7]), 240 + 200 * (P[7] - 0.5)
  elseif kind == "hover_frontal" then
    -- a far tag wandering within a few degrees of face-on: no frame says which branch
    local width = 10 + 20 * P[1]
    local tx = rad(3 * P[2]) * sin(2 * pi * (0.5 + P[3]) * f + h[1]) + rad(2) * (P[4] - 0.5)
    local ty = rad(3 * P[2]) * sin(2 * pi * (0.5 + P[5]) * f + h[2]) + rad(2) * (P[8] - 0.5)
    return 0.024 * 883.98 / width, tx, ty, h[5] + 0.2 * sin(2 * pi * f),
      320 + 300 * (P[6] - 0.5) + 15 * sin(2 * pi * f + h[3]), 240 + 200 * (P[7] - 0.5)
  elseif kind == "pan" then
    -- the camera pans across a still tag: the line of sight sweeps past the tag's normal
    local u = 40 + 560 * (P[1] < 0.5 and f or 1 - f)
    local along = math.atan((u - 320) / 883.98)
    local tx, ty = polar(1, h[1])
    local tilt0 = rad(25 * (P[2] - 0.5))
    return 0.25 + 0.45 * P[3], tilt0 * tx - along, tilt0 * ty + rad(4 * (P[4] - 0.5)),
      h[5], u, 240 + 200 * (P[7] - 0.5)
  elseif kind == "shake" then
    -- a vibrating mount: quick small rotations on a mean tilt of 3..25°
    local tx, ty = polar(rad(3 + 22 * P[1]), h[1])
    local a = rad(1 + 3 * P[2])
    local w = 2 * pi * (15 + 25 * P[3])
    return 0.2 + 0.5 * P[4], tx + a * sin(w * f + h[2]), ty + a * sin(1.3 * w * f + h[3]),
      h[5] + 0.5 * a * sin(0.7 * w * f + h[4]), 320 + 200 * (P[6] - 0.5) + 5 * sin(w * f),
      240 + 150 * (P[7] - 0.5)
  elseif kind == "tumble" then
    -- turning at a steady rate about an axis across the line of sight, passing face-on
    local rate = rad(20 + 60 * P[1])
    local s = rate * (f - P[2])
    local a = h[1]
    return 0.3 + 0.4 * P[3], s * cos(a) + rad(2 * (P[4] - 0.5)) * sin(a),
      s * sin(a), h[5] + rad(30) * f * (P[5] - 0.5), 320 + 250 * (P[6] - 0.5),
      240 + 180 * (P[7] - 0.5)
  end
  -- robot_approach: a robot camera looking down at a block's face as it drives up to it,
  -- turning a little left and right (yaw) as it steers
  local yaw = rad(12 * P[1]) * sin(2 * pi * (1 + P[2]) * f + h[1])
  return 0.6 - 0.5 * f * (0.5 + 0.5 * P[3]), rad(20 + 30 * P[4]) + 0.3 * yaw, yaw, h[5],
    320 + 200 * (P[6] - 0.5) * (1 - f) + 60 * yaw, 280 + 120 * P[7] * f
end

-- the tag's rotation (flat) and translation for a trajectory point, by geometry.random_pose
local function pose_of(d, tx, ty, roll, u, v)
  local tilt = sqrt(tx * tx + ty * ty)
  local azimuth = tilt > 0 and atan2(ty, tx) or 0
  u, v = pixel(u, v)
  local r, t = G.random_pose(nil, camera, size, { width = camera.fx * size / distance(d),
    tilt = tilt, azimuth = azimuth, roll = roll, u = u, v = v })
  return r, t
end

os.execute('mkdir -p "' .. opt.out .. '"')
local corners = assert(io.open(opt.out .. "/corners.csv", "w"))
local truth = assert(io.open(opt.out .. "/truth.csv", "w"))
corners:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,time\n")
truth:write("frame,tag,x,y,z,qw,qx,qy,qz,track\n")
local names, rows = {}, 0
for sq = 0, opt.count - 1 do
  -- which nominal frames are seen (dropped frames and bursts), and their times
  local seen, times, k = {}, {}, 0
  while k < opt.frames do
    local burst = 1
    local u = rng.uniform()
    if u < opt.drop then
      burst = 0
    elseif u < 1.5 * opt.drop then
      burst = -floor(rng.uniform(2, 7))
    end
    if burst == 1 then
      seen[k] = true
      times[k] = (k + opt.jitter * rng.uniform(-1, 1)) * FRAME
      k = k + 1
    else
      k = k + (burst == 0 and 1 or -burst)
    end
  end
  local tags = {}
  for j = 1, opt.tags do
    local kind = opt.kinds[((sq * opt.tags + j - 1) % #opt.kinds) + 1]
    local h, P = {}, {}
    for i = 1, 8 do h[i] = rng.uniform(0, 2 * pi) end
    for i = 1, 8 do P[i] = rng.uniform() end
    tags[j] = { kind = kind, h = h, P = P, kept = 0 }
  end
  local span = opt.frames * FRAME
  for k2 = 0, opt.frames - 1 do
    if seen[k2] then
      for j, tag in ipairs(tags) do
        local f = times[k2] / span
        if f < 0 then f = 0 end
        local r, t = pose_of(trajectory(tag.kind, f, tag.P, tag.h))
        local px = G.project(camera, r, t, size)
        local inside = px ~= nil
        for i = 1, 4 do
          if inside and (px[i][1] < 1 or px[i][1] > camera.width - 1 or px[i][2] < 1
            or px[i][2] > camera.height - 1) then
            inside = false
          end
        end
        if inside then
          local frame, values = sq * 1000 + k2, {}
          for i = 1, 4 do
            values[i] = ("%.17g,%.17g"):format(px[i][1] + opt.sigma * rng.normal(),
              px[i][2] + opt.sigma * rng.normal())
          end
          corners:write(frame, ",0,", table.concat(values, ","), (",%.17g\n"):format(times[k2]))
          local w, x, y, z = rotation.to_quaternion(r)
          truth:write(("%d,0,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d\n"):format(frame, t[1],
            t[2], t[3], w, x, y, z, sq * opt.tags + j - 1))
          tag.kept = tag.kept + 1
          rows = rows + 1
        end
      end
    end
  end
  for j, tag in ipairs(tags) do
    names[#names + 1] = ('    {"sequence": %d, "track": %d, "name": "%s", "frames": %d}'):format(
      sq, sq * opt.tags + j - 1, tag.kind, tag.kept)
  end
end
corners:close()
truth:close()
local file = assert(io.open(opt.out .. "/camera.lua", "w"))
file:write(("return { fx = %.17g, fy = %.17g, cx = %.17g, cy = %.17g, width = %d, height = %d, "
  .. "tag_size = %.17g }\n"):format(camera.fx, camera.fy, camera.cx, camera.cy, camera.width,
  camera.height, size))
file:close()
file = assert(io.open(opt.out .. "/meta.json", "w"))
file:write(('{\n  "name": "synthetic sequences",\n  "generator": "bench/make_sequences.lua",\n'
  .. '  "seed": %d,\n  "noise": {"sigma_px": %g},\n  "camera": "%s",\n  "frame_time": %.17g,\n'
  .. '  "jitter": %g,\n  "drop": %g,\n  "tags": %d,\n  "rows": %d,\n  "sequences": [\n%s\n  ]\n}\n')
  :format(opt.seed, opt.sigma, opt.camera, FRAME, opt.jitter, opt.drop, opt.tags, rows,
  table.concat(names, ",\n")))
file:close()
print(("wrote %d sequences (%d rows) to %s"):format(opt.count, rows, opt.out))
