-- Synthetic cube-block data sets, drawn like bench/dev/blocks but from other seeds, so
-- that figures measured on the one dev file can be checked for overfitting.
--
--   lua5.4 bench/make_blocks.lua OUT_DIR FRAMES SEED [SIGMA]
--   lua5.4 examples/blocks.lua OUT_DIR
--
-- Writes OUT_DIR/camera.lua, corners.csv, truth.csv and truth_tags.csv in the format of the dev
-- set (its meta.json "files", "conventions" and "face_convention"), each of FRAMES frames drawn
-- as its meta.json "scene" and "visibility" say. SIGMA is the corner noise in pixels (default
-- 0.3, as the dev set; 0 gives exact projections). Prints a one-line summary to stderr.
-- Self-contained and deterministic: one SEED gives byte-identical files on Lua 5.1-5.4 and
-- LuaJIT (a Park-Miller generator of its own, exact in doubles; numbers written with %.17g).
--
-- How the rules are read (world: X forward, Y left, Z up, ground Z = 0, camera above the
-- origin):
-- * the camera's forward axis is world X pitched down, its x axis (right) world -Y, its y axis
--   down; then it is rolled about the forward axis;
-- * a block's "range" is the 3D distance from the camera centre to the block's centre; a
--   scattered block's azimuth is measured from world X about Z; "projecting inside the image"
--   is 0 <= u <= width - 1 and 0 <= v <= height - 1 (pixel centres);
-- * each try of a next block draws its kind afresh (adjacent 0.45, stacked 0.20, else
--   scattered); a try that finds no uncovered ground block to stack on, leaves the range or
--   overlaps a block fails; after 60 failed tries the frame has one block fewer;
-- * the side offset of an adjacent block is along the side it touches; the 3 mm offsets of a
--   stacked block are drawn on world X and Y;
-- * a tag's corners are ">= 1 px inside the image" when 1 <= u <= width - 2 and
--   1 <= v <= height - 2 before noise (the dev set's corners reach u = 317.999, v = 1.04);
--   shortest edges are measured before noise too;
-- * a segment occludes when it comes within 1e-6 m of another block (slab method), so a face
--   in contact with a neighbour's face is occluded; the test uses only the block's yaw, since a
--   tipped block's box is the upright one;
-- * two blocks overlap when their footprints (2D separating axes) and their height intervals
--   both overlap by more than 1e-9 m: every block's z axis is vertical as a line, so this is
--   the full separating-axis test for these boxes.

-- luacheck: push compat
local unpack = table.unpack or unpack
-- luacheck: pop

local sqrt, sin, cos, log = math.sqrt, math.sin, math.cos, math.log
local abs, floor, min, pi, rad = math.abs, math.floor, math.min, math.pi, math.rad
local format, concat = string.format, table.concat

local USAGE = "usage: lua bench/make_blocks.lua OUT_DIR FRAMES SEED [SIGMA]"

local CAMERA = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 }
local TAG, BLOCK = 0.024, 0.055
local HALF = BLOCK / 2

-- the scene (meta.json "scene"); lengths in metres, angles in degrees
local HEIGHT_MIN, HEIGHT_MAX = 0.06, 0.22
local PITCH_MIN, PITCH_MAX = 20, 40
local ROLL_MAX = 3
local MAX_BLOCKS, TRIES = 4, 60
local RANGE_MIN, RANGE_MAX = 0.08, 0.6
local AZIMUTH_MAX = 30
local P_ADJACENT, P_STACKED, P_TIPPED = 0.45, 0.20, 0.15
local P_TOUCHING, GAP_MAX = 0.6, 0.004
local P_ALIGNED, OFFSET_MAX = 0.5, 0.25 -- sideways offset, in blocks
local STACK_YAW, STACK_OFFSET = 5, 0.003
local OVERLAP_SLACK = 1e-9

-- visibility (meta.json "visibility")
local FACING = -0.05      -- cosine between the face normal and the view ray, at most
local MARGIN = 1          -- px inside the image
local MIN_EDGE = 8        -- px
local GRID = 5            -- occlusion grid over the tag, per side
local OCCLUSION_SLACK = 1e-6

-- The faces, in the order of meta.json "faces": outward normal n and R = [tag_x tag_y tag_z]
-- (flat 3x3, row-major, 1-based; block frame), tag_z = -n.
local FACES = {
  { name = "+x", n = { 1, 0, 0 }, x = { 0, 1, 0 }, y = { 0, 0, -1 }, z = { -1, 0, 0 } },
  { name = "-x", n = { -1, 0, 0 }, x = { 0, -1, 0 }, y = { 0, 0, -1 }, z = { 1, 0, 0 } },
  { name = "+y", n = { 0, 1, 0 }, x = { -1, 0, 0 }, y = { 0, 0, -1 }, z = { 0, -1, 0 } },
  { name = "-y", n = { 0, -1, 0 }, x = { 1, 0, 0 }, y = { 0, 0, -1 }, z = { 0, 1, 0 } },
  { name = "+z", n = { 0, 0, 1 }, x = { 1, 0, 0 }, y = { 0, -1, 0 }, z = { 0, 0, -1 } },
  { name = "-z", n = { 0, 0, -1 }, x = { 1, 0, 0 }, y = { 0, 1, 0 }, z = { 0, 0, 1 } },
}
for _, f in ipairs(FACES) do
  local x, y, z = f.x, f.y, f.z
  f.r = { x[1], y[1], z[1], x[2], y[2], z[2], x[3], y[3], z[3] }
end

-- tag corners c1..c4 in the tag frame (z = 0)
local CORNERS = { { -TAG / 2, TAG / 2 }, { TAG / 2, TAG / 2 }, { TAG / 2, -TAG / 2 },
  { -TAG / 2, -TAG / 2 } }

---------------------------------------------------------------------------------------------
-- Random numbers: Park-Miller "minimal standard" with the 48271 multiplier. state * 48271 <
-- 2^47, so every step is exact in doubles (Lua 5.1, LuaJIT) and in integers (Lua 5.3+), and
-- state / M is the same double everywhere. Normals by Box-Muller (both values used).

local function new_rng(seed)
  local M, A = 2147483647, 48271
  local state = seed % (M - 1) + 1
  local spare
  local rng = {}
  -- U(0, 1) (never 0 or 1), or U(a, b)
  function rng.uniform(a, b)
    state = state * A % M
    local u = state / M
    if a then return a + (b - a) * u end
    return u
  end
  -- an integer uniform in 1..n
  function rng.index(n)
    return floor(rng.uniform() * n) + 1
  end
  function rng.normal()
    if spare then
      local z = spare
      spare = nil
      return z
    end
    local r, phi = sqrt(-2 * log(rng.uniform())), 2 * pi * rng.uniform()
    spare = r * sin(phi)
    return r * cos(phi)
  end
  for _ = 1, 10 do rng.uniform() end -- move away from small seeds' small first states
  return rng
end

---------------------------------------------------------------------------------------------
-- 3x3 matrices: flat, row-major, 1-based.

local function mat_mul(a, b)
  local c = {}
  for i = 0, 6, 3 do
    local a1, a2, a3 = a[i + 1], a[i + 2], a[i + 3]
    c[i + 1] = a1 * b[1] + a2 * b[4] + a3 * b[7]
    c[i + 2] = a1 * b[2] + a2 * b[5] + a3 * b[8]
    c[i + 3] = a1 * b[3] + a2 * b[6] + a3 * b[9]
  end
  return c
end

local function mat_vec(a, x, y, z)
  return a[1] * x + a[2] * y + a[3] * z, a[4] * x + a[5] * y + a[6] * z,
    a[7] * x + a[8] * y + a[9] * z
end

local function rot_z(angle)
  local c, s = cos(angle), sin(angle)
  return { c, -s, 0, s, c, 0, 0, 0, 1 }
end

-- The 24 rotations of a cube (signed permutation matrices, det +1) and the 20 of them that do
-- not keep +z up (third column other than +z).
local TIPS = {}
do
  local perms = { { 1, 2, 3, 1 }, { 1, 3, 2, -1 }, { 2, 1, 3, -1 }, { 2, 3, 1, 1 },
    { 3, 1, 2, 1 }, { 3, 2, 1, -1 } } -- columns of rows 1..3, and the permutation's sign
  local count = 0
  for _, p in ipairs(perms) do
    for sx = -1, 1, 2 do
      for sy = -1, 1, 2 do
        for sz = -1, 1, 2 do
          if p[4] * sx * sy * sz == 1 then
            local g = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }
            g[p[1]], g[3 + p[2]], g[6 + p[3]] = sx, sy, sz
            count = count + 1
            if g[9] ~= 1 then TIPS[#TIPS + 1] = g end
          end
        end
      end
    end
  end
  assert(count == 24 and #TIPS == 20)
end

-- unit quaternion (w >= 0) of a rotation matrix, by Shepperd's method
local function quaternion(m)
  local m11, m12, m13, m21, m22, m23, m31, m32, m33 = unpack(m, 1, 9)
  local trace = m11 + m22 + m33
  local w, x, y, z
  if trace >= m11 and trace >= m22 and trace >= m33 then
    w = sqrt(1 + trace) / 2
    x, y, z = (m32 - m23) / (4 * w), (m13 - m31) / (4 * w), (m21 - m12) / (4 * w)
  elseif m11 >= m22 and m11 >= m33 then
    x = sqrt(1 + m11 - m22 - m33) / 2
    w, y, z = (m32 - m23) / (4 * x), (m12 + m21) / (4 * x), (m13 + m31) / (4 * x)
  elseif m22 >= m33 then
    y = sqrt(1 - m11 + m22 - m33) / 2
    w, x, z = (m13 - m31) / (4 * y), (m12 + m21) / (4 * y), (m23 + m32) / (4 * y)
  else
    z = sqrt(1 - m11 - m22 + m33) / 2
    w, x, y = (m21 - m12) / (4 * z), (m13 + m31) / (4 * z), (m23 + m32) / (4 * z)
  end
  if w < 0 then w, x, y, z = -w, -x, -y, -z end
  local n = sqrt(w * w + x * x + y * y + z * z)
  return w / n, x / n, y / n, z / n
end

---------------------------------------------------------------------------------------------
-- The camera: centre (0, 0, height) in the world; rows of rwc are its x (right), y (down) and
-- z (forward) axes in world coordinates, so X_cam = rwc (X_world - centre).

local function new_camera(height, pitch, roll)
  local sp, cp, sr, cr = sin(pitch), cos(pitch), sin(roll), cos(roll)
  -- before the roll: x = (0, -1, 0), y = (-sp, 0, -cp), z = (cp, 0, -sp)
  return { height = height, rwc = {
    -sr * sp, -cr, -sr * cp,
    -cr * sp, sr, -cr * cp,
    cp, 0, -sp,
  } }
end

-- pixel of a world point, and its depth
local function project(cam, x, y, z)
  local X, Y, Z = mat_vec(cam.rwc, x, y, z - cam.height)
  return CAMERA.fx * X / Z + CAMERA.cx, CAMERA.fy * Y / Z + CAMERA.cy, Z
end

---------------------------------------------------------------------------------------------
-- Blocks: centre (x, y, z) in the world, yaw (ca, sa = its cosine and sine), rot = yaw * G
-- (block -> world), level 0 on the ground or 1 stacked, covered when a block is stacked on it.

local function new_block(x, y, z, yaw, how)
  return { x = x, y = y, z = z, yaw = yaw, ca = cos(yaw), sa = sin(yaw), how = how,
    level = z > BLOCK and 1 or 0 }
end

local function range(cam, b)
  local dz = b.z - cam.height
  return sqrt(b.x * b.x + b.y * b.y + dz * dz)
end

-- half-width of block b's footprint along the unit direction (nx, ny)
local function radius(b, nx, ny)
  return HALF * (abs(b.ca * nx + b.sa * ny) + abs(b.ca * ny - b.sa * nx))
end

-- do blocks a and b overlap by more than OVERLAP_SLACK (touching is allowed)?
local function overlap(a, b)
  if BLOCK - abs(a.z - b.z) <= OVERLAP_SLACK then return false end
  local dx, dy = b.x - a.x, b.y - a.y
  local axes = { a.ca, a.sa, -a.sa, a.ca, b.ca, b.sa, -b.sa, b.ca }
  for i = 1, 7, 2 do
    local nx, ny = axes[i], axes[i + 1]
    if abs(dx * nx + dy * ny) >= radius(a, nx, ny) + radius(b, nx, ny) - OVERLAP_SLACK then
      return false
    end
  end
  return true
end

-- does the segment p -> q (world) come within OCCLUSION_SLACK of block b? (slab method)
local function segment_hits(b, px, py, pz, qx, qy, qz)
  local h = HALF + OCCLUSION_SLACK
  local ox, oy, oz = px - b.x, py - b.y, pz - b.z
  local dx, dy, dz = qx - px, qy - py, qz - pz
  -- origin and direction along the block's axes (yaw only: the box is the same when tipped)
  local o = { b.ca * ox + b.sa * oy, b.ca * oy - b.sa * ox, oz }
  local d = { b.ca * dx + b.sa * dy, b.ca * dy - b.sa * dx, dz }
  local t0, t1 = 0, 1
  for i = 1, 3 do
    if abs(d[i]) < 1e-15 then
      if abs(o[i]) > h then return false end
    else
      local ta, tb = (-h - o[i]) / d[i], (h - o[i]) / d[i]
      if ta > tb then ta, tb = tb, ta end
      if ta > t0 then t0 = ta end
      if tb < t1 then t1 = tb end
      if t0 > t1 then return false end
    end
  end
  return true
end

---------------------------------------------------------------------------------------------
-- Placing the blocks (meta.json "scene").

local function scattered(rng, cam)
  local r = rng.uniform(RANGE_MIN, RANGE_MAX)
  local azimuth = rad(rng.uniform(-AZIMUTH_MAX, AZIMUTH_MAX))
  local yaw = rng.uniform(-pi, pi)
  local dz = HALF - cam.height
  if r * r <= dz * dz then return nil end
  local d = sqrt(r * r - dz * dz)
  local b = new_block(d * cos(azimuth), d * sin(azimuth), HALF, yaw, "scattered")
  local u, v, depth = project(cam, b.x, b.y, b.z)
  if not (depth > 0 and u >= 0 and u <= CAMERA.width - 1 and v >= 0
      and v <= CAMERA.height - 1) then
    return nil
  end
  return b
end

local function adjacent(rng, blocks)
  local ground = {}
  for _, b in ipairs(blocks) do
    if b.level == 0 then ground[#ground + 1] = b end
  end
  local g = ground[rng.index(#ground)]
  local side = rng.index(4)
  local gap = rng.uniform() < P_TOUCHING and 0 or rng.uniform(0, GAP_MAX)
  local offset = rng.uniform() < P_ALIGNED and 0 or rng.uniform(-OFFSET_MAX, OFFSET_MAX) * BLOCK
  -- the side's outward direction (nx, ny) and the direction along it (-ny, nx)
  local nx, ny = g.ca, g.sa
  if side == 2 then
    nx, ny = -nx, -ny
  elseif side == 3 then
    nx, ny = -ny, nx
  elseif side == 4 then
    nx, ny = ny, -nx
  end
  local step = BLOCK + gap
  local b = new_block(g.x + step * nx - offset * ny, g.y + step * ny + offset * nx, g.z, g.yaw,
    "adjacent")
  b.touching = gap == 0
  return b
end

local function stacked(rng, blocks)
  local free = {}
  for _, b in ipairs(blocks) do
    if b.level == 0 and not b.covered then free[#free + 1] = b end
  end
  if #free == 0 then return nil end
  local g = free[rng.index(#free)]
  local yaw = g.yaw + rad(rng.uniform(-STACK_YAW, STACK_YAW))
  local dx = rng.uniform(-STACK_OFFSET, STACK_OFFSET)
  local dy = rng.uniform(-STACK_OFFSET, STACK_OFFSET)
  local b = new_block(g.x + dx, g.y + dy, g.z + BLOCK, yaw, "stacked")
  b.base = g
  return b
end

-- a new block for the scene, or nil when a try fails
local function try_block(rng, cam, blocks)
  local b
  if #blocks == 0 then
    b = scattered(rng, cam)
  else
    local p = rng.uniform()
    if p < P_ADJACENT then
      b = adjacent(rng, blocks)
    elseif p < P_ADJACENT + P_STACKED then
      b = stacked(rng, blocks)
    else
      b = scattered(rng, cam)
    end
  end
  if not b then return nil end
  local r = range(cam, b)
  if r < RANGE_MIN or r > RANGE_MAX then return nil end
  for _, other in ipairs(blocks) do
    if overlap(b, other) then return nil end
  end
  return b
end

local function draw_scene(rng)
  local cam = new_camera(rng.uniform(HEIGHT_MIN, HEIGHT_MAX),
    rad(rng.uniform(PITCH_MIN, PITCH_MAX)), rad(rng.uniform(-ROLL_MAX, ROLL_MAX)))
  local blocks = {}
  for _ = 1, rng.index(MAX_BLOCKS) do
    for _ = 1, TRIES do
      local b = try_block(rng, cam, blocks)
      if b then
        local yaw = rot_z(b.yaw)
        if rng.uniform() < P_TIPPED then
          b.tipped = true
          b.rot = mat_mul(yaw, TIPS[rng.index(#TIPS)])
        else
          b.rot = yaw
        end
        if b.base then b.base.covered = true end
        blocks[#blocks + 1] = b
        break
      end
    end
  end
  return cam, blocks
end

---------------------------------------------------------------------------------------------
-- Visibility (meta.json "visibility"): the listed tags of a scene, in block then face order,
-- each { block = index into blocks, face = 0..5, r = tag -> camera rotation, t, px = the
-- corners' exact pixels {u1, v1, ..., u4, v4}, edge = shortest edge in px }.

local function is_occluded(cam, blocks, self, rtag, tx, ty, tz)
  for i = 0, GRID - 1 do
    for j = 0, GRID - 1 do
      local gx = TAG * (i / (GRID - 1) - 0.5)
      local gy = TAG * (j / (GRID - 1) - 0.5)
      local px, py, pz = mat_vec(rtag, gx, gy, 0)
      px, py, pz = px + tx, py + ty, pz + tz
      for _, other in ipairs(blocks) do
        if other ~= self and segment_hits(other, 0, 0, cam.height, px, py, pz) then
          return true
        end
      end
    end
  end
  return false
end

local function visible_tags(cam, blocks, stats)
  local tags = {}
  local umax, vmax = CAMERA.width - 1 - MARGIN, CAMERA.height - 1 - MARGIN
  for k, b in ipairs(blocks) do
    for f, face in ipairs(FACES) do
      local nx, ny, nz = mat_vec(b.rot, unpack(face.n))
      local tx, ty, tz = b.x + HALF * nx, b.y + HALF * ny, b.z + HALF * nz -- tag centre
      local rx, ry, rz = tx, ty, tz - cam.height
      local cosine = (nx * rx + ny * ry + nz * rz) / sqrt(rx * rx + ry * ry + rz * rz)
      if cosine < FACING then
        local rtag = mat_mul(b.rot, face.r) -- tag -> world
        local r = mat_mul(cam.rwc, rtag)    -- tag -> camera
        local px, inside = {}, true
        for c = 1, 4 do
          local x, y = CORNERS[c][1], CORNERS[c][2]
          local wx, wy, wz = mat_vec(rtag, x, y, 0)
          local u, v, depth = project(cam, tx + wx, ty + wy, tz + wz)
          px[2 * c - 1], px[2 * c] = u, v
          if not (depth > 0 and u >= MARGIN and u <= umax and v >= MARGIN and v <= vmax) then
            inside = false
          end
        end
        local edge = math.huge
        for c = 1, 4 do
          local d = c % 4 + 1
          local du, dv = px[2 * d - 1] - px[2 * c - 1], px[2 * d] - px[2 * c]
          edge = min(edge, sqrt(du * du + dv * dv))
        end
        if inside and edge >= MIN_EDGE then
          if is_occluded(cam, blocks, b, rtag, tx, ty, tz) then
            stats.occluded = stats.occluded + 1
          else
            tags[#tags + 1] = { block = k, face = f - 1, r = r, px = px, edge = edge,
              t = { mat_vec(cam.rwc, tx, ty, tz - cam.height) } }
          end
        end
      end
    end
  end
  return tags
end

---------------------------------------------------------------------------------------------
-- Main

local out, frames, seed = arg[1], tonumber(arg[2] or ""), tonumber(arg[3] or "")
local sigma = tonumber(arg[4] or "0.3")
if not (out and frames and seed and sigma) or frames < 1 or frames ~= floor(frames)
    or seed ~= floor(seed) or not (sigma >= 0) or arg[5] then
  io.stderr:write(USAGE .. "\n")
  os.exit(2)
end

-- numbers as %.17g (-0 written as 0)
local function num(x)
  if x == 0 then x = 0 end
  return format("%.17g", x)
end

local rng = new_rng(seed)
local corner_lines = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
local truth_lines = { "frame,block,x,y,z,qw,qx,qy,qz,faces_visible" }
local tag_lines = { "frame,block,face,x,y,z,qw,qx,qy,qz" }
local stats = { occluded = 0, resampled = 0, unseen = 0, blocks = 0, one_face = 0, rows = 0,
  per_frame = { 0, 0, 0, 0 }, faces = { 0, 0, 0 }, how = { scattered = 0, adjacent = 0,
  stacked = 0 }, tipped = 0, touching = 0, edges = {}, ranges = {} }

for frame = 0, frames - 1 do
  local cam, blocks, tags
  repeat
    cam, blocks = draw_scene(rng)
    tags = visible_tags(cam, blocks, stats)
    if #tags == 0 then stats.resampled = stats.resampled + 1 end
  until #tags > 0

  -- number the listed blocks 0.. in placing order
  local faces, number, listed = {}, {}, 0
  for _, tag in ipairs(tags) do faces[tag.block] = (faces[tag.block] or 0) + 1 end
  for k, b in ipairs(blocks) do
    if faces[k] then
      number[k], listed = listed, listed + 1
      local x, y, z = mat_vec(cam.rwc, b.x, b.y, b.z - cam.height)
      local qw, qx, qy, qz = quaternion(mat_mul(cam.rwc, b.rot))
      truth_lines[#truth_lines + 1] = concat({ format("%d,%d", frame, number[k]), num(x), num(y),
        num(z), num(qw), num(qx), num(qy), num(qz), format("%d", faces[k]) }, ",")
      stats.blocks = stats.blocks + 1
      stats.faces[faces[k]] = stats.faces[faces[k]] + 1
      stats.how[b.how] = stats.how[b.how] + 1
      if b.tipped then stats.tipped = stats.tipped + 1 end
      if b.touching then stats.touching = stats.touching + 1 end
      stats.ranges[#stats.ranges + 1] = range(cam, b)
    else
      stats.unseen = stats.unseen + 1
    end
  end
  stats.per_frame[listed] = stats.per_frame[listed] + 1

  -- the rows in random order (Fisher-Yates), then the noise
  for i = #tags, 2, -1 do
    local j = rng.index(i)
    tags[i], tags[j] = tags[j], tags[i]
  end
  for _, tag in ipairs(tags) do
    local cells = { format("%d,0", frame) }
    for i = 1, 8 do
      cells[#cells + 1] = num(tag.px[i] + sigma * rng.normal()) -- drawn even when sigma = 0
    end
    corner_lines[#corner_lines + 1] = concat(cells, ",")
    local qw, qx, qy, qz = quaternion(tag.r)
    tag_lines[#tag_lines + 1] = concat({ format("%d,%d,%d", frame, number[tag.block], tag.face),
      num(tag.t[1]), num(tag.t[2]), num(tag.t[3]), num(qw), num(qx), num(qy), num(qz) }, ",")
    stats.edges[#stats.edges + 1] = tag.edge
  end
  stats.rows = stats.rows + #tags
end

local function write(name, text)
  local f = assert(io.open(out .. "/" .. name, "w"))
  f:write(text)
  f:close()
end

os.execute('mkdir -p "' .. out .. '"')
write("camera.lua", concat({
  format("-- blocks: camera intrinsics, tag size and block size (generated by "
    .. "bench/make_blocks.lua, %d frames, seed %d, sigma %g px)", frames, seed, sigma),
  "return {",
  "  fx = 313.9,",
  "  fy = 313.9,",
  "  cx = 159.5,",
  "  cy = 119.5,",
  "  width = 320,",
  "  height = 240,",
  "  distortion = nil,",
  "  tag_size = 0.024,",
  "  block_size = 0.055,",
  "}", "" }, "\n"))
write("corners.csv", concat(corner_lines, "\n") .. "\n")
write("truth.csv", concat(truth_lines, "\n") .. "\n")
write("truth_tags.csv", concat(tag_lines, "\n") .. "\n")

-- percentiles 0, 5, 50, 95, 100 (linear between order statistics)
local function percentiles(xs)
  table.sort(xs)
  local cells = {}
  for _, p in ipairs({ 0, 0.05, 0.5, 0.95, 1 }) do
    local pos = p * (#xs - 1)
    local lo = floor(pos)
    local hi = min(lo + 1, #xs - 1)
    cells[#cells + 1] = format("%.4g", xs[lo + 1] + (pos - lo) * (xs[hi + 1] - xs[lo + 1]))
  end
  return "[" .. concat(cells, " ") .. "]"
end

local s = stats
io.stderr:write(format("make_blocks: %d frames, %d blocks (%d 1-face, %d 2+-face; faces 1/2/3 "
  .. "%d/%d/%d), %d tag rows; blocks per frame 1/2/3/4 %d/%d/%d/%d; scattered/adjacent/stacked "
  .. "%d/%d/%d, touching %d, tipped %d; edge px %s, range m %s; %d placed blocks unseen, %d faces "
  .. "occluded, %d frames redrawn\n", frames, s.blocks, s.faces[1], s.faces[2] + s.faces[3],
  s.faces[1], s.faces[2], s.faces[3], s.rows, s.per_frame[1], s.per_frame[2], s.per_frame[3],
  s.per_frame[4], s.how.scattered, s.how.adjacent, s.how.stacked, s.touching, s.tipped,
  percentiles(s.edges), percentiles(s.ranges), s.unseen, s.occluded, s.resampled))
