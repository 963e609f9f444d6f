-- Synthetic tracking sequences, for checking the tracking rule beyond the dev set's eight.
--
--   lua5.4 bench/make_sequences.lua OUT_DIR [SEQUENCES [SEED]]
--   lua5.4 examples/accuracy.lua OUT_DIR --track
--
-- Writes OUT_DIR/corners.csv, truth.csv, camera.lua and meta.json in the format of
-- bench/dev (frame = sequence * 1000 + k): SEQUENCES (default 70) trajectories of up
-- to 250 frames each, cycling through seven kinds (approach, far_hover, far_wobble, orbit, spin,
-- drive_by, enter_turning) with random parameters, a 24 mm tag seen by a 640x480 camera
-- (fx = fy = 883.98), corners with Gaussian noise of 0.5 px; frames whose corners leave the
-- image are dropped (a gap in the track). Deterministic for a SEED (default 777). Run from the
-- repository root (it uses spec/support/geometry.lua).

package.path = "./spec/?.lua;./src/?.lua;./src/?/init.lua;" .. package.path
local G = require("support.geometry")
local rotation = require("tagpose.rotation")

local out = arg[1] or error("usage: lua bench/make_sequences.lua OUT_DIR [SEQUENCES [SEED]]")
local count, seed = tonumber(arg[2] or "70"), tonumber(arg[3] or "777")

local sin, pi, rad, abs = math.sin, math.pi, math.rad, math.abs
local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 }
local size, sigma, frames = 0.024, 0.5, 250
local KINDS = { "approach", "far_hover", "far_wobble", "orbit", "spin", "drive_by",
  "enter_turning" }

-- the pose of kind at fraction f of the sequence, given random parameters P (uniform 0..1) and
-- phases h: distance (m), tilt from the line of sight, its azimuth, in-plane roll, pixel (u, v)
local function trajectory(kind, f, P, h)
  if kind == "approach" then
    return 0.8 - 0.7 * f, rad(5 + 40 * P[1] + 5 * sin(2 * pi * f + h[1])),
      h[2] + 0.3 * sin(pi * f), h[3] + 0.5 * f, 320 + 150 * (P[4] - 0.5) * (1 - f),
      240 + 100 * (P[5] - 0.5)
  elseif kind == "far_hover" then
    return 0.9 + 0.6 * P[1] + 0.03 * sin(2 * pi * f + h[1]),
      rad(8 + 7 * sin(2 * pi * (1 + 2 * P[2]) * f + h[2])), h[3] + sin(2 * pi * f * P[4] + h[4]),
      h[5] + 0.2 * sin(2 * pi * f), 320 + 200 * (P[6] - 0.5) + 20 * sin(2 * pi * f + h[6]),
      240 + 150 * (P[7] - 0.5)
  elseif kind == "far_wobble" then
    -- the tilt swings through face-on: the two poses cross
    local tilt, azimuth = rad(20 * sin(2 * pi * (1 + 2 * P[2]) * f + h[2])), h[3]
    if tilt < 0 then tilt, azimuth = -tilt, azimuth + pi end
    return 0.5 + 0.4 * P[1], tilt, azimuth, h[5] + 0.3 * sin(2 * pi * f),
      320 + 200 * (P[6] - 0.5), 240 + 150 * (P[7] - 0.5)
  elseif kind == "orbit" then
    return 0.3 + 0.2 * P[1], rad(30 + 30 * sin(2 * pi * f + h[2])), h[3] + 2 * pi * f, h[5],
      320 + 100 * (P[6] - 0.5), 240 + 80 * (P[7] - 0.5)
  elseif kind == "spin" then
    return 0.2 + 0.2 * P[1], rad(10 + 30 * P[2]), h[3], h[5] + 4 * pi * f,
      320 + 100 * (P[6] - 0.5), 240 + 80 * (P[7] - 0.5)
  elseif kind == "drive_by" then
    return 0.4 + 0.3 * P[1], rad(50 * abs(2 * f - 1)), h[3] + (f < 0.5 and 0 or pi), h[5],
      60 + 520 * f, 240 + 100 * (P[7] - 0.5)
  end
  -- enter_turning
  return 0.25 + 0.1 * P[1], rad(15 + 35 * f), h[3] + f, h[5] + f, 600 - 400 * f,
    240 + 100 * (P[7] - 0.5)
end

local rng = G.rng(seed)
os.execute('mkdir -p "' .. out .. '"')
local corners = assert(io.open(out .. "/corners.csv", "w"))
local truth = assert(io.open(out .. "/truth.csv", "w"))
corners:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
truth:write("frame,tag,x,y,z,qw,qx,qy,qz\n")
local names = {}
for sq = 0, count - 1 do
  local kind = KINDS[sq % #KINDS + 1]
  local h, P = {}, {}
  for i = 1, 8 do h[i] = rng.uniform(0, 2 * pi) end
  for i = 1, 8 do P[i] = rng.uniform() end
  local kept = 0
  for k = 0, frames - 1 do
    local d, tilt, azimuth, roll, u, v = trajectory(kind, k / frames, P, h)
    local r, t = G.random_pose(rng, camera, size, { width = camera.fx * size / d, tilt = tilt,
      azimuth = azimuth, roll = roll, u = u, v = v })
    local px = G.project(camera, r, t, size)
    local inside = px ~= nil
    for i = 1, 4 do
      if inside and (px[i][1] < 1 or px[i][1] > camera.width - 1 or px[i][2] < 1
        or px[i][2] > camera.height - 1) then
        inside = false
      end
    end
    if inside then
      local frame, values = sq * 1000 + k, {}
      for i = 1, 4 do
        values[i] = ("%.17g,%.17g"):format(px[i][1] + sigma * rng.normal(),
          px[i][2] + sigma * rng.normal())
      end
      corners:write(frame, ",0,", table.concat(values, ","), "\n")
      local w, x, y, z = rotation.to_quaternion(r)
      truth:write(("%d,0,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n"):format(frame, t[1], t[2],
        t[3], w, x, y, z))
      kept = kept + 1
    end
  end
  names[#names + 1] = ('    {"sequence": %d, "name": "%s", "frames": %d}'):format(sq, kind, kept)
end
corners:close()
truth:close()
local file = assert(io.open(out .. "/camera.lua", "w"))
file:write("return { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480, "
  .. "tag_size = 0.024 }\n")
file:close()
file = assert(io.open(out .. "/meta.json", "w"))
file:write(('{\n  "name": "synthetic sequences",\n  "seed": %d,\n  "noise": {"sigma_px": %g},\n'
  .. '  "sequences": [\n%s\n  ]\n}\n'):format(seed, sigma, table.concat(names, ",\n")))
file:close()
print(("wrote %d sequences to %s"):format(count, out))
