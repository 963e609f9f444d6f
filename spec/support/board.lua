-- Ground truth for the board calibrations, from geometry alone (nothing here calls tagpose): an
-- N×N board of tags glued off by known amounts, seen by a camera from in front at several
-- angles, every tag's corners projected. For the layout calibration's spec and
-- bench/bounds.lua (its time on large boards).
--
-- The board's frame: x right, y down, z into the board (a tag lies flat with the body's axes);
-- tag id `row·N + col` sits at `((col - (N - 1)/2)·pitch, (row - (N - 1)/2)·pitch, 0)`.

local geometry = require("support.geometry")
local layouts = require("support.layouts")

local cos, sin, pi, rad = math.cos, math.sin, math.pi, math.rad

local B = {}

--- The camera the board is seen with (1280×960, no lens distortion).
B.CAMERA = { fx = 1000, fy = 1000, cx = 639.5, cy = 479.5, width = 1280, height = 960 }

local function entry(r, x, y, size)
  return { size = size, position = { x = x, y = y, z = 0 }, quaternion = layouts.quaternion(r) }
end

--- The nominal board and the board glued off: per tag an in-plane offset U(-mm, mm) in x and
-- y, a turn U(-deg, deg) about its normal and a tilt U(0, tilt) degrees about a random
-- in-plane axis.
-- @return nominal, truth (public layouts)
function B.layouts(rng, n, size, pitch, mm, deg, tilt)
  local nominal, truth = { tags = {} }, { tags = {} }
  local identity = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }
  for row = 0, n - 1 do
    for col = 0, n - 1 do
      local id = row * n + col
      local x, y = (col - (n - 1) / 2) * pitch, (row - (n - 1) / 2) * pitch
      nominal.tags[id] = entry(identity, x, y, size)
      local dx, dy = rng.uniform(-mm, mm) / 1000, rng.uniform(-mm, mm) / 1000
      local phi = rng.uniform(0, 2 * pi)
      local glue = geometry.mul(geometry.axis_angle(cos(phi), sin(phi), 0,
        rad(rng.uniform(0, tilt))), geometry.axis_angle(0, 0, 1, rad(rng.uniform(-deg, deg))))
      truth.tags[id] = entry(glue, x + dx, y + dy, size)
    end
  end
  return nominal, truth
end

--- `frames` views of a layout from in front: the camera at distance `distance` on a cone of
-- half-angle up to 35° about the board's normal, looking at the board's centre (moved by a
-- few cm), every tag facing it within 75° and inside the image, corners with N(0, sigma) px
-- noise. Returns an array of frames of detections.
function B.views(layout, rng, frames, distance, sigma)
  local out = {}
  for k = 1, frames do
    local a = 2 * pi * (k - 1) / frames + rng.uniform(0, 0.3)
    local tilt = rad(10 + 25 * rng.uniform())
    local c = { distance * sin(tilt) * cos(a), distance * sin(tilt) * sin(a),
      -distance * cos(tilt) }
    local target = { 0.02 * rng.normal(), 0.02 * rng.normal(), 0 }
    local rb, tb = layouts.look_at(c, target, { 0, -1, 0 })
    local dets = layouts.detections(layout, B.CAMERA, rb, tb, rng, sigma)
    if #dets > 0 then out[#out + 1] = dets end
  end
  return out
end

return B
