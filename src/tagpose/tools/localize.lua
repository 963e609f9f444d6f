--- tagpose-localize: replay a robot's log (corners of several cameras, odometry, gyro) through
-- `tagpose.localizer` and write where the robot was at every camera frame.
--
--   tagpose-localize CORNERS.csv --map MAP --cameras CAMERAS.lua [--odometry ODOMETRY.csv]
--     [--gyro GYRO.csv] [--single] [--tag-size S[UNIT]] [--mount-position-sigma S]
--     [--mount-angle-sigma A] [--map-sigma S] [--map-check CHECK.csv] [--svg PLOT.svg]
--     --out POSES.csv
--
-- CORNERS.csv  time,camera,tag,u1,v1,u2,v2,u3,v3,u4,v4 (rows of one time and camera are one
--              frame; corners in the detector's order, pixels; times in seconds)
-- --map        the map: a WPILib field JSON (its tag size from --tag-size or CAMERAS.lua's
--              `tag_size`), or any layout file `tagpose.layout.read` takes
-- --cameras    a Lua data file `return {NAME = {fx, fy, cx, cy, ..., mount = {position =,
--              quaternion =}}, ..., tag_size = S}` (read as data, never run); mount = camera →
--              robot (ROS robot frame: x forward, y left, z up, origin on the floor), metres
-- --odometry   time,x,y,yaw: the robot's dead-reckoned pose (any frame; need not be reset)
-- --gyro       time,yaw: the gyro's heading, radians (any offset: it is learnt from the tags)
-- --max-gap    the longest gap allowed between two odometry or two gyro rows (default 1 s)
-- --single     each frame that saw a map tag alone, with the gyro and the floor as priors
--              (no odometry; the gyro's offset learnt from the frames before it)
-- --mount-position-sigma, --mount-angle-sigma, --map-sigma  how far the mounts and the map's
--              tags may be from where the files put them (the localizer's options of those
--              names: 1cm, 0.5deg, 1cm by default), each with its unit, or 0 when known exactly
-- --map-check  where each map tag was seen against where the map puts it (the localizer's
--              `map_check`): tag,dx,dy,dz,distance,frames (field frame, m), largest first
-- --svg        the field from above (`tagpose.tools.localize_plot`): the map's tags, the
--              estimated path with its 95 % position ellipses every 0.5 s, the odometry (not
--              with --single) moved onto the path by the rigid motion that best fits it, each
--              tag rejected marked with the rows that rejected it and the rows that saw it
-- --out        time,camera,x,y,z,qw,qx,qy,qz,sx,sy,syaw,c11..c66,tags,rejected: one row per
--              camera frame (the fused mode: every frame once the robot is placed; --single:
--              every frame answered), the robot → field pose, σ of x, y and yaw, the 6×6
--              covariance (x, y, z, then a small rotation in the field frame), the tags used
--              and those rejected (space-separated ids)
--
-- The inputs are read whole and merged in time order (at one time: odometry, gyro, then the
-- frames), so each row is the estimate at its frame's time from the data stamped up to it.
-- Exit status: 0 written, 1 a file cannot be read or written, or has a bad row (its file and
-- line named), 2 a usage error or an output (--out, --map-check, --svg) that is an input or
-- another output. Nothing is written partially.
-- @module tagpose.tools.localize

local tagpose = require("tagpose")
local compat = require("tagpose.core.compat")
local output = require("tagpose.formats.output")
local luadata = require("tagpose.formats.luadata")
local csv = require("tagpose.tools.csv")
local files = require("tagpose.tools.files")
local command = require("tagpose.tools.command")
local localize_plot = require("tagpose.tools.localize_plot")

local format, concat = string.format, table.concat
local decimal = compat.decimal

local USAGE = "usage: tagpose-localize CORNERS.csv --map MAP --cameras CAMERAS.lua\n"
  .. "  [--odometry ODOMETRY.csv] [--gyro GYRO.csv] [--single] [--tag-size S[UNIT]]\n"
  .. "  [--max-gap S] [--mount-position-sigma S] [--mount-angle-sigma A] [--map-sigma S]\n"
  .. "  [--map-check CHECK.csv] [--svg PLOT.svg] --out POSES.csv\n"

local SPEC = {
  about = "Replay a robot's log (corners of several cameras, odometry, gyro) through"
    .. " tagpose.localizer and write where the robot was at every camera frame.",
  arguments = {
    { name = "CORNERS.csv", key = "corners", what = "corner log", help = "time,camera,tag,"
      .. "u1,v1,...,u4,v4 (the rows of one time and camera are one frame; times in seconds)" },
  },
  options = {
    { name = "--map", kind = "string", meta = "MAP", help = "the map: a WPILib field JSON, or"
      .. " any layout file tagpose.layout.read takes (required)" },
    { name = "--cameras", kind = "string", meta = "CAMERAS.lua", help = "the cameras, a Lua"
      .. " data file {NAME = {fx, fy, cx, cy, ..., mount = {position =, quaternion =}}, ...,"
      .. " tag_size = S} (required)" },
    { name = "--odometry", kind = "string", meta = "ODOMETRY.csv", help = "time,x,y,yaw: the"
      .. " robot's dead-reckoned pose" },
    { name = "--gyro", kind = "string", meta = "GYRO.csv", help = "time,yaw: the gyro's"
      .. " heading, radians (any offset)" },
    { name = "--max-gap", kind = "number", meta = "S", default_text = "1", help = "the"
      .. " longest gap allowed between two odometry or two gyro rows, in seconds (a sensor"
      .. " that stopped)" },
    { name = "--single", kind = "flag", help = "each frame alone, with the gyro and the floor"
      .. " as priors (no odometry)" },
    { name = "--tag-size", kind = "size", meta = "S[UNIT]", default_text = "CAMERAS.lua's"
      .. " tag_size", help = "the side of the map's tags, with an optional unit (m, cm, mm,"
      .. " in, ft; without one, metres)" },
    { name = "--mount-position-sigma", kind = "length", meta = "S", default_text = "1cm",
      help = "how far each camera's mount may be from where CAMERAS.lua puts it, a length with"
      .. " its unit (0 for mounts known exactly)" },
    { name = "--mount-angle-sigma", kind = "angle", meta = "A", default_text = "0.5deg",
      help = "how far each mount may be turned, an angle with its unit (deg, rad; 0 for none)" },
    { name = "--map-sigma", kind = "length", meta = "S", default_text = "1cm", help = "how far"
      .. " each tag may be from where the map puts it, a length with its unit (0 for none)" },
    { name = "--map-check", kind = "string", meta = "CHECK.csv", help = "write where each map"
      .. " tag was seen against where the map puts it" },
    { name = "--svg", kind = "string", meta = "PLOT.svg", help = "draw the field from above:"
      .. " the map's tags, the path with its 95 % ellipses, the odometry" },
    { name = "--out", kind = "string", meta = "POSES.csv", help = "write the robot's pose at"
      .. " every camera frame (required)" },
  },
}

local cmd = command.new("localize", USAGE, SPEC)
local usage, fail, refuse = cmd.usage, cmd.fail, cmd.refuse

local M = {}

local MAX_RECORD, MAX_COLUMNS = 4096, 64
local MAX_GAP = 1 -- s between two odometry or gyro rows, unless --max-gap says otherwise
local MAX_CAMERAS_BYTES = 1048576

local function parse(argv)
  local opt = cmd.parse(argv)
  if not opt.map then usage("give the map: --map MAP") end
  if not opt.cameras then usage("give the cameras: --cameras CAMERAS.lua") end
  if not opt.out then usage("give the output: --out POSES.csv") end
  if opt.tag_size then
    -- the map is in metres: a size with its unit converted, one without read as metres
    if opt.tag_size_unit then
      opt.tag_size = command.convert(opt.tag_size, opt.tag_size_unit, "m")
    else
      local bare = command.bare_metres("--tag-size", opt.given.tag_size, opt.tag_size)
      if bare then usage(bare) end
    end
  end
  return opt
end

-- Every row of a CSV file with the named columns, as numbers (`text` columns kept as strings),
-- each with its line; a row that is not is a failure naming the file and line.
local function read_table(path, columns, text)
  local reader, err = csv.reader(path, columns, MAX_RECORD, MAX_COLUMNS)
  if not reader then fail(path .. ": " .. err) end
  local rows = {}
  local index = {}
  for i, c in ipairs(columns) do index[i] = reader.column[c] end
  while true do
    local fields, line, reason = reader:read()
    if fields == nil then break end
    if not fields then
      reader:close()
      fail(format("%s:%d: %s", path, line, reason))
    end
    local row = { line = line }
    for i, c in ipairs(columns) do
      local v = fields[index[i]]
      if text and text[c] then
        row[i] = v
      else
        local n = decimal(v)
        if not (n and n - n == 0) then
          reader:close()
          fail(format("%s:%d: %s: a finite number expected, got %q", path, line, c, v))
        end
        row[i] = n
      end
    end
    rows[#rows + 1] = row
  end
  reader:close()
  return rows
end

-- Rows in time order, or a failure at the first that goes back; with `gap`, at the first more
-- than `gap` seconds after the row before (a sensor that stopped: its steps would be one long
-- one, or none).
local function in_order(path, rows, gap)
  for i = 2, #rows do
    if rows[i][1] < rows[i - 1][1] then
      fail(format("%s:%d: time %s goes back (the row before: %s)", path, rows[i].line,
        tostring(rows[i][1]), tostring(rows[i - 1][1])))
    end
    if gap and rows[i][1] - rows[i - 1][1] > gap then
      fail(format("%s:%d: a gap of %.3g s after time %s (more than --max-gap %g s)", path,
        rows[i].line, rows[i][1] - rows[i - 1][1], tostring(rows[i - 1][1]), gap))
    end
  end
  return rows
end

local CORNER_COLUMNS = { "time", "camera", "tag", "u1", "v1", "u2", "v2", "u3", "v3", "u4", "v4" }

-- The frames of the corner log: `{t =, camera =, detections = {...}}` in time order.
local function read_frames(path, cameras)
  local rows = in_order(path, read_table(path, CORNER_COLUMNS, { camera = true }))
  local frames, last = {}, nil
  for _, r in ipairs(rows) do
    if not cameras[r[2]] then
      fail(format("%s:%d: camera %q is not in the cameras file", path, r.line, r[2]))
    end
    if not (last and last.t == r[1] and last.camera == r[2]) then
      last = { t = r[1], camera = r[2], detections = {}, line = r.line }
      frames[#frames + 1] = last
    end
    local d = last.detections
    d[#d + 1] = { id = r[3], corners = { { r[4], r[5] }, { r[6], r[7] }, { r[8], r[9] },
      { r[10], r[11] } } }
  end
  return frames
end

local function read_cameras(path)
  local text, err = output.read_text(path, MAX_CAMERAS_BYTES, "a cameras file")
  if not text then fail(err) end
  local data, derr = luadata.decode(text, path)
  if not data then fail(tostring(derr)) end
  if type(data) ~= "table" then fail(path .. ": a table of cameras expected") end
  return data
end

local function row_text(fr, res)
  local p, q, s = res.position, res.quaternion, res.sigma
  local parts = { format("%.6f,%s,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f,%.9f,%.6g,%.6g,%.6g", fr.t,
    fr.camera, p.x, p.y, p.z, q.w, q.x, q.y, q.z, s.x, s.y, s.yaw) }
  local C = res.covariance
  for i = 1, 6 do
    for j = 1, 6 do parts[#parts + 1] = format("%.6g", C[i][j]) end
  end
  local used, rej = {}, {}
  for _, id in ipairs(res.tags) do used[#used + 1] = format("%d", id) end
  for _, r in ipairs(res.rejected) do rej[#rej + 1] = format("%d", r.id) end
  parts[#parts + 1] = concat(used, " ")
  parts[#parts + 1] = concat(rej, " ")
  return concat(parts, ",")
end

-- What the plot reads of a result (see `tagpose.tools.localize_plot`).
local function plot_row(t, res)
  local p, C = res.position, res.covariance
  return { time = t, position = { x = p.x, y = p.y }, yaw = res.yaw,
    covariance = { { C[1][1], C[1][2] }, { C[2][1], C[2][2] } }, tags = res.tags,
    rejected = res.rejected[1] and res.rejected or nil }
end

local function header()
  local h = { "time,camera,x,y,z,qw,qx,qy,qz,sx,sy,syaw" }
  for i = 1, 6 do
    for j = 1, 6 do h[#h + 1] = format("c%d%d", i, j) end
  end
  h[#h + 1] = "tags,rejected"
  return concat(h, ",")
end

local function run(argv, open)
  local opt = parse(argv)
  local inputs = { { name = "the corner log", path = opt.corners },
    { name = "the map", path = opt.map }, { name = "the cameras file", path = opt.cameras },
    { name = "the odometry", path = opt.odometry }, { name = "the gyro log", path = opt.gyro } }
  local outputs = { { name = "the poses (--out)", path = opt.out },
    { name = "the map check (--map-check)", path = opt.map_check },
    { name = "the plot (--svg)", path = opt.svg } }
  local clash = files.clash(inputs, outputs)
  if clash then refuse(clash) end
  local out = cmd.output(open, opt.out, "the poses (--out)")
  local check = opt.map_check and cmd.output(open, opt.map_check, "the map check (--map-check)")
  local plot = opt.svg and cmd.output(open, opt.svg, "the plot (--svg)")
  local cameras = read_cameras(opt.cameras)
  local size = opt.tag_size or cameras.tag_size
  local map, merr = tagpose.layout.read(opt.map, size and { size = size } or nil)
  if not map then fail(merr) end
  local ok, loc = pcall(tagpose.localizer.new, map, cameras,
    { mode = opt.single and "single" or "fused", map_check = opt.map_check ~= nil,
      mount_position_sigma = opt.mount_position_sigma, mount_angle_sigma = opt.mount_angle_sigma,
      map_sigma = opt.map_sigma })
  if not ok then fail(opt.cameras .. ": " .. tostring(loc):gsub("^bad argument #%d to 'new' %(",
    ""):gsub("%)$", "")) end
  local frames = read_frames(opt.corners, loc.cameras)
  local odo = opt.odometry and not opt.single
    and in_order(opt.odometry, read_table(opt.odometry, { "time", "x", "y", "yaw" }),
      opt.max_gap or MAX_GAP) or {}
  local gyro = opt.gyro and in_order(opt.gyro, read_table(opt.gyro, { "time", "yaw" }),
    opt.max_gap or MAX_GAP) or {}
  -- merged in time order: at one time the odometry, the gyro, then the frames
  local i, j = 1, 1
  out:write(header(), "\n")
  local rows = 0
  local kept = opt.svg and {} or nil -- the rows the plot needs, only what it reads
  for _, fr in ipairs(frames) do
    while true do
      local to, tg = odo[i] and odo[i][1], gyro[j] and gyro[j][1]
      if to and to <= fr.t and (not tg or to <= tg) then
        loc:odometry(to, odo[i][2], odo[i][3], odo[i][4])
        i = i + 1
      elseif tg and tg <= fr.t then
        loc:gyro(tg, gyro[j][2])
        j = j + 1
      else
        break
      end
    end
    local res = loc:update(fr.camera, fr.detections, fr.t)
    if res and res.position then
      out:write(row_text(fr, res), "\n")
      rows = rows + 1
      if kept then kept[#kept + 1] = plot_row(fr.t, res) end
    end
  end
  if check then
    check:write("tag,dx,dy,dz,distance,frames\n")
    for _, r in ipairs(loc:map_check()) do
      check:write(format("%d,%.4f,%.4f,%.4f,%.4f,%d\n", r.id, r.dx, r.dy, r.dz, r.distance,
        r.frames))
    end
    check:commit()
  end
  if plot then
    plot:write((localize_plot.svg(loc.tags, kept, #odo > 0 and odo or nil,
      { title = "tagpose-localize " .. opt.corners })))
    plot:commit()
  end
  out:commit()
  io.stdout:write(format("wrote %s: %d rows from %d camera frames\n", opt.out, rows, #frames))
  return 0
end

--- Run the command.
-- @tparam {string,...} argv
-- @treturn int the exit status
function M.main(argv)
  return cmd.main(run, argv)
end

return M
