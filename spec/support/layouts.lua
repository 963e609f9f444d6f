-- Ground truth for the layout specs, from geometry alone (nothing here calls tagpose): glued
-- cubes and boards, the body seen from a camera circling it, the tags' corners projected.
-- Rotations are flat row-major 3×3; layouts have the public shape
-- {tags = {[id] = {size =, position = {x, y, z}, quaternion = {w, x, y, z}}}}.

local geometry = require("support.geometry")
local FACES = require("support.faces").FACES

local sqrt, cos, sin, pi, rad, abs = math.sqrt, math.cos, math.sin, math.pi, math.rad, math.abs

local L = {}

--- Unit quaternion (w >= 0) of a rotation matrix (the largest of 1 + trace and the diagonal
-- terms picks the branch).
function L.quaternion(m)
  local t = m[1] + m[5] + m[9]
  local w, x, y, z
  if t >= m[1] and t >= m[5] and t >= m[9] then
    w = sqrt(1 + t) / 2
    x, y, z = (m[8] - m[6]) / (4 * w), (m[3] - m[7]) / (4 * w), (m[4] - m[2]) / (4 * w)
  elseif m[1] >= m[5] and m[1] >= m[9] then
    x = sqrt(1 + m[1] - m[5] - m[9]) / 2
    w, y, z = (m[8] - m[6]) / (4 * x), (m[2] + m[4]) / (4 * x), (m[3] + m[7]) / (4 * x)
  elseif m[5] >= m[9] then
    y = sqrt(1 - m[1] + m[5] - m[9]) / 2
    w, x, z = (m[3] - m[7]) / (4 * y), (m[2] + m[4]) / (4 * y), (m[6] + m[8]) / (4 * y)
  else
    z = sqrt(1 - m[1] - m[5] + m[9]) / 2
    w, x, y = (m[4] - m[2]) / (4 * z), (m[3] + m[7]) / (4 * z), (m[6] + m[8]) / (4 * z)
  end
  if w < 0 then w, x, y, z = -w, -x, -y, -z end
  return { w = w, x = x, y = y, z = z }
end

--- Rotation matrix of a quaternion {w, x, y, z} (any length).
function L.matrix(q)
  local n = sqrt(q.w ^ 2 + q.x ^ 2 + q.y ^ 2 + q.z ^ 2)
  local w, x, y, z = q.w / n, q.x / n, q.y / n, q.z / n
  return { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
end

function L.apply(r, x, y, z)
  return r[1] * x + r[2] * y + r[3] * z, r[4] * x + r[5] * y + r[6] * z,
    r[7] * x + r[8] * y + r[9] * z
end

function L.transpose(r)
  return { r[1], r[4], r[7], r[2], r[5], r[8], r[3], r[6], r[9] }
end

local function entry(r, p, size)
  return { size = size, position = { x = p[1], y = p[2], z = p[3] }, quaternion = L.quaternion(r) }
end

--- A cube of side `block` with tags 0-5 of side `tag` on faces +x, -x, +y, -y, +z, -z, and the
-- same cube glued off: per tag an in-plane offset U(-mm, mm) in x and y, an in-plane turn
-- U(-deg, deg) and a tilt U(0, tilt) degrees about a random in-plane axis. Returns the nominal
-- layout, the glued one.
function L.cube(rng, tag, block, mm, deg, tilt)
  local nominal, truth = { tags = {} }, { tags = {} }
  for f = 1, 6 do
    local face = FACES[f]
    local h = block / 2
    local p = { h * face.n[1], h * face.n[2], h * face.n[3] }
    nominal.tags[f - 1] = entry(face.r, p, tag)
    local dx, dy = rng.uniform(-mm, mm) / 1000, rng.uniform(-mm, mm) / 1000
    local phi = rng.uniform(0, 2 * pi)
    local glue = geometry.mul(geometry.axis_angle(cos(phi), sin(phi), 0, rad(rng.uniform(0, tilt))),
      geometry.axis_angle(0, 0, 1, rad(rng.uniform(-deg, deg))))
    local ox, oy, oz = L.apply(face.r, dx, dy, 0)
    truth.tags[f - 1] = entry(geometry.mul(face.r, glue), { p[1] + ox, p[2] + oy, p[3] + oz }, tag)
  end
  return nominal, truth
end

--- The tag corners c1..c4 of a layout entry in the body frame ({x, y, z} each).
function L.corners(e)
  local r, p = L.matrix(e.quaternion), e.position
  local out = {}
  for i, c in ipairs(geometry.tag_corners(e.size)) do
    local x, y, z = L.apply(r, c[1], c[2], c[3])
    out[i] = { x + p.x, y + p.y, z + p.z }
  end
  return out
end

--- The detections of a layout seen from the body pose (rb, tb): every tag facing the camera
-- within `facing` degrees (default 75), inside the image (when the camera has width and height),
-- corners with N(0, sigma) noise. Sorted by id.
function L.detections(layout, camera, rb, tb, rng, sigma, facing)
  local limit = cos(rad(facing or 75))
  local ids = {}
  for id in pairs(layout.tags) do ids[#ids + 1] = id end
  table.sort(ids)
  local out = {}
  for _, id in ipairs(ids) do
    local e = layout.tags[id]
    local r = geometry.mul(rb, L.matrix(e.quaternion))
    local p = e.position
    local x, y, z = L.apply(rb, p.x, p.y, p.z)
    local t = { x + tb[1], y + tb[2], z + tb[3] }
    local d = sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
    if (r[3] * t[1] + r[6] * t[2] + r[9] * t[3]) / d > limit then
      local px = geometry.project(camera, r, t, e.size)
      local inside = px ~= nil
      for _, c in ipairs(px or {}) do
        if camera.width and not (c[1] >= 1 and c[1] <= camera.width - 2 and c[2] >= 1
          and c[2] <= camera.height - 2) then
          inside = false
        end
      end
      if inside then
        for _, c in ipairs(px) do
          c[1], c[2] = c[1] + sigma * rng.normal(), c[2] + sigma * rng.normal()
        end
        out[#out + 1] = { id = id, corners = px }
      end
    end
  end
  return out
end

--- The body → camera pose of a camera at `c` (body frame) looking at `target` with the body
-- axis `up` up (roughly): rb, tb.
function L.look_at(c, target, up)
  local z = { target[1] - c[1], target[2] - c[2], target[3] - c[3] }
  local n = sqrt(z[1] ^ 2 + z[2] ^ 2 + z[3] ^ 2)
  z = { z[1] / n, z[2] / n, z[3] / n }
  -- x = z × up (right), y = z × x (down)
  local x = { z[2] * up[3] - z[3] * up[2], z[3] * up[1] - z[1] * up[3],
    z[1] * up[2] - z[2] * up[1] }
  n = sqrt(x[1] ^ 2 + x[2] ^ 2 + x[3] ^ 2)
  x = { x[1] / n, x[2] / n, x[3] / n }
  local y = { z[2] * x[3] - z[3] * x[2], z[3] * x[1] - z[1] * x[3], z[1] * x[2] - z[2] * x[1] }
  local rb = { x[1], x[2], x[3], y[1], y[2], y[3], z[1], z[2], z[3] } -- body → camera
  local a, b, d = L.apply(rb, c[1], c[2], c[3])
  return rb, { -a, -b, -d }
end

--- A session: the cube resting on the face with outward normal `down` (a body axis, e.g.
-- {0, 0, -1}), a camera circling it `n` frames at distance 0.18-0.35 and height 0.06-0.14
-- above its centre, looking at it. Returns an array of frames of detections and their body
-- poses ({r =, t =}).
function L.session(layout, camera, rng, n, down, sigma)
  local up = { -down[1], -down[2], -down[3] }
  -- two horizontal axes
  local a = abs(up[1]) < 0.9 and { 1, 0, 0 } or { 0, 1, 0 }
  local h1 = { up[2] * a[3] - up[3] * a[2], up[3] * a[1] - up[1] * a[3],
    up[1] * a[2] - up[2] * a[1] }
  local nh = sqrt(h1[1] ^ 2 + h1[2] ^ 2 + h1[3] ^ 2)
  h1 = { h1[1] / nh, h1[2] / nh, h1[3] / nh }
  local h2 = { up[2] * h1[3] - up[3] * h1[2], up[3] * h1[1] - up[1] * h1[3],
    up[1] * h1[2] - up[2] * h1[1] }
  local frames, poses = {}, {}
  local phi0 = rng.uniform(0, 2 * pi)
  for k = 1, n do
    local phi = phi0 + 2 * pi * 1.2 * k / n
    local rho = 0.18 + 0.17 * (0.5 + 0.5 * cos(3 * phi))
    local h = 0.06 + 0.08 * k / n
    local c = {}
    for i = 1, 3 do c[i] = rho * (cos(phi) * h1[i] + sin(phi) * h2[i]) + h * up[i] end
    local target = { 0.005 * rng.normal(), 0.005 * rng.normal(), 0.005 * rng.normal() }
    local rb, tb = L.look_at(c, target, up)
    local dets = L.detections(layout, camera, rb, tb, rng, sigma)
    if #dets > 0 then
      frames[#frames + 1] = dets
      poses[#poses + 1] = { r = rb, t = tb }
    end
  end
  return frames, poses
end

--- For every ordered pair of tags (i, j) of two layouts: the largest difference of tag j's
-- centre in tag i's frame (length) and of their relative rotation (degrees).
function L.pair_error(a, b)
  local worst_d, worst_r = 0, 0
  for i, ei in pairs(a.tags) do
    for j, ej in pairs(a.tags) do
      if i ~= j then
        local function rel(li, lj)
          local ri, rj = L.matrix(li.quaternion), L.matrix(lj.quaternion)
          local pi_, pj = li.position, lj.position
          local rt = L.transpose(ri)
          local x, y, z = L.apply(rt, pj.x - pi_.x, pj.y - pi_.y, pj.z - pi_.z)
          return { x, y, z }, geometry.mul(rt, rj)
        end
        local pa, ra = rel(ei, ej)
        local pb, rb = rel(b.tags[i], b.tags[j])
        local d = sqrt((pa[1] - pb[1]) ^ 2 + (pa[2] - pb[2]) ^ 2 + (pa[3] - pb[3]) ^ 2)
        local s = 0
        for k = 1, 9 do s = s + (ra[k] - rb[k]) ^ 2 end
        local angle = math.deg(2 * math.asin(math.min(1, sqrt(s / 8))))
        if d > worst_d then worst_d = d end
        if angle > worst_r then worst_r = angle end
      end
    end
  end
  return worst_d, worst_r
end

--- Write a calibration log of `truth` seen by `camera` (sessions of n frames with the body set
-- down on -z, +x and +y, corner noise sigma: `L.session`) as dir/corners.csv, and the camera
-- as dir/camera.lua.
function L.write_log(dir, truth, camera, rng, n, sigma)
  local lines, frame = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }, 0
  for _, down in ipairs({ { 0, 0, -1 }, { 1, 0, 0 }, { 0, 1, 0 } }) do
    for _, dets in ipairs(L.session(truth, camera, rng, n, down, sigma)) do
      for _, d in ipairs(dets) do
        local row = { frame, d.id }
        for _, c in ipairs(d.corners) do
          row[#row + 1] = ("%.17g"):format(c[1])
          row[#row + 1] = ("%.17g"):format(c[2])
        end
        lines[#lines + 1] = table.concat(row, ",")
      end
      frame = frame + 1
    end
  end
  local write = require("support.run").write
  write(dir .. "/corners.csv", table.concat(lines, "\n") .. "\n")
  write(dir .. "/camera.lua", ("return { fx = %.17g, fy = %.17g, cx = %.17g, cy = %.17g }\n")
    :format(camera.fx, camera.fy, camera.cx, camera.cy))
end

return L
