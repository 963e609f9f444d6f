--- tagpose-replay's command line: its options, its paths and its ways out.
--
-- The ways out are those of `tagpose.tools.command` (its `EXIT` tables, caught by
-- `tagpose.tools.replay.main`): `usage` (status 2, with the usage), `refuse` (status 2: an
-- output that is an input), `fail` (status 1: a file cannot be read or written), and
-- `--help` (status 0).
-- @module tagpose.tools.replay.command

local frame = require("tagpose.tools.command")

local M = {}

--- The usage line.
M.USAGE = "usage: tagpose-replay LOG.csv [--camera FILE] [--tag-size S[UNIT]]\n"
  .. "  [--order apriltag|opencv] [--method refined|seed] [--track] [--smooth]\n"
  .. "  [--max-gap T(s|ms)] [--sigma PX] [--fps F] [--out POSES.csv|-] [--svg PLOT.svg]\n"
  .. "  [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]\n"

--- Frames per second of the `frame` column when the log has no `time` column (`--fps`).
M.FPS = 30

local USAGE = M.USAGE

--- The corner noise (`--sigma`, px) and the frame rate (`--fps`) are taken within these
-- bounds: beyond them the covariance overflows or the frames' times do.
M.SIGMA = { 1e-6, 1e6 }
M.FPS_RANGE = { 1e-6, 1e6 }

--- The command's arguments and options (`tagpose.tools.command`): `parse` reads them, `--help`
-- prints them.
M.SPEC = {
  about = "Solve every detection of a corner log (one row per tag seen: frame,tag,u1,v1,...,"
    .. "u4,v4, optionally a time column in seconds), write the poses, print a summary and draw"
    .. " the poses over the frames.",
  arguments = {
    { name = "LOG.csv", key = "log", what = "corner log", help = "the corner log (header"
      .. " frame,tag,u1,v1,u2,v2,u3,v3,u4,v4, optionally time; other columns ignored)" },
  },
  options = {
    { name = "--camera", kind = "string", meta = "FILE", default_text = "camera.lua beside"
      .. " LOG.csv", help = "the camera: a Lua camera file, ROS or CameraInfo YAML, OpenCV"
      .. " FileStorage YAML, XML or JSON, a Kalibr camchain (its cam0)" },
    { name = "--tag-size", kind = "size", meta = "S[UNIT]", default_text = "the camera file's"
      .. " tag_size", help = "the side of the tag's black square, with an optional unit (m,"
      .. " cm, mm, in, ft: 0.024m, 24mm); the poses come out in its unit" },
    { name = "--order", kind = "choice", meta = "ORDER", choices = { "apriltag", "opencv" },
      default = "apriltag", help = "the corners' order: apriltag (the detector's c1..c4) or"
      .. " opencv (OpenCV's and ArUco's: top-left, top-right, bottom-right, bottom-left)" },
    { name = "--method", kind = "choice", meta = "METHOD", choices = { "refined", "seed" },
      default = "refined", help = "refined, or seed (the report's method exactly)" },
    { name = "--track", kind = "flag", help = "the poses of tagpose.tracker, fed each frame's"
      .. " rows with the frame's time" },
    { name = "--smooth", kind = "flag", set = { track = true }, help = "the tracker's choices"
      .. " revised with the later frames (two passes); implies --track" },
    { name = "--max-gap", kind = "time", meta = "T(s|ms)", default_text = "0.5s",
      set = { track = true }, bare = "(a bare number counted frames before; the tracker's gap"
      .. " is in seconds: 3 frames at 30 fps are --max-gap 0.1s)",
      help = "a track unseen longer ends; implies --track" },
    { name = "--sigma", kind = "number", meta = "PX", min = M.SIGMA[1], max = M.SIGMA[2],
      default_text = "each track's running estimate with --track, else tagpose.solve's",
      help = "the corner noise in pixels, for the covariance" },
    { name = "--fps", kind = "number", meta = "F", min = M.FPS_RANGE[1], max = M.FPS_RANGE[2],
      default = M.FPS, help = "frames per second of the frame column, for a log without a"
        .. " time column" },
    { name = "--out", kind = "string", meta = "POSES.csv|-", help = "write the pose log, one"
      .. " row per readable input row (\"-\": standard output; the summary then goes to"
      .. " standard error)" },
    { name = "--svg", kind = "string", meta = "PLOT.svg", help = "draw x, y, z and the"
      .. " rotation over frames (over time with a time column), one line per track, with"
      .. " each pose's ±2 sigma band and its confidence" },
    { name = "--rpy", kind = "flag", help = "draw roll, pitch and yaw in degrees instead of the"
      .. " quaternion" },
    { name = "--unit", kind = "string", meta = "NAME", default_text = "the tag size's unit",
      help = "the unit of the poses: a tag size given in another unit (m, cm, mm, in, ft) is"
        .. " converted to it; else only the name on the plot's axes" },
    { name = "--title", kind = "string", meta = "TEXT", default_text = "replay of LOG.csv",
      help = "the plot's title" },
    { name = "--compare", kind = "list", meta = "OTHER.csv ...", help = "pose logs or truth"
      .. " files (frame,tag,x,y,z,qw,qx,qy,qz) to draw dashed and to measure against, matched"
      .. " by frame and tag; several may follow one --compare" },
  },
}

--- The command's frame (`tagpose.tools.command.new`): its ways out, its option readers, its
-- `main`.
M.command = frame.new("replay", USAGE, M.SPEC)

--- The metatable of the ways out.
M.EXIT = frame.EXIT

--- Leave with status 2: a usage error (`msg`, then the usage).
-- @function usage
-- @tparam[opt] string msg
M.usage = M.command.usage

--- Leave with status 2 without the usage: a command line that names one file twice (an
-- output that is one of the inputs).
-- @function refuse
-- @tparam string msg
M.refuse = M.command.refuse

--- Leave with status 1: a file cannot be read or written.
-- @function fail
-- @tparam string msg
M.fail = M.command.fail

--- The options of the command line.
-- @tparam {string,...} arg the arguments
-- @treturn table `{log =, camera =, tag_size =, tag_size_unit =, order =, method =, track =,
--   smooth =, max_gap =, sigma =, fps =, out =, svg =, rpy =, unit =, title =,
--   compare = {path, ...}, given = {[key] = true}}` (`track` set by `--smooth` and `--max-gap`
--   too; `max_gap` in seconds or nil, the tracker's default; `fps` `FPS` unless given)
-- @raise an `EXIT` for `--help`, `--version` and a usage error
function M.parse(arg)
  return M.command.parse(arg)
end

--- The last component of a path.
-- @tparam string path
-- @treturn string
function M.basename(path)
  return (path:match("([^/]+)$") or path)
end

--- The last two components of a path: what tells logs named corners.csv apart.
-- @tparam string path
-- @treturn string
function M.short_name(path)
  return path:match("([^/]+/[^/]+)$") or M.basename(path)
end

return M
