-- Robot views of a mapped field, for the field benchmark: a camera on a robot somewhere on the
-- carpet, the tags of a WPILib field map it sees, their corners with pixel noise.
--
--   lua5.4 bench/make_field.lua OUT_DIR SEED [--views N] [--sigma PX] [--camera NAME|W,H,FX]
--     [--size S] [--map PATH]
--   lua5.4 bench/field_solve.lua OUT_DIR            -- tagpose: OUT_DIR/tagpose.csv
--   /usr/bin/python3 bench/field_opencv.py OUT_DIR  -- OpenCV, and both side by side
--   (bench/field.sh OUT_DIR SEED [options] runs the three)
--
-- Writes OUT_DIR/camera.lua, meta.json, corners.csv (frame,tag,u1,v1,...,u4,v4) and truth.csv
-- (frame,tags,x,y,z,qw,qx,qy,qz: the camera → field pose of each view, the camera's frame
-- OpenCV's: x right, y down, z forward).
--
-- The scene (metres, radians unless said; the field frame WPILib's: x along the field from the
-- blue alliance wall, z up):
-- * the map (--map, default bench/field/2024-crescendo.json), every tag of side S (default
--   0.1651, FRC's 6.5 in);
-- * the camera (--camera, default ov9281): ov9281 (1280x800, fx = fy = 910: a global-shutter
--   OV9281 behind a 70° lens, the common FRC coprocessor camera), lifecam (640x480, fx = fy
--   = 700), wide (1280x800, fx = fy = 520), or W,H,FX; principal point at the image's centre
--   moved by up to 2 % of the size, fy = fx·U(0.99, 1.01);
-- * each view: the robot anywhere on the carpet (x in 0.5..length - 0.5, y in 0.5..width
--   - 0.5), the camera U(0.2, 0.8) above the carpet, heading U(-180°, 180°), pitched up
--   U(0°, 30°), rolled N(0, 1°) (mount and carpet);
-- * a tag is seen when its face is towards the camera, its four corners are in the image (1 px
--   inside) and its shortest side is 10 px or more; a view that sees no tag is drawn again;
-- * corners get N(0, SIGMA) px noise per coordinate (default 0.5).
--
-- Self-contained (geometry written here and in bench/field_map.lua; nothing of tagpose) and
-- deterministic: one SEED and options give byte-identical files on Lua 5.1-5.4 and LuaJIT
-- (Park-Miller, %.17g numbers).

local map = dofile((arg[0]:match("^(.*)/[^/]*$") or ".") .. "/field_map.lua")

local sqrt, sin, cos, log, pi, rad = math.sqrt, math.sin, math.cos, math.log, math.pi, math.rad
local format = string.format

local USAGE = "usage: lua bench/make_field.lua OUT_DIR SEED [--views N] [--sigma PX] "
  .. "[--camera ov9281|lifecam|wide|W,H,FX] [--size S] [--map PATH]"

local CAMERAS = {
  ov9281 = { width = 1280, height = 800, fx = 910 },
  lifecam = { width = 640, height = 480, fx = 700 },
  wide = { width = 1280, height = 800, fx = 520 },
}

local MARGIN, MIN_SIDE = 1, 10

-- Park-Miller with the 48271 multiplier (exact in doubles everywhere)
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
    return sqrt(-2 * log(rng.uniform())) * cos(2 * pi * rng.uniform())
  end
  for _ = 1, 10 do rng.uniform() end
  return rng
end

local function parse(argv)
  local o = { views = 300, sigma = 0.5, camera = "ov9281", size = 0.1651,
    map = "bench/field/2024-crescendo.json" }
  o.out, o.seed = argv[1], tonumber(argv[2])
  if not (o.out and o.seed) then error(USAGE, 0) end
  local i = 3
  while argv[i] do
    local key, v = argv[i]:match("^%-%-(.+)$"), argv[i + 1]
    if not key or o[key] == nil or v == nil or key == "out" or key == "seed" then
      error(USAGE, 0)
    end
    o[key] = (key == "camera" or key == "map") and v or tonumber(v)
    if o[key] == nil then error(USAGE, 0) end
    i = i + 2
  end
  return o
end

local function camera_of(o, rng)
  local c = CAMERAS[o.camera]
  if not c then
    local w, h, fx = o.camera:match("^(%d+),(%d+),([%d.]+)$")
    if not w then error(USAGE, 0) end
    c = { width = tonumber(w), height = tonumber(h), fx = tonumber(fx) }
  end
  local fx = c.fx
  return { width = c.width, height = c.height, fx = fx, fy = fx * rng.uniform(0.99, 1.01),
    cx = (c.width - 1) / 2 + rng.uniform(-0.02, 0.02) * c.width,
    cy = (c.height - 1) / 2 + rng.uniform(-0.02, 0.02) * c.height }
end

-- The camera → field rotation (columns: the camera's x right, y down, z forward in the field)
-- of a heading h, pitch up p and roll r about the optical axis.
local function camera_rotation(h, p, r)
  local z = { cos(p) * cos(h), cos(p) * sin(h), sin(p) }
  local x0 = { sin(h), -cos(h), 0 }
  local y0 = { z[2] * x0[3] - z[3] * x0[2], z[3] * x0[1] - z[1] * x0[3],
    z[1] * x0[2] - z[2] * x0[1] }
  local c, s = cos(r), sin(r)
  local x, y = {}, {}
  for i = 1, 3 do
    x[i] = c * x0[i] + s * y0[i]
    y[i] = -s * x0[i] + c * y0[i]
  end
  return { x[1], y[1], z[1], x[2], y[2], z[2], x[3], y[3], z[3] }
end

-- The pixels of a tag's corners (field frame) seen from a camera at c with rotation r, or nil
-- when the tag is not seen.
local function view_tag(tag, size, camera, r, c)
  local nx, ny, nz = map.normal(tag)
  if (c[1] - tag.x) * nx + (c[2] - tag.y) * ny + (c[3] - tag.z) * nz <= 0 then return nil end
  local px = {}
  for k, p in ipairs(map.corners(tag, size)) do
    local dx, dy, dz = p[1] - c[1], p[2] - c[2], p[3] - c[3]
    -- field → camera: Rᵀ (p - c)
    local x = r[1] * dx + r[4] * dy + r[7] * dz
    local y = r[2] * dx + r[5] * dy + r[8] * dz
    local z = r[3] * dx + r[6] * dy + r[9] * dz
    if z < 0.05 then return nil end
    local u, v = camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy
    if u < MARGIN or v < MARGIN or u > camera.width - 1 - MARGIN
      or v > camera.height - 1 - MARGIN then
      return nil
    end
    px[2 * k - 1], px[2 * k] = u, v
  end
  for k = 1, 4 do
    local j = k % 4 + 1
    local du, dv = px[2 * j - 1] - px[2 * k - 1], px[2 * j] - px[2 * k]
    if sqrt(du * du + dv * dv) < MIN_SIDE then return nil end
  end
  return px
end

local function main(argv)
  local o = parse(argv)
  local rng = new_rng(o.seed)
  local field = map.read(o.map)
  local camera = camera_of(o, rng)
  os.execute("mkdir -p '" .. o.out .. "'")
  local corners = assert(io.open(o.out .. "/corners.csv", "w"))
  local truth = assert(io.open(o.out .. "/truth.csv", "w"))
  corners:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
  truth:write("frame,tags,x,y,z,qw,qx,qy,qz\n")
  local drawn, histogram = 0, {}
  for frame = 0, o.views - 1 do
    local rows
    repeat
      drawn = drawn + 1
      local c = { rng.uniform(0.5, field.length - 0.5), rng.uniform(0.5, field.width - 0.5),
        rng.uniform(0.2, 0.8) }
      local r = camera_rotation(rng.uniform(-pi, pi), rad(rng.uniform(0, 30)), rad(rng.normal()))
      rows = {}
      for _, id in ipairs(field.ids) do
        local px = view_tag(field.tags[id], o.size, camera, r, c)
        if px then
          local line = { frame, id }
          for k = 1, 8 do line[2 + k] = format("%.17g", px[k] + o.sigma * rng.normal()) end
          rows[#rows + 1] = table.concat(line, ",")
        end
      end
      if #rows > 0 then
        local q = map.quaternion(r)
        truth:write(format("%d,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", frame, #rows,
          c[1], c[2], c[3], q.w, q.x, q.y, q.z))
      end
    until #rows > 0
    histogram[#rows] = (histogram[#rows] or 0) + 1
    corners:write(table.concat(rows, "\n"), "\n")
  end
  corners:close()
  truth:close()
  local f = assert(io.open(o.out .. "/camera.lua", "w"))
  f:write(format("-- %s: generated by bench/make_field.lua (seed %d, camera %s)\nreturn {\n"
    .. "  fx = %.17g,\n  fy = %.17g,\n  cx = %.17g,\n  cy = %.17g,\n  width = %d,\n"
    .. "  height = %d,\n  tag_size = %.17g,\n}\n", o.out:match("[^/]*$"), o.seed, o.camera,
    camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height, o.size))
  f:close()
  local counts, most = {}, 0
  for n in pairs(histogram) do
    if n > most then most = n end
  end
  for n = 1, most do counts[n] = format('"%d": %d', n, histogram[n] or 0) end
  f = assert(io.open(o.out .. "/meta.json", "w"))
  f:write(format('{\n  "generator": "bench/make_field.lua",\n  "seed": %d,\n  "map": "%s",\n'
    .. '  "camera": "%s",\n  "views": %d,\n  "drawn": %d,\n  "sigma_px": %.17g,\n'
    .. '  "tag_size": %.17g,\n  "views_by_tags_seen": {%s}\n}\n', o.seed, o.map, o.camera,
    o.views, drawn, o.sigma, o.size, table.concat(counts, ", ")))
  f:close()
  io.write(format("%s: %d views (%d drawn), tags seen per view:", o.out, o.views, drawn))
  for n = 1, #field.ids do
    if histogram[n] then io.write(format(" %d:%d", n, histogram[n])) end
  end
  io.write("\n")
end

local ok, err = pcall(main, arg)
if not ok then
  io.stderr:write(tostring(err), "\n")
  os.exit(2)
end
