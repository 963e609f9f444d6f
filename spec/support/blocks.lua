-- The scenes of the block specs, from geometry alone (nothing here calls tagpose but `solve`,
-- the call under test): cubes on a floor in front of a robot's camera, the tags of the faces
-- that face it projected, with noise when asked.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")

local sqrt, sin, cos, rad = math.sqrt, math.sin, math.cos, math.rad

local B = {}

local camera = { fx = 313.9, fy = 312.1, cx = 161.2, cy = 118.4, width = 320, height = 240 }
local TAG, BLOCK = 0.024, 0.055

local FACES = require("support.faces").FACES

-- the cube's 24 rotations: signed permutation matrices with determinant +1
local SYMMETRIES = {}
local PERMUTATIONS = { { 1, 2, 3 }, { 2, 3, 1 }, { 3, 1, 2 }, { 1, 3, 2 }, { 3, 2, 1 },
  { 2, 1, 3 } }
for _, p in ipairs(PERMUTATIONS) do
  for s = 0, 7 do
    local signs = { s % 2 == 0 and 1 or -1, s % 4 < 2 and 1 or -1, s < 4 and 1 or -1 }
    local g = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }
    for row = 1, 3 do g[(row - 1) * 3 + p[row]] = signs[row] end
    local det = g[1] * (g[5] * g[9] - g[6] * g[8]) - g[2] * (g[4] * g[9] - g[6] * g[7])
      + g[3] * (g[4] * g[8] - g[5] * g[7])
    if det > 0 then SYMMETRIES[#SYMMETRIES + 1] = g end
  end
end

local function apply(r, v)
  return { r[1] * v[1] + r[2] * v[2] + r[3] * v[3], r[4] * v[1] + r[5] * v[2] + r[6] * v[3],
    r[7] * v[1] + r[8] * v[2] + r[9] * v[3] }
end

-- rotation error in degrees, the least over the cube's symmetries
local function symmetric_error(truth, got)
  local best = math.huge
  for _, g in ipairs(SYMMETRIES) do
    local e = assertions.rotation_angle(geometry.mul(truth, g), got)
    if e < best then best = e end
  end
  return best
end

-- The robot's camera: looking forward (world x) and down by `pitch` from `height` above the
-- floor (world z up). Returns world → camera rotation, the camera centre, and up in the camera.
local function robot_camera(pitch, height)
  local c, s = cos(pitch), sin(pitch)
  -- rows: camera x (right = world -y), camera y (down), camera z (forward)
  local r = { 0, -1, 0, -s, 0, -c, c, 0, -s }
  return r, { 0, 0, height }, { r[3], r[6], r[9] }
end

-- A block in the world: centre (world), rotation block → world. Its pose in the camera and the
-- tags of the faces that face the camera (or of the faces named), projected (by `opts.camera`
-- or the robot's camera; noise N(0, opts.sigma) from opts.rng; every id opts.id or 0).
local function view(cam_r, cam_c, centre, r_world, opts)
  opts = opts or {}
  local r = geometry.mul(cam_r, r_world)
  local t = apply(cam_r, { centre[1] - cam_c[1], centre[2] - cam_c[2], centre[3] - cam_c[3] })
  local tags = {}
  for _, f in ipairs(FACES) do
    local n = apply(r, f.n)
    local tt = { t[1] + 0.5 * BLOCK * n[1], t[2] + 0.5 * BLOCK * n[2], t[3] + 0.5 * BLOCK * n[3] }
    local d = sqrt(tt[1] ^ 2 + tt[2] ^ 2 + tt[3] ^ 2)
    local facing = (n[1] * tt[1] + n[2] * tt[2] + n[3] * tt[3]) / d
    local wanted = opts.faces and opts.faces[f.name] or (not opts.faces and facing < -0.15)
    if wanted then
      local corners = geometry.project(opts.camera or camera, geometry.mul(r, f.r), tt, TAG)
      if opts.rng and opts.sigma then
        for _, c in ipairs(corners) do
          c[1] = c[1] + opts.sigma * opts.rng.normal()
          c[2] = c[2] + opts.sigma * opts.rng.normal()
        end
      end
      tags[#tags + 1] = { id = opts.id or 0, corners = corners, face = f.name }
    end
  end
  return r, t, tags
end

local function yaw(a)
  return geometry.axis_angle(0, 0, 1, a)
end

-- a random scene: one block on the floor, `k` faces in view
local function random_block(rng, k, sigma)
  for _ = 1, 1000 do
    local pitch, height = rad(rng.uniform(20, 40)), rng.uniform(0.06, 0.22)
    local cam_r, cam_c, up = robot_camera(pitch, height)
    local range = rng.uniform(0.1, 0.45)
    local az = rng.uniform(-0.4, 0.4)
    local centre = { range * cos(az), range * sin(az), 0.5 * BLOCK }
    local r_world = yaw(rng.uniform(0, 2 * math.pi))
    local r, t, tags = view(cam_r, cam_c, centre, r_world, { rng = rng, sigma = sigma })
    local inside = t[3] > 0.05
    for _, tag in ipairs(tags) do
      for _, c in ipairs(tag.corners) do
        if c[1] < 0 or c[1] > camera.width or c[2] < 0 or c[2] > camera.height then
          inside = false
        end
      end
    end
    if inside and #tags == k then return r, t, tags, up end
  end
  error("no scene with " .. k .. " faces")
end

local function detections_of(tags)
  local out = {}
  for i, tag in ipairs(tags) do out[i] = { id = tag.id, corners = tag.corners } end
  return out
end

local function solve(tags, options)
  return tagpose.block.solve(detections_of(tags), camera, TAG, BLOCK, options)
end

B.camera, B.TAG, B.BLOCK, B.FACES, B.SYMMETRIES = camera, TAG, BLOCK, FACES, SYMMETRIES
B.apply, B.symmetric_error, B.robot_camera, B.view, B.yaw = apply, symmetric_error,
  robot_camera, view, yaw
B.random_block, B.detections_of, B.solve = random_block, detections_of, solve

return B
