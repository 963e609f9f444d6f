-- The scenes of the block specs, from geometry alone (nothing here calls tagpose but `solve`,
-- the call under test): cubes on a floor in front of a robot's camera, the tags of the faces
-- that face it projected, with noise when asked.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local layouts = require("support.layouts")

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

-- A cube glued by hand: tags 0-5 of side TAG on the faces of the cube of side BLOCK
-- (tagpose.layout.cube's faces, written out in support/faces.lua), each off its face's centre
-- by U(-2, 2) mm in x and y, turned U(-2, 2)° on the face and tilted U(0, 0.5)°, and tag 3
-- (face -y) a smaller one, 18 mm. Returns the nominal layout and the glued one (the truth).
local function glued_cube(rng)
  local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 2, 0.5)
  nominal.tags[3].size, truth.tags[3].size = 0.018, 0.018
  return nominal, truth
end

-- A calibration log of a layout: sessions of n frames with the cube set down on its faces -z,
-- +x and +y, a camera circling it (support/layouts.session), corner noise sigma.
local function calibration_log(layout, cam, rng, n, sigma)
  local frames = {}
  for _, down in ipairs({ { 0, 0, -1 }, { 1, 0, 0 }, { 0, 1, 0 } }) do
    for _, f in ipairs(layouts.session(layout, cam, rng, n, down, sigma)) do
      frames[#frames + 1] = f
    end
  end
  return frames
end

-- One frame of `count` copies of a layout's cube side by side across the view (centres about
-- 85 mm apart, 0.25-0.35 away), each turned at random: the detections of the tags facing the
-- camera (within 70°, inside the image, noise sigma), and each copy's pose {r =, t =} (block
-- -> camera).
local function copies(layout, cam, rng, count, sigma)
  local dets, poses = {}, {}
  for c = 1, count do
    local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
      rng.uniform(0, math.pi))
    local t = { (c - (count + 1) / 2) * 0.085 + rng.uniform(-0.005, 0.005),
      rng.uniform(-0.03, 0.03), rng.uniform(0.25, 0.35) }
    for _, d in ipairs(layouts.detections(layout, cam, r, t, rng, sigma, 70)) do
      dets[#dets + 1] = d
    end
    poses[c] = { r = r, t = t }
  end
  return dets, poses
end

-- The errors of blocks against the true poses of the copies: for each copy, the block whose
-- centre is nearest (within half a block), its centre's distance and its rotation's angle
-- (degrees, absolute: the block frame of a layout whose ids tell the tags apart); nil for a
-- copy no block found.
local function errors(blocks, poses)
  local out = {}
  for c, pose in ipairs(poses) do
    local best, best_d = nil, 0.5 * BLOCK
    for _, b in ipairs(blocks) do
      local p = b.position
      local d = sqrt((p.x - pose.t[1]) ^ 2 + (p.y - pose.t[2]) ^ 2 + (p.z - pose.t[3]) ^ 2)
      if d < best_d then best, best_d = b, d end
    end
    out[c] = best and { centre = best_d, faces = best.faces,
      angle = assertions.rotation_angle(pose.r, best.rotation) } or false
  end
  return out
end

B.camera, B.TAG, B.BLOCK, B.FACES, B.SYMMETRIES = camera, TAG, BLOCK, FACES, SYMMETRIES
B.glued_cube, B.calibration_log, B.copies, B.errors = glued_cube, calibration_log, copies, errors
B.apply, B.symmetric_error, B.robot_camera, B.view, B.yaw = apply, symmetric_error,
  robot_camera, view, yaw
B.random_block, B.detections_of, B.solve = random_block, detections_of, solve

return B
