--- tagpose-replay: replay a corner log: solve every detection the robot's tag detector logged,
-- write the poses, summarise, and draw the curves.
--
--   tagpose-replay LOG.csv [--camera FILE] [--tag-size S[UNIT]]
--     [--order apriltag|opencv] [--method refined|seed] [--track] [--smooth]
--     [--max-gap T(s|ms)] [--sigma PX] [--fps F] [--out POSES.csv|-] [--svg PLOT.svg]
--     [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]
--
-- (`--help` says each option with its default: the options are the table
-- `tagpose.tools.replay.command.SPEC`, read by `tagpose.tools.command`.)
--
-- LOG.csv      a corner log (header frame,tag,u1,v1,u2,v2,u3,v3,u4,v4, optionally time in
--              seconds; further columns ignored; blank lines and lines starting with #
--              skipped; see tagpose.tools.log)
-- --camera     a calibration file (tagpose.calibration): a Lua camera file (read as data),
--              ROS camera_calibration or CameraInfo YAML, OpenCV FileStorage YAML, XML or
--              JSON, or a Kalibr camchain (its cam0); default: camera.lua beside LOG.csv
-- --tag-size   the side of the tag's black square, optionally with its unit (0.024, 24mm);
--              default: the camera file's tag_size (a number, or {[id] = size, default =
--              size}). Poses come out in its unit, or in --unit's, the size converted to it;
--              tags a median 100 m away or more are pointed out (a size in another unit)
-- --order      apriltag (default) or opencv: the corners in OpenCV's and ArUco's order
-- --method     refined (default) or seed (the report's method exactly)
-- --track      the poses of tagpose.tracker, fed each frame's rows with the frame's time: the
--              same poses as a user's own loop over the tracker
-- --smooth     the tracker's choices revised with the later frames (tracker:smooth(), two
--              passes over the log); implies --track
-- --max-gap    the tracker's max_gap, a time with its unit (0.5s, 500ms; default 0.5 s): a
--              track unseen longer ends; implies --track. A bare number (frames, before) is
--              refused
-- --sigma      the corner noise in px, for the covariance (default: the tracker's running
--              estimate per track; without --track, tagpose.solve's default); 1e-6 to 1e6
-- --fps        frames per second of the frame column, for a log without a time column
--              (default 30; 1e-6 to 1e6)
-- --out        write the pose log (frame,tag,x,y,z,qw,qx,qy,qz,error,iterations, then
--              confidence and the covariance's deviations): one row per readable input row,
--              in input order; a row that failed keeps its frame and tag with empty pose
--              fields. "-" writes it to standard output (the summary then goes to standard
--              error)
-- --svg        draw x, y, z and the quaternion (or with --rpy roll, pitch, yaw in degrees) over
--              frames (over time with a time column), one line per track, with each pose's
--              ±2σ band and its confidence; every --compare log is drawn dashed over it
-- --compare    other pose logs (or truth files frame,tag,x,y,z,qw,qx,qy,qz) to draw and to
--              measure against, matched by frame and tag; several may follow one --compare
--
-- The log is read, solved and written a frame at a time (tagpose.tools.replay.frames): memory
-- holds the rows of one frame, the tracker's live tracks and, for the plot, at most
-- `plot.MAX_POINTS` points per track. Rows that share a (frame, tag) key (lab tags are often
-- all id 0) are kept apart as tracks by the tracker, by image position, with or without
-- --track. A malformed row is reported with its line number and skipped. Times that look like
-- milliseconds or frame numbers, and fractional frame numbers, are pointed out on standard
-- error (tagpose.tools.replay.clock).
--
-- The corner log is opened first: a log that cannot be read is named before anything else.
-- The outputs (--out, --svg) may not be inputs (the log, the camera file, a compared log) or
-- each other, under any name (`tagpose.tools.files`: the file system's device and inode); they
-- are opened before anything is read and written whole (`tagpose.formats.output`: a device, a
-- FIFO or a pipe written through, in place). Exit status: 0 when the log was replayed
-- and a row at least was solved, 1 when no row was (the reason on standard error and in the
-- plot's panels, the pose log and the plot written) or a file cannot be read or written
-- (standard output included), 2 on a usage error or an output that is an input; a pipe
-- closed by its reader ends the command by SIGPIPE (Lua cannot ignore it).
--
-- Its parts: `tagpose.tools.replay.command` (its options, on `tagpose.tools.command`: the
-- ways out, option readers and inputs it shares with tagpose-calibrate),
-- `tagpose.tools.replay.frames` (rows fed to the tracker, written and counted a frame at a
-- time), `tagpose.tools.replay.clock` (the frames' times), `tagpose.tools.replay.slots` (the
-- plot's lines), `tagpose.tools.replay.compare` (the logs compared with),
-- `tagpose.tools.replay.stats` (bounded counts) and `tagpose.tools.replay.summary` (what it
-- says, and the figure).
-- @module tagpose.tools.replay

local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local plot = require("tagpose.tools.plot")
local command = require("tagpose.tools.replay.command")
local frames = require("tagpose.tools.replay.frames")
local clock = require("tagpose.tools.replay.clock")
local compare = require("tagpose.tools.replay.compare")
local summary = require("tagpose.tools.replay.summary")
local files = require("tagpose.tools.files")
local frame = require("tagpose.tools.command")

local usage, fail = command.usage, command.fail

local M = {}

-- refuse an output that is one of the inputs (or another output), before reading anything
local function refuse_clashes(opt, camera_path)
  local inputs = { { name = "the corner log", path = opt.log },
    { name = "the camera file", path = camera_path } }
  for _, path in ipairs(opt.compare) do
    inputs[#inputs + 1] = { name = "the compared log", path = path }
  end
  local outputs = {}
  if opt.out and opt.out ~= "-" then
    outputs[#outputs + 1] = { name = "the pose log (--out)", path = opt.out }
  end
  if opt.svg then outputs[#outputs + 1] = { name = "the plot (--svg)", path = opt.svg } end
  local clash = files.clash(inputs, outputs)
  if clash then command.refuse(clash) end
end

-- sizes (a size, or sizes by id) moved from one unit to another
local function convert_sizes(sizes, from, to)
  if type(sizes) ~= "table" then return frame.convert(sizes, from, to) end
  local out = {}
  for k, v in pairs(sizes) do
    out[k] = type(v) == "number" and frame.convert(v, from, to) or v
  end
  return out
end

-- the camera file, what it says, the tag sizes and the length unit; the replay's tracker
local function load_camera(opt, camera_path)
  local camera, info = tagpose.calibration.read(camera_path)
  if not camera then fail(info) end
  local problem = tagpose.camera.check(camera)
  if problem then fail(camera_path .. ": " .. problem) end
  local sizes = opt.tag_size or info.tag_size
  if sizes == nil then
    usage(camera_path .. " has no tag_size; give --tag-size S")
  end
  -- the unit the sizes are given in; --unit another: the sizes converted to it
  local given = opt.tag_size and opt.tag_size_unit or not opt.tag_size and info.unit or nil
  if opt.unit and given and opt.unit ~= given then
    if not (frame.UNITS[opt.unit] and frame.UNITS[given]) then
      usage(("--unit %s: the tag size is in %s; --unit converts it to one of m, cm, mm, in, ft")
        :format(opt.unit, given))
    end
    sizes = convert_sizes(sizes, given, opt.unit)
  end
  -- (the tracker checks the sizes: a table it cannot use is the camera file's fault)
  local ok, tracker = pcall(frames.tracker, opt, camera, sizes)
  if not ok then
    fail(camera_path .. ": "
      .. tostring(tracker):gsub("^bad argument #%d to 'new' %((.*)%)$", "%1"))
  end
  local unit = opt.unit or given or (opt.tag_size and "tag-size units") or "m"
  return camera, { path = camera_path, info = info, unit = unit }, sizes, tracker
end

-- the outputs, opened before anything is read (a file that cannot be written is found before
-- the replay): the pose log's writer and the plot's file, kept in `open` for `main` to abort
-- (an output committed is not touched by its abort)
local function open_outputs(opt, open)
  local out = { compares = {} }
  if opt.out then
    local werr
    out.writer, werr = log.pose_writer(opt.out == "-" and io.stdout or opt.out)
    if not out.writer then fail("the pose log (--out): " .. werr:gsub("^log: ", "")) end
    open[#open + 1] = out.writer
  end
  if opt.svg then
    out.svg = command.command.output(open, opt.svg, "the plot (--svg)")
  end
  return out
end

-- the corner log's reader, of the log opened (`source`, a file) or of its path
local function open_log(opt, source)
  local reader, rerr = log.corner_reader(source)
  if not reader then fail(rerr:find(opt.log, 1, true) and rerr or opt.log .. ": " .. rerr) end
  return reader
end

-- the corner log, the figure's recorder, the logs to compare with
local function open_inputs(opt, out, log_file)
  local reader = open_log(opt, log_file)
  if opt.svg then
    out.recorder = plot.recorder({ rotation = opt.rpy and "rpy" or "quaternion",
      x = reader.has_time and "time" or "frame" })
    out.main_source = out.recorder:source("tagpose " .. (opt.method or "refined")
      .. (opt.smooth and " smoothed" or opt.track and " tracked" or ""))
  end
  for _, path in ipairs(opt.compare) do
    local c, cerr = compare.open(path, out.recorder, opt.fps)
    if not c then fail(cerr) end
    out.compares[#out.compares + 1] = c
  end
  return reader
end

local function run(arg, open)
  local opt = command.parse(arg)
  -- the log first: a log that cannot be read is named as such, not as a missing camera file
  local log_file, camera_path = command.command.inputs(opt,
    "no camera file: %s does not exist; give --camera FILE")
  refuse_clashes(opt, camera_path)
  local files_out = open_outputs(opt, open)

  -- where the summary goes: stdout, unless the pose log does; a failed write ends the command
  local out = opt.out == "-" and io.stderr or io.stdout
  local function say(fmt, ...)
    local ok, err = out:write(select("#", ...) > 0 and fmt:format(...) or fmt, "\n")
    if not ok then fail((out == io.stdout and "standard output: " or "") .. tostring(err)) end
  end

  local camera, source, sizes, tracker = load_camera(opt, camera_path)
  local reader = open_inputs(opt, files_out, log_file)
  local times = clock.new(opt, reader.has_time, function(text)
    io.stderr:write("replay: warning: ", text, "\n")
  end)
  local smoothed = opt.smooth
    and frames.forward(opt, camera, sizes, open_log(opt, opt.log), times)
  local replay = frames.new(opt, camera, sizes, tracker, files_out, times, smoothed or nil)
  frames.read(replay, reader)
  log_file:close()
  local far = summary.far(replay, source.unit)
  if far then io.stderr:write("replay: warning: ", far, "\n") end
  for _, c in ipairs(files_out.compares) do c:finish() end

  -- the pose log first, so that a summary never claims a file that was not written
  local written = nil
  if files_out.writer then
    local n, werr = files_out.writer:close()
    if not n then
      fail(opt.out == "-" and "standard output: " .. werr:gsub("^log: ", "") or werr)
    end
    written = n
  end

  summary.head(say, replay, source)
  summary.rows(say, replay)
  summary.medians(say, replay)
  summary.comparisons(say, replay, source.unit)
  if written then
    say("wrote %s (%d rows)", opt.out == "-" and "the pose log to standard output" or opt.out,
      written)
  end
  local why = summary.nothing_solved(replay)
  if files_out.recorder then summary.figure(say, replay, source.unit, files_out.svg, why) end
  -- a log of which no row gives a pose is a failure, whatever was written
  if why then fail(why) end
  return 0
end

--- Run the command on its arguments (`arg` of the script).
-- @tparam {string,...} argv the command-line arguments
-- @treturn int the exit status: 0 replayed, 1 no row solved or a file could not be read or
--   written (standard output included), 2 a usage error (an output that is one of the inputs
--   included)
function M.main(argv)
  return command.command.main(run, argv)
end

return M
