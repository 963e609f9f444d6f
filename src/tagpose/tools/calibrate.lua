--- tagpose-calibrate: calibrate a layout (a hand-glued cube, a board, the tags on a robot) from
-- a corner log the robot recorded, print per tag what is off, and write the calibrated layout.
--
--   tagpose-calibrate LOG.csv (--layout NOMINAL | --cube TAG_SIZE,BLOCK_SIZE)
--     [--camera CAMERA] [--out CALIBRATED.lua|.yaml|.csv] [--bundle NAME] [--unit NAME]
--     [--order apriltag|opencv] [--reference ID] [--gauge planes|corners] [--robust K]
--     [--max-iterations N]
--
-- (`--help` says each option with its default: the options are the table `SPEC`, read by
-- `tagpose.tools.command`.)
--
-- LOG.csv      a corner log (frame,tag,u1,v1,...,u4,v4; rows of one frame are one image)
-- --layout     the nominal layout: a Lua layout file (.lua, read as data), an apriltag_ros
--              tags.yaml (.yaml, .yml; --bundle names the bundle when it has several) or a CSV
--              table id,size,x,y,z,qw,qx,qy,qz (.csv)
-- --cube       instead: a cube of side BLOCK_SIZE with tags 0-5 of side TAG_SIZE centred on
--              its faces +x, -x, +y, -y, +z, -z (tagpose.layout.cube); each size with an
--              optional unit (22.9mm,54.8mm); sizes without one that read as metres a tag
--              more than 1 m wide are refused (millimetres without their unit)
-- --camera     a camera file (tagpose.calibration): a Lua camera file, ROS camera_calibration
--              or CameraInfo YAML, OpenCV FileStorage YAML, XML or JSON, or a Kalibr camchain
--              (its cam0); default camera.lua beside LOG.csv
-- --out        write the calibrated layout, in the format its extension names
-- --unit       the unit of the layout's lengths (default --cube's unit, else m; a --cube in
--              another unit converted to it): corrections are printed in mm for m, cm and
--              mm, else in the unit
-- --order      opencv: the log's corners in OpenCV's and ArUco's order (top-left first)
-- --reference, --gauge, --robust, --max-iterations: tagpose.layout.calibrate's options
--              (--reference a tag of the layout, --robust at least 1)
--
-- --out may not be an input (the log, the camera file, the nominal layout) under any name
-- (`tagpose.tools.files`); it is checked and opened before the log is read, and written whole
-- (`tagpose.formats.output`: a device, a FIFO or a pipe written through, in place). Exit
-- status: 0 calibrated, 1 a file could not be read or written (standard output included) or
-- the log cannot calibrate the layout, 2 a usage error or an --out that is an input; a pipe
-- closed by its reader ends the command by SIGPIPE (Lua cannot ignore it).
-- @module tagpose.tools.calibrate

local tagpose = require("tagpose")
local tag_id = require("tagpose.tools.tag_id")
local log = require("tagpose.tools.log")
local files = require("tagpose.tools.files")
local frame = require("tagpose.tools.command")

local deg, abs = math.deg, math.abs
local id_text = tag_id.text

local M = {}

local USAGE = "usage: tagpose-calibrate LOG.csv (--layout NOMINAL | --cube TAG_SIZE,BLOCK_SIZE)\n"
  .. "  [--camera CAMERA] [--out CALIBRATED.lua|.yaml|.csv] [--bundle NAME] [--unit NAME]\n"
  .. "  [--order apriltag|opencv] [--reference ID] [--gauge planes|corners] [--robust K]\n"
  .. "  [--max-iterations N]\n"

local SPEC = {
  about = "Calibrate a layout (a glued cube, a board, the tags on a robot) from a corner log:"
    .. " print per tag what is off its nominal place, and write the calibrated layout.",
  arguments = {
    { name = "LOG.csv", key = "log", what = "corner log", help = "the corner log"
      .. " (frame,tag,u1,v1,...,u4,v4; the rows of one frame are one image)" },
  },
  options = {
    { name = "--layout", kind = "string", meta = "NOMINAL", help = "the nominal layout: a Lua"
      .. " layout file, an apriltag_ros tags.yaml or a CSV table id,size,x,y,z,qw,qx,qy,qz" },
    { name = "--cube", kind = "sizes", count = 2, meta = "TAG_SIZE,BLOCK_SIZE",
      what = "TAG_SIZE,BLOCK_SIZE (0 < TAG_SIZE < BLOCK_SIZE, each with an optional unit m,"
        .. " cm, mm, in, ft)",
      check = function(xs)
        if not (xs[1] < xs[2]) then
          return "TAG_SIZE,BLOCK_SIZE (0 < TAG_SIZE < BLOCK_SIZE) expected"
        end
      end,
      help = "instead of --layout: a cube of side BLOCK_SIZE with tags 0-5 of side TAG_SIZE"
        .. " centred on its faces +x, -x, +y, -y, +z, -z (22.9mm,54.8mm)" },
    { name = "--camera", kind = "string", meta = "CAMERA", default_text = "camera.lua beside"
      .. " LOG.csv", help = "the camera file: a Lua camera file, ROS or CameraInfo YAML, OpenCV"
      .. " FileStorage YAML, XML or JSON, a Kalibr camchain (its cam0)" },
    { name = "--out", kind = "string", meta = "CALIBRATED", help = "write the calibrated"
      .. " layout, in the format its extension names (.lua, .yaml, .csv)" },
    { name = "--bundle", kind = "string", meta = "NAME", help = "the bundle of a tags.yaml that"
      .. " has several" },
    { name = "--unit", kind = "string", meta = "NAME", default_text = "--cube's unit, else m",
      help = "the unit of the layout's lengths (a --cube given in another of m, cm, mm, in, ft"
        .. " is converted to it); corrections are printed in mm for m, cm and mm" },
    { name = "--order", kind = "choice", meta = "ORDER", choices = { "apriltag", "opencv" },
      default = "apriltag", help = "the corners' order: apriltag (the detector's c1..c4) or"
        .. " opencv (OpenCV's and ArUco's: top-left, top-right, bottom-right, bottom-left)" },
    { name = "--reference", kind = "integer", meta = "ID", min = -2 ^ 53 + 1, max = 2 ^ 53 - 1,
      what = "tag id (" .. tag_id.ID .. ")", default_text = "the tag seen most",
      help = "the tag held fixed, one of the layout's" },
    { name = "--gauge", kind = "choice", meta = "planes|corners", choices = { "planes",
      "corners" }, default = "planes", help = "how the result is moved onto the nominal"
      .. " layout: by the tags' planes or by their corners" },
    { name = "--robust", kind = "number", meta = "K", min = 1, max = 1e100, what = "a number of"
      .. " at least 1 (below it most detections weigh as outliers)", default = 3,
      help = "the robust loss's scale, in corner noise deviations: a detection of RMS residual"
        .. " K times the noise weighs half" },
    { name = "--max-iterations", kind = "integer", meta = "N", default = 100,
      help = "the bound on the iterations of the adjustment" },
  },
}

local cmd = frame.new("calibrate", USAGE, SPEC)
local usage, fail, refuse = cmd.usage, cmd.fail, cmd.refuse

local MM = { m = 1000, cm = 10, mm = 1 }

-- The command line into a table, and tagpose.layout.calibrate's options.
local function parse(argv)
  local opt = cmd.parse(argv)
  if not opt.layout and not opt.cube then usage("give the nominal layout: --layout or --cube") end
  if opt.layout and opt.cube then usage("--layout and --cube: give one") end
  if opt.cube then
    local unit = opt.cube_unit
    if unit and opt.unit and opt.unit ~= unit then
      if not frame.UNITS[opt.unit] then
        usage(("--unit %s: --cube is in %s; --unit converts it to one of m, cm, mm, in, ft")
          :format(opt.unit, unit))
      end
      opt.cube = { frame.convert(opt.cube[1], unit, opt.unit),
        frame.convert(opt.cube[2], unit, opt.unit) }
    end
    opt.unit = opt.unit or unit
    local bare = not opt.unit and frame.bare_metres("--cube", opt.given.cube, opt.cube[1])
    if bare then usage(bare .. ", or --unit") end
  end
  opt.unit = opt.unit or "m"
  local options = { reference = opt.reference, order = opt.order,
    gauge = opt.given.gauge and opt.gauge or nil,
    robust = opt.given.robust and opt.robust or nil,
    max_iterations = opt.given.max_iterations and opt.max_iterations or nil }
  return opt, options
end

-- "+x", "-y+z", ...: the body axes a shift is mostly along
local function towards(s)
  local parts = { { abs(s.x), s.x < 0 and "-x" or "+x" }, { abs(s.y), s.y < 0 and "-y" or "+y" },
    { abs(s.z), s.z < 0 and "-z" or "+z" } }
  table.sort(parts, function(a, b) return a[1] > b[1] end)
  local text = parts[1][2]
  for k = 2, 3 do
    if parts[k][1] >= 0.4 * parts[1][1] then text = text .. parts[k][2] end
  end
  return text
end

-- The corner log (`file`, opened from `path`, closed here) read into frames of detections
-- `{id =, corners =}` (rows of one frame number, in the order the numbers first come), keeping
-- nothing else of a row; the number of rows, and the malformed rows (the first 10 kept, with
-- their count).
local function read_frames(path, file)
  local reader, err = log.corner_reader(file)
  if not reader then fail(err:find(path, 1, true) and err or path .. ": " .. err) end
  local frames, index, nrows, problems = {}, {}, 0, { n = 0 }
  while true do
    local det, line, reason = reader:read()
    if det == nil then break end
    if det then
      nrows = nrows + 1
      local k = index[det.frame]
      if not k then
        k = #frames + 1
        index[det.frame] = k
        frames[k] = {}
      end
      local f = frames[k]
      f[#f + 1] = { id = det.tag, corners = det.corners }
    else
      problems.n = problems.n + 1
      if #problems < 10 then problems[#problems + 1] = { line = line, reason = reason } end
    end
  end
  reader:close()
  file:close()
  return frames, nrows, problems
end

-- The per-tag lines of a report.
local function tag_lines(say, report, scale, unit)
  local ids = {}
  for id in pairs(report.tags) do ids[#ids + 1] = id end
  table.sort(ids)
  for _, id in ipairs(ids) do
    local t = report.tags[id]
    say("tag %s: %.2f %s towards %s, turned %.2f deg (in its plane %.2f %s, %+.2f deg; off it"
      .. " %+.2f %s, tilted %.2f deg); %d detections%s, rms %.3f px", id_text(id),
      scale * t.distance, unit, towards(t.shift), deg(t.angle), scale * t.in_plane, unit,
      deg(t.turn), scale * t.normal, unit, deg(t.tilt), t.observations,
      t.outliers > 0 and (" (" .. t.outliers .. " outliers)") or "", t.rms)
  end
  for _, u in ipairs(report.unplaced) do
    say("tag %s: not placed, %s (kept at its nominal pose)", id_text(u.id), u.reason)
  end
end

-- The calibrated layout's file, opened before anything is read (its name refused when it is
-- one of the inputs, its format and its directory checked): nil without --out.
local function open_output(opt, camera_path, open)
  if not opt.out then return nil end
  local clash = files.clash({ { name = "the corner log", path = opt.log },
    { name = "the camera file", path = camera_path },
    { name = "the nominal layout", path = opt.layout } },
    { { name = "the calibrated layout (--out)", path = opt.out } })
  if clash then refuse(clash) end
  local _, why = tagpose.layout.encode(opt.out, { tags = {} })
  if why then usage("--out: " .. why:gsub("^layout: ", "")) end
  return cmd.output(open, opt.out, "the calibrated layout (--out)")
end

local function run(argv, open)
  local opt, options = parse(argv)
  -- the log first: a log that cannot be read is named as such, not as a missing camera file
  local log_file, camera_path = cmd.inputs(opt, "no camera file %s; give --camera")
  local out_file = open_output(opt, camera_path, open)
  local out = io.stdout
  local function say(fmt, ...)
    local ok, err = out:write(fmt:format(...), "\n")
    if not ok then fail("standard output: " .. tostring(err)) end
  end
  -- the camera and the nominal layout
  local camera, cerr = tagpose.calibration.read(camera_path)
  if not camera then fail(cerr) end
  local nominal, lerr
  if opt.cube then
    nominal = tagpose.layout.cube(opt.cube[1], opt.cube[2])
  else
    nominal, lerr = tagpose.layout.read(opt.layout, opt.bundle)
    if not nominal then fail(lerr) end
  end
  -- the log
  if options.reference and not nominal.tags[options.reference] then
    local ids = {}
    for id in pairs(nominal.tags) do ids[#ids + 1] = id end
    table.sort(ids)
    for i, id in ipairs(ids) do ids[i] = id_text(id) end
    usage(("--reference %s: no tag %s in the layout (its tags: %s)"):format(
      id_text(options.reference), id_text(options.reference), table.concat(ids, ", ", 1,
      math.min(#ids, 20)) .. (#ids > 20 and ", ..." or "")))
  end
  local frames, nrows, problems = read_frames(opt.log, log_file)
  local ok, layout, report = pcall(tagpose.layout.calibrate, frames, camera, nominal, options)
  if not ok then fail(tostring(layout)) end
  if not layout then
    fail(frame.order_hint(report))
  end
  local unit = opt.unit
  local scale, shown = MM[unit] or 1, MM[unit] and "mm" or unit
  say("calibrate %s: %d rows in %d frames%s", opt.log, nrows, #frames,
    problems.n > 0 and (", " .. problems.n .. " malformed rows skipped") or "")
  for k = 1, #problems do
    say("  line %d: %s", problems[k].line, problems[k].reason)
  end
  local f = report.frames
  say("frames: %d used (two or more tags of the layout), %d with one tag, %d with none, %d not"
    .. " solved, %d apart from the reference's tags", f.used, f.single, f.unknown, f.failed,
    f.elsewhere)
  tag_lines(say, report, scale, shown)
  local d = report.detections
  say("residual rms %.3f px (nominal layout %.3f px), corner noise %.3f px; %d outliers of %d"
    .. " detections", report.rms, report.rms_start, report.sigma, d.outliers, d.used)
  say("gauge: tag %s held fixed, the result moved onto the nominal layout by %.3f %s (rms over"
    .. " the corners); %d iterations in %d stages%s", id_text(report.reference),
    report.reference and scale * report.alignment or 0, shown, report.iterations, report.stages,
    report.converged and "" or " (stopped at --max-iterations)")
  if out_file then
    local text, why = tagpose.layout.encode(opt.out, layout)
    if not text then fail(why) end
    out_file:write(text)
    local committed, werr = out_file:commit()
    if not committed then fail(werr) end
    say("wrote %s", opt.out)
  end
  return 0
end

--- Run the command on its arguments (`arg` of the script).
-- @tparam {string,...} argv the command-line arguments
-- @treturn int the exit status: 0 calibrated, 1 a file could not be read or written (standard
--   output included) or the log cannot calibrate the layout, 2 a usage error (an --out that is
--   one of the inputs included)
function M.main(argv)
  return cmd.main(run, argv)
end

return M
