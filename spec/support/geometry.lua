-- Ground truth for the specs, built from geometry alone (nothing here calls tagpose): a
-- deterministic random generator, rotations, the pinhole projection of docs/conventions.md
-- and a random pose generator.

local sqrt, sin, cos, pi = math.sqrt, math.sin, math.cos, math.pi

local G = {}

--- Park-Miller minimal standard generator: exact in doubles, the same sequence on every VM.
function G.rng(seed)
  local s = seed % 2147483647
  if s <= 0 then s = s + 2147483646 end
  local self = {}
  function self.uniform(a, b)
    s = (16807 * s) % 2147483647
    local u = s / 2147483647
    if a == nil then return u end
    return a + (b - a) * u
  end
  function self.log_uniform(a, b)
    return a * (b / a) ^ self.uniform()
  end
  function self.normal()
    local u1, u2 = self.uniform(), self.uniform()
    return sqrt(-2 * math.log(u1)) * cos(2 * pi * u2)
  end
  return self
end

--- Flat row-major rotation about a unit axis (Rodrigues).
function G.axis_angle(ax, ay, az, t)
  local n = sqrt(ax * ax + ay * ay + az * az)
  ax, ay, az = ax / n, ay / n, az / n
  local c, s = cos(t), sin(t)
  local k = 1 - c
  return {
    c + ax * ax * k, ax * ay * k - az * s, ax * az * k + ay * s,
    ay * ax * k + az * s, c + ay * ay * k, ay * az * k - ax * s,
    az * ax * k - ay * s, az * ay * k + ax * s, c + az * az * k,
  }
end

function G.mul(a, b)
  local o = {}
  for i = 0, 2 do
    for j = 1, 3 do
      o[i * 3 + j] = a[i * 3 + 1] * b[j] + a[i * 3 + 2] * b[3 + j] + a[i * 3 + 3] * b[6 + j]
    end
  end
  return o
end

function G.nested(r)
  return { { r[1], r[2], r[3] }, { r[4], r[5], r[6] }, { r[7], r[8], r[9] } }
end

--- Tag corners c1..c4 (docs/conventions.md), side s, in the tag frame.
function G.tag_corners(s)
  local h = s / 2
  return { { -h, h, 0 }, { h, h, 0 }, { h, -h, 0 }, { -h, -h, 0 } }
end

--- OpenCV's lens models, written out from OpenCV's documentation (independently of tagpose):
-- normalised undistorted (x, y) -> distorted (xd, yd).
function G.distort(camera, x, y)
  local d = camera.distortion
  if not d then return x, y end
  if camera.model == "fisheye" then
    local r = math.sqrt(x * x + y * y)
    if r == 0 then return x, y end
    local th = math.atan(r)
    local th2 = th * th
    local thd = th * (1 + (d.k1 or 0) * th2 + (d.k2 or 0) * th2 ^ 2 + (d.k3 or 0) * th2 ^ 3
      + (d.k4 or 0) * th2 ^ 4)
    return thd / r * x, thd / r * y
  end
  local k1, k2, k3 = d.k1 or 0, d.k2 or 0, d.k3 or 0
  local k4, k5, k6 = d.k4 or 0, d.k5 or 0, d.k6 or 0
  local p1, p2 = d.p1 or 0, d.p2 or 0
  local r2 = x * x + y * y
  local radial = (1 + k1 * r2 + k2 * r2 ^ 2 + k3 * r2 ^ 3)
    / (1 + k4 * r2 + k5 * r2 ^ 2 + k6 * r2 ^ 3)
  return x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
    y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
end

--- Pixels {{u, v}, ...} of the tag's corners for pose (r flat, t = {x, y, z}), through the
-- camera's lens model if it has one; nil if a corner is not in front of the camera.
function G.project(camera, r, t, s)
  local out = {}
  for i, c in ipairs(G.tag_corners(s)) do
    local x = r[1] * c[1] + r[2] * c[2] + r[3] * c[3] + t[1]
    local y = r[4] * c[1] + r[5] * c[2] + r[6] * c[3] + t[2]
    local z = r[7] * c[1] + r[8] * c[2] + r[9] * c[3] + t[3]
    if not (z > 0) then return nil end
    local xd, yd = G.distort(camera, x / z, y / z)
    out[i] = { camera.fx * xd + camera.cx, camera.fy * yd + camera.cy }
  end
  return out
end

--- A random visible pose: the tag centre at a random pixel, a random apparent width (px),
-- the tag's normal tilted `tilt` radians from the line of sight (random azimuth), a random
-- in-plane roll. Returns r (flat), t ({x, y, z}), tilt.
function G.random_pose(rng, camera, s, opts)
  opts = opts or {}
  local width = opts.width or rng.log_uniform(10, 400)
  local tilt = opts.tilt or rng.uniform(0, opts.max_tilt or (80 * pi / 180))
  local u = opts.u or rng.uniform(0, camera.width or 2 * camera.cx)
  local v = opts.v or rng.uniform(0, camera.height or 2 * camera.cy)
  -- line of sight through (u, v)
  local dx, dy = (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
  local n = sqrt(dx * dx + dy * dy + 1)
  local lx, ly, lz = dx / n, dy / n, 1 / n
  local dist = camera.fx * s / width
  local t = { lx * dist, ly * dist, lz * dist }
  -- a frame whose z axis is the line of sight
  local ax, ay, az = 0, 1, 0
  if math.abs(ly) > 0.9 then ax, ay, az = 1, 0, 0 end
  -- x = a × l, y = l × x
  local x1, x2, x3 = ay * lz - az * ly, az * lx - ax * lz, ax * ly - ay * lx
  local xn = sqrt(x1 * x1 + x2 * x2 + x3 * x3)
  x1, x2, x3 = x1 / xn, x2 / xn, x3 / xn
  local y1, y2, y3 = ly * x3 - lz * x2, lz * x1 - lx * x3, lx * x2 - ly * x1
  local base = { x1, y1, lx, x2, y2, ly, x3, y3, lz }
  -- roll about the tag normal, then tilt about an axis across the line of sight
  local roll = opts.roll or rng.uniform(0, 2 * pi)
  local azimuth = opts.azimuth or rng.uniform(0, 2 * pi)
  local r = G.mul(base, G.mul(G.axis_angle(cos(azimuth), sin(azimuth), 0, tilt),
    G.axis_angle(0, 0, 1, roll)))
  return r, t, tilt
end

-- Hamilton product of quaternions {w, x, y, z}
function G.qmul(a, b)
  return { a[1] * b[1] - a[2] * b[2] - a[3] * b[3] - a[4] * b[4],
    a[1] * b[2] + a[2] * b[1] + a[3] * b[4] - a[4] * b[3],
    a[1] * b[3] - a[2] * b[4] + a[3] * b[1] + a[4] * b[2],
    a[1] * b[4] + a[2] * b[3] - a[3] * b[2] + a[4] * b[1] }
end

return G
