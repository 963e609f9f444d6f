-- Synthetic single-tag data sets drawn like bench/dev's (the kinds of its PEERS.md),
-- with the held-out sets' differences: fx != fy, an off-centre principal point, other tag sizes
-- and ranges. For checking figures measured on the dev sets away from those files.
--
--   lua5.4 bench/make_tags.lua OUT_DIR KIND SEED [ROWS]
--   lua5.4 examples/uncertainty.lua OUT_DIR
--
-- KIND is one of noise_0.5, noise_1, noise_2, far_frontal, large_tag, builderbot, distorted, or
-- "all" (then OUT_DIR/KIND for each). Writes camera.lua, corners.csv, truth.csv and meta.json
-- (with noise.sigma_px) in the dev sets' format; ROWS defaults to 2000. Each SEED perturbs the
-- kind's camera and sizes: fx by up to ±5 %, fy = fx·(1 ± 3 %), the principal point by up to
-- ±5 % of the image, the tag side and the range limits by a factor in [0.8, 1.25], the largest
-- tilt by up to ±5°, the distortion coefficients by ±20 %. Poses as PEERS.md draws them: the tag
-- centre's pixel uniform over the image, the range (far_frontal: the frontal side in pixels)
-- uniform, the tilt from the line of sight uniform, its azimuth and the in-plane roll uniform;
-- rejected unless all four corners are at least 1 px inside the image and the shortest edge is
-- at least 8 px (before noise); then Gaussian noise of the kind's σ on every coordinate.
-- Deterministic for a SEED on every VM (Park-Miller, spec/support/geometry.lua). Run from the
-- repository root.

package.path = "./spec/?.lua;./src/?.lua;./src/?/init.lua;" .. package.path
local G = require("support.geometry")
local rotation = require("tagpose.core.rotation")
local camera_model = require("tagpose.core.camera")

local usage = "usage: lua bench/make_tags.lua OUT_DIR KIND SEED [ROWS]"
local out, kind, seed = arg[1], arg[2], tonumber(arg[3] or "")
local rows = tonumber(arg[4] or "2000")
if not (out and kind and seed and rows) then error(usage) end

local rad, deg, sqrt = math.rad, math.deg, math.sqrt

local ROBOT = { fx = 883.98, width = 640, height = 480 }
local KINDS = {
  ["noise_0.5"] = { cam = ROBOT, size = 0.024, range = { 0.05, 0.8 }, tilt = 75, sigma = 0.5 },
  noise_1 = { cam = ROBOT, size = 0.024, range = { 0.05, 0.8 }, tilt = 75, sigma = 1 },
  noise_2 = { cam = ROBOT, size = 0.024, range = { 0.05, 0.8 }, tilt = 75, sigma = 2 },
  far_frontal = { cam = ROBOT, size = 0.024, side = { 10, 30 }, tilt = 30, sigma = 0.5 },
  large_tag = { cam = ROBOT, size = 0.16, range = { 0.3, 6 }, tilt = 75, sigma = 0.5 },
  builderbot = { cam = { fx = 313.9, width = 320, height = 240 }, size = 0.024,
    range = { 0.05, 0.5 }, tilt = 75, sigma = 0.3 },
  distorted = { cam = { fx = 700, width = 1280, height = 720,
    distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0 } },
    size = 0.1, range = { 0.2, 3 }, tilt = 75, sigma = 0.5 },
}
local ORDER = { "noise_0.5", "noise_1", "noise_2", "far_frontal", "large_tag", "builderbot",
  "distorted" }

local function fmt(v) return ("%.17g"):format(v) end

local function write_set(dir, name, set_seed)
  local K = KINDS[name] or error("unknown kind " .. tostring(name) .. "\n" .. usage)
  -- Park-Miller's state after k draws is seed * 16807^k (mod 2^31 - 1), so nearby seeds give
  -- draws in arithmetic progression: start from one state, SEED * 7 + 10 draws along instead
  local rng = G.rng(20170)
  for _ = 1, 7 * set_seed + 10 do rng.uniform() end
  local base = K.cam
  local fx = base.fx * rng.uniform(0.95, 1.05)
  local camera = {
    fx = fx, fy = fx * rng.uniform(0.97, 1.03),
    cx = (base.width - 1) / 2 + rng.uniform(-0.05, 0.05) * base.width,
    cy = (base.height - 1) / 2 + rng.uniform(-0.05, 0.05) * base.height,
    width = base.width, height = base.height,
  }
  if base.distortion then
    local d = {}
    for _, k in ipairs({ "k1", "k2", "p1", "p2", "k3" }) do
      d[k] = base.distortion[k] * rng.uniform(0.8, 1.2)
    end
    camera.distortion = d
  end
  local size = K.size * rng.uniform(0.8, 1.25)
  local r0, r1
  if K.range then
    r0, r1 = K.range[1] * rng.uniform(0.8, 1.25), K.range[2] * rng.uniform(0.8, 1.25)
  end
  local max_tilt = rad(K.tilt + rng.uniform(-5, 5))
  os.execute('mkdir -p "' .. dir .. '"')
  local corners = assert(io.open(dir .. "/corners.csv", "w"))
  local truth = assert(io.open(dir .. "/truth.csv", "w"))
  corners:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
  truth:write("frame,tag,x,y,z,qw,qx,qy,qz\n")
  local written, tries = 0, 0
  while written < rows do
    tries = tries + 1
    local u, v = rng.uniform(0, camera.width - 1), rng.uniform(0, camera.height - 1)
    -- the line of sight through (u, v): a pinhole pixel for G.random_pose
    local x, y = camera_model.normalise(camera, u, v)
    local width
    if K.side then
      width = rng.uniform(K.side[1], K.side[2])
    else
      width = camera.fx * size / rng.uniform(r0, r1)
    end
    local r, t = G.random_pose(rng, camera, size, { width = width,
      tilt = rng.uniform(0, max_tilt), u = x and camera.fx * x + camera.cx or -1e9,
      v = y and camera.fy * y + camera.cy or -1e9 })
    local px = x and G.project(camera, r, t, size)
    local ok = px ~= nil
    if ok then
      local shortest = math.huge
      for i = 1, 4 do
        local a, b = px[i], px[i % 4 + 1]
        if a[1] < 1 or a[1] > camera.width - 2 or a[2] < 1 or a[2] > camera.height - 2 then
          ok = false
        end
        local e = sqrt((a[1] - b[1]) ^ 2 + (a[2] - b[2]) ^ 2)
        if e < shortest then shortest = e end
      end
      ok = ok and shortest >= 8
    end
    if ok then
      local line = { written, 0 }
      for i = 1, 4 do
        line[#line + 1] = fmt(px[i][1] + K.sigma * rng.normal())
        line[#line + 1] = fmt(px[i][2] + K.sigma * rng.normal())
      end
      corners:write(table.concat(line, ","), "\n")
      local w, qx, qy, qz = rotation.to_quaternion(r)
      truth:write(table.concat({ written, 0, fmt(t[1]), fmt(t[2]), fmt(t[3]), fmt(w), fmt(qx),
        fmt(qy), fmt(qz) }, ","), "\n")
      written = written + 1
    end
  end
  corners:close()
  truth:close()
  local f = assert(io.open(dir .. "/camera.lua", "w"))
  f:write(("-- %s, seed %d: drawn by bench/make_tags.lua\nreturn {\n"):format(name, set_seed))
  for _, k in ipairs({ "fx", "fy", "cx", "cy", "width", "height" }) do
    f:write(("  %s = %s,\n"):format(k, fmt(camera[k])))
  end
  if camera.distortion then
    local d = camera.distortion
    f:write(("  distortion = { k1 = %s, k2 = %s, p1 = %s, p2 = %s, k3 = %s },\n"):format(
      fmt(d.k1), fmt(d.k2), fmt(d.p1), fmt(d.p2), fmt(d.k3)))
  end
  f:write(("  tag_size = %s,\n}\n"):format(fmt(size)))
  f:close()
  f = assert(io.open(dir .. "/meta.json", "w"))
  f:write(('{\n  "name": "%s",\n  "generator": "bench/make_tags.lua",\n  "seed": %d,\n'
    .. '  "rows": %d,\n  "acceptance": %.4f,\n  "tag_size": %s,\n  "max_tilt_deg": %.3f,\n'
    .. '  "noise": { "model": "gaussian", "sigma_px": %s }\n}\n'):format(name, set_seed, rows,
    rows / tries, fmt(size), deg(max_tilt), fmt(K.sigma)))
  f:close()
  io.stderr:write(("%s: %d rows (acceptance %.2f), fx %.1f fy %.1f c (%.1f, %.1f), tag %.4g\n")
    :format(dir, rows, rows / tries, camera.fx, camera.fy, camera.cx, camera.cy, size))
end

if kind == "all" then
  for i, name in ipairs(ORDER) do write_set(out .. "/" .. name, name, seed * 100 + i) end
else
  write_set(out, kind, seed)
end
