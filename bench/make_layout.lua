-- Synthetic glued-cube data sets drawn like bench/dev/layout_cube, from other seeds,
-- cameras and sizes, so that layout calibration is tuned to the problem and not to one file.
--
--   lua5.4 bench/make_layout.lua OUT_DIR SEED [--frames N] [--calib K] [--test M]
--     [--sigma PX] [--tag-size S] [--block-size B] [--camera builderbot|vga|wide]
--     [--glue MM,DEG,TILT] [--outliers P]
--   lua5.4 bench/score_layout.lua OUT_DIR
--
-- Writes OUT_DIR/camera.lua, meta.json, nominal_layout.csv, truth_layout.csv, and calib/ and
-- test/ with corners.csv (frame,tag,u1,v1,...,u4,v4) and truth_tags.csv (frame,tag,x,y,z,qw,
-- qx,qy,qz: every tag's camera-frame pose in every frame, seen or not), in the dev set's form.
--
-- The scene (lengths in metres, angles in degrees; world Z up):
-- * the cube (side B, default 0.0548) carries tags 0-5 (side S, default 0.0229) on its faces
--   +x, -x, +y, -y, +z, -z as tagpose.layout.cube places them; each tag is glued off: an
--   in-plane offset U(-MM, MM) in its x and y, an in-plane turn U(-DEG, DEG) and a tilt
--   |N(0, TILT)| about a random in-plane axis (default 2, 3, 0.3: the dev set's);
-- * a session sets the cube down on one face (a random order of the six faces: the first K
--   sessions, default 4, are the calibration log, the next M, default 2, the test log) with a
--   random yaw, and a camera circles it for N frames (default 150): azimuth over U(1, 1.5)
--   turns either way, horizontal distance oscillating within U(0.12, 0.2)..U(0.3, 0.4) of the
--   cube, height above the cube's centre from U(0.1, 0.18) to U(0.05, 0.1), looking at the
--   cube's centre moved by N(0, 1 cm) per axis, rolled N(0, 3);
-- * a tag is seen when it faces the camera within 75 degrees, its corners are 1 px inside the
--   image and its shortest edge is 8 px or more; corners get N(0, SIGMA) px noise (default
--   0.3); with --outliers P, a seen tag's corners are replaced, with probability P, by a
--   gross misdetection (shifted 2-20 px, one corner 5-30 px further);
-- * the camera (--camera): builderbot (the dev set's 320x240, fx 307.22, fy 305.74), vga
--   (640x480, fx 600, fy 596) or wide (640x480, fx 380, fy 378, k1 -0.28, k2 0.07: projected
--   through Brown-Conrady distortion); the seed moves the focal lengths by up to 2 % and the
--   principal point by up to 4 px.
--
-- Self-contained and deterministic: one SEED and options give byte-identical files on Lua
-- 5.1-5.4 and LuaJIT (a Park-Miller generator of its own, exact in doubles; %.17g numbers).

package.path = "./spec/?.lua;" .. package.path
local layouts = require("support.layouts")

local sqrt, sin, cos, log, abs = math.sqrt, math.sin, math.cos, math.log, math.abs
local floor, pi, rad = math.floor, math.pi, math.rad
local format, concat = string.format, table.concat

local USAGE = "usage: lua bench/make_layout.lua OUT_DIR SEED [--frames N] [--calib K] "
  .. "[--test M] [--sigma PX] [--tag-size S] [--block-size B] [--camera builderbot|vga|wide] "
  .. "[--glue MM,DEG,TILT] [--outliers P]"

local CAMERAS = {
  builderbot = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87, width = 320, height = 240 },
  vga = { fx = 600, fy = 596, cx = 319.5, cy = 239.5, width = 640, height = 480 },
  wide = { fx = 380, fy = 378, cx = 319.5, cy = 239.5, width = 640, height = 480,
    distortion = { k1 = -0.28, k2 = 0.07 } },
}

local FACING = cos(rad(75))
local MARGIN, MIN_EDGE = 1, 8

---------------------------------------------------------------------------------------------
-- Random numbers: Park-Miller with the 48271 multiplier (exact in doubles everywhere).

local function new_rng(seed)
  local M, A = 2147483647, 48271
  local state = seed % (M - 1) + 1
  local rng = {}
  function rng.uniform(a, b)
    state = state * A % M
    local u = state / M
    if a then return a + (b - a) * u end
    return u
  end
  function rng.normal()
    local r, phi = sqrt(-2 * log(rng.uniform())), 2 * pi * rng.uniform()
    return r * cos(phi)
  end
  for _ = 1, 10 do rng.uniform() end
  return rng
end

---------------------------------------------------------------------------------------------
-- 3x3 matrices, flat row-major.

local function mul(a, b)
  local c = {}
  for i = 0, 6, 3 do
    for j = 1, 3 do
      c[i + j] = a[i + 1] * b[j] + a[i + 2] * b[3 + j] + a[i + 3] * b[6 + j]
    end
  end
  return c
end

local function apply(a, x, y, z)
  return a[1] * x + a[2] * y + a[3] * z, a[4] * x + a[5] * y + a[6] * z,
    a[7] * x + a[8] * y + a[9] * z
end

local function axis_angle(x, y, z, t)
  local n = sqrt(x * x + y * y + z * z)
  x, y, z = x / n, y / n, z / n
  local c, s = cos(t), sin(t)
  local k = 1 - c
  return { c + x * x * k, x * y * k - z * s, x * z * k + y * s,
    y * x * k + z * s, c + y * y * k, y * z * k - x * s,
    z * x * k - y * s, z * y * k + x * s, c + z * z * k }
end

-- unit quaternion (w >= 0) of a rotation, as four numbers (spec/support/layouts.lua's)
local function quaternion(m)
  local q = layouts.quaternion(m)
  local n = sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z)
  return q.w / n, q.x / n, q.y / n, q.z / n
end

---------------------------------------------------------------------------------------------
-- The cube: faces in id order, outward normal n and the tag frame R = [x y z] on the body
-- (tag z = -n; side faces: tag y = -z; top +z: x = +x, y = -y; bottom -z: x = +x, y = +y).

local FACES = {
  { n = { 1, 0, 0 }, r = { 0, 0, -1, 1, 0, 0, 0, -1, 0 } },
  { n = { -1, 0, 0 }, r = { 0, 0, 1, -1, 0, 0, 0, -1, 0 } },
  { n = { 0, 1, 0 }, r = { -1, 0, 0, 0, 0, -1, 0, -1, 0 } },
  { n = { 0, -1, 0 }, r = { 1, 0, 0, 0, 0, 1, 0, -1, 0 } },
  { n = { 0, 0, 1 }, r = { 1, 0, 0, 0, -1, 0, 0, 0, -1 } },
  { n = { 0, 0, -1 }, r = { 1, 0, 0, 0, 1, 0, 0, 0, 1 } },
}

-- the body -> world rotation that puts face f's outward normal down
local function resting(f, yaw)
  local n = FACES[f].n
  local r
  if n[3] == -1 then
    r = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }
  elseif n[3] == 1 then
    r = axis_angle(1, 0, 0, pi)
  else
    -- turn n onto -Z about the horizontal axis n x (-Z)
    r = axis_angle(-n[2], n[1], 0, pi / 2)
  end
  return mul(axis_angle(0, 0, 1, yaw), r)
end

---------------------------------------------------------------------------------------------

local function parse(argv)
  local o = { dir = argv[1], seed = tonumber(argv[2]), frames = 150, calib = 4, test = 2,
    sigma = 0.3, tag = 0.0229, block = 0.0548, camera = "builderbot", glue = { 2, 3, 0.3 },
    outliers = 0 }
  if not o.dir or not o.seed then return nil end
  local i = 3
  while argv[i] do
    local a, v = argv[i], argv[i + 1]
    if v == nil then return nil end
    if a == "--frames" then o.frames = tonumber(v)
    elseif a == "--calib" then o.calib = tonumber(v)
    elseif a == "--test" then o.test = tonumber(v)
    elseif a == "--sigma" then o.sigma = tonumber(v)
    elseif a == "--tag-size" then o.tag = tonumber(v)
    elseif a == "--block-size" then o.block = tonumber(v)
    elseif a == "--camera" then o.camera = v
    elseif a == "--outliers" then o.outliers = tonumber(v)
    elseif a == "--glue" then
      local g = {}
      for x in v:gmatch("[^,]+") do g[#g + 1] = tonumber(x) end
      if #g ~= 3 then return nil end
      o.glue = g
    else return nil end
    i = i + 2
  end
  if not CAMERAS[o.camera] or not (o.calib + o.test <= 6) then return nil end
  return o
end

local o = parse(arg)
if not o then
  io.stderr:write(USAGE .. "\n")
  os.exit(2)
end
local rng = new_rng(o.seed)

-- the camera of this draw
local base = CAMERAS[o.camera]
local cam = { width = base.width, height = base.height, distortion = base.distortion }
cam.fx = base.fx * (1 + rng.uniform(-0.02, 0.02))
cam.fy = base.fy * (1 + rng.uniform(-0.02, 0.02))
cam.cx = base.cx + rng.uniform(-4, 4)
cam.cy = base.cy + rng.uniform(-4, 4)

local function project(x, y, z)
  local a, b = x / z, y / z
  local d = cam.distortion
  if d then
    local r2 = a * a + b * b
    local f = 1 + d.k1 * r2 + d.k2 * r2 * r2
    a, b = a * f, b * f
  end
  return cam.fx * a + cam.cx, cam.fy * b + cam.cy
end

-- the nominal and the glued layout
local HALF, H = o.block / 2, o.tag / 2
local nominal, truth = {}, {}
for f = 1, 6 do
  local face = FACES[f]
  nominal[f] = { r = face.r, p = { HALF * face.n[1], HALF * face.n[2], HALF * face.n[3] } }
  local g = o.glue[1] / 1000
  local dx, dy = rng.uniform(-g, g), rng.uniform(-g, g)
  local turn = rad(rng.uniform(-o.glue[2], o.glue[2]))
  local phi = rng.uniform(0, 2 * pi)
  local tilt = rad(abs(rng.normal() * o.glue[3]))
  local glue = mul(axis_angle(cos(phi), sin(phi), 0, tilt), axis_angle(0, 0, 1, turn))
  local ox, oy, oz = apply(face.r, dx, dy, 0)
  truth[f] = { r = mul(face.r, glue), p = { nominal[f].p[1] + ox, nominal[f].p[2] + oy,
    nominal[f].p[3] + oz } }
end

-- the faces set down, in session order
local order = { 1, 2, 3, 4, 5, 6 }
for i = 6, 2, -1 do
  local j = floor(rng.uniform() * i) + 1
  order[i], order[j] = order[j], order[i]
end

local function num(v) return format("%.17g", v) end

local function session(s, down, corner_lines, truth_lines, stats)
  local rwb = resting(down, rng.uniform(-pi, pi))
  local centre = { 0, 0, HALF }
  local turns = rng.uniform(1, 1.5) * (rng.uniform() < 0.5 and -1 or 1)
  local phi0 = rng.uniform(0, 2 * pi)
  local near, far = rng.uniform(0.12, 0.2), rng.uniform(0.3, 0.4)
  local wave, psi = rng.uniform(0.8, 1.6), rng.uniform(0, 2 * pi)
  local h0, h1 = rng.uniform(0.1, 0.18), rng.uniform(0.05, 0.1)
  for k = 0, o.frames - 1 do
    local u = k / (o.frames - 1)
    local phi = phi0 + 2 * pi * turns * u
    local rho = near + (far - near) * 0.5 * (1 + cos(2 * pi * wave * u + psi))
    local h = h0 + (h1 - h0) * u
    local c = { rho * cos(phi), rho * sin(phi), centre[3] + h }
    local target = { centre[1] + 0.01 * rng.normal(), centre[2] + 0.01 * rng.normal(),
      centre[3] + 0.01 * rng.normal() }
    local z = { target[1] - c[1], target[2] - c[2], target[3] - c[3] }
    local nz = sqrt(z[1] ^ 2 + z[2] ^ 2 + z[3] ^ 2)
    z = { z[1] / nz, z[2] / nz, z[3] / nz }
    local x = { z[2], -z[1], 0 } -- z x (0, 0, 1)
    local nx = sqrt(x[1] ^ 2 + x[2] ^ 2)
    x = { x[1] / nx, x[2] / nx, 0 }
    local y = { z[2] * x[3] - z[3] * x[2], z[3] * x[1] - z[1] * x[3], z[1] * x[2] - z[2] * x[1] }
    local rcw = mul(axis_angle(0, 0, 1, rad(3 * rng.normal())),
      { x[1], x[2], x[3], y[1], y[2], y[3], z[1], z[2], z[3] }) -- world -> camera
    local frame = 1000 * s + k
    local seen = 0
    for f = 1, 6 do
      local t = truth[f]
      local r = mul(rcw, mul(rwb, t.r)) -- tag -> camera
      local wx, wy, wz = apply(rwb, t.p[1], t.p[2], t.p[3])
      local tx, ty, tz = apply(rcw, wx + centre[1] - c[1], wy + centre[2] - c[2],
        wz + centre[3] - c[3])
      local qw, qx, qy, qz = quaternion(r)
      truth_lines[#truth_lines + 1] = concat({ frame, f - 1, num(tx), num(ty), num(tz), num(qw),
        num(qx), num(qy), num(qz) }, ",")
      -- facing: the tag's z (into the body) against the line of sight to its centre
      local d = sqrt(tx * tx + ty * ty + tz * tz)
      local ok = (r[3] * tx + r[6] * ty + r[9] * tz) / d > FACING
      local px = {}
      if ok then
        for i = 1, 4 do
          local a, b = (i == 1 or i == 4) and -H or H, (i <= 2) and H or -H
          local X, Y, Z = apply(r, a, b, 0)
          X, Y, Z = X + tx, Y + ty, Z + tz
          if not (Z > 0) then ok = false break end
          px[2 * i - 1], px[2 * i] = project(X, Y, Z)
          if not (px[2 * i - 1] >= MARGIN and px[2 * i - 1] <= cam.width - 1 - MARGIN
            and px[2 * i] >= MARGIN and px[2 * i] <= cam.height - 1 - MARGIN) then
            ok = false
          end
        end
      end
      if ok then
        for i = 1, 4 do
          local j = i % 4 + 1
          local e = sqrt((px[2 * j - 1] - px[2 * i - 1]) ^ 2 + (px[2 * j] - px[2 * i]) ^ 2)
          if e < MIN_EDGE then ok = false end
        end
      end
      if ok then
        seen = seen + 1
        local bad = o.outliers > 0 and rng.uniform() < o.outliers
        local sx, sy = 0, 0
        if bad then
          local m, a = rng.uniform(2, 20), rng.uniform(0, 2 * pi)
          sx, sy = m * cos(a), m * sin(a)
          stats.outliers = stats.outliers + 1
        end
        local line = { frame, f - 1 }
        local far_corner = bad and floor(rng.uniform() * 4) + 1 or 0
        for i = 1, 4 do
          local ex, ey = sx, sy
          if i == far_corner then
            local m, a = rng.uniform(5, 30), rng.uniform(0, 2 * pi)
            ex, ey = ex + m * cos(a), ey + m * sin(a)
          end
          line[#line + 1] = num(px[2 * i - 1] + o.sigma * rng.normal() + ex)
          line[#line + 1] = num(px[2 * i] + o.sigma * rng.normal() + ey)
        end
        corner_lines[#corner_lines + 1] = concat(line, ",")
        stats.rows = stats.rows + 1
      end
    end
    if seen > 0 then stats.frames = stats.frames + 1 end
    if seen > 1 then stats.multi = stats.multi + 1 end
  end
end

local function write(path, text)
  local f = assert(io.open(path, "w"))
  f:write(text)
  f:close()
end

local function layout_csv(list)
  local lines = { "id,size,x,y,z,qw,qx,qy,qz" }
  for f = 1, 6 do
    local t = list[f]
    local w, x, y, z = quaternion(t.r)
    lines[#lines + 1] = concat({ f - 1, num(o.tag), num(t.p[1]), num(t.p[2]), num(t.p[3]), num(w),
      num(x), num(y), num(z) }, ",")
  end
  return concat(lines, "\n") .. "\n"
end

os.execute("mkdir -p '" .. o.dir .. "/calib' '" .. o.dir .. "/test'")
local summary = {}
for _, part in ipairs({ "calib", "test" }) do
  local range = part == "calib" and { 1, o.calib } or { o.calib + 1, o.calib + o.test }
  local corners = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
  local truths = { "frame,tag,x,y,z,qw,qx,qy,qz" }
  local stats = { rows = 0, frames = 0, multi = 0, outliers = 0 }
  summary[part] = stats
  for s = range[1], range[2] do session(s - 1, order[s], corners, truths, stats) end
  write(o.dir .. "/" .. part .. "/corners.csv", concat(corners, "\n") .. "\n")
  write(o.dir .. "/" .. part .. "/truth_tags.csv", concat(truths, "\n") .. "\n")
end
write(o.dir .. "/nominal_layout.csv", layout_csv(nominal))
write(o.dir .. "/truth_layout.csv", layout_csv(truth))
local cam_lines = { "-- generated by bench/make_layout.lua, seed " .. o.seed, "return {",
  "  fx = " .. num(cam.fx) .. ",", "  fy = " .. num(cam.fy) .. ",", "  cx = " .. num(cam.cx)
  .. ",", "  cy = " .. num(cam.cy) .. ",", "  width = " .. cam.width .. ",", "  height = "
  .. cam.height .. ",", "  tag_size = " .. num(o.tag) .. ",", "  block_size = " .. num(o.block)
  .. "," }
if cam.distortion then
  cam_lines[#cam_lines + 1] = "  distortion = { k1 = " .. num(cam.distortion.k1) .. ", k2 = "
    .. num(cam.distortion.k2) .. " },"
end
cam_lines[#cam_lines + 1] = "}"
write(o.dir .. "/camera.lua", concat(cam_lines, "\n") .. "\n")
local faces = {}
for s = 1, o.calib + o.test do faces[s] = tostring(order[s] - 1) end
write(o.dir .. "/meta.json", concat({ "{",
  ' "generator": "bench/make_layout.lua",',
  ' "seed": ' .. o.seed .. ',',
  ' "camera": "' .. o.camera .. '",',
  ' "tag_size": ' .. num(o.tag) .. ',',
  ' "block_size": ' .. num(o.block) .. ',',
  ' "sigma_px": ' .. num(o.sigma) .. ',',
  ' "glue": "offset U(-' .. o.glue[1] .. ', ' .. o.glue[1] .. ') mm, turn U(-' .. o.glue[2]
    .. ', ' .. o.glue[2] .. ') deg, tilt |N(0, ' .. o.glue[3] .. ')| deg",',
  ' "outliers": ' .. num(o.outliers) .. ',',
  ' "bottom_tags_by_session": [' .. concat(faces, ", ") .. '],',
  ' "calib": {"rows": ' .. summary.calib.rows .. ', "frames_with_tags": ' .. summary.calib.frames
    .. ', "frames_with_2plus": ' .. summary.calib.multi .. ', "outliers": '
    .. summary.calib.outliers .. '},',
  ' "test": {"rows": ' .. summary.test.rows .. ', "frames_with_tags": ' .. summary.test.frames
    .. ', "frames_with_2plus": ' .. summary.test.multi .. '}',
  "}" }, "\n") .. "\n")
io.stderr:write(format("%s: calib %d rows, %d frames (%d with 2+ tags), test %d rows, %d frames\n",
  o.dir, summary.calib.rows, summary.calib.frames, summary.calib.multi, summary.test.rows,
  summary.test.frames))
