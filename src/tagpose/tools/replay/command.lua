--- tagpose-replay's command line: its options, its paths and its ways out.
--
-- The ways out are those of `tagpose.tools.command` (its `EXIT` tables, caught by
-- `tagpose.tools.replay.main`): `usage` (status 2, with the usage), `refuse` (status 2: an
-- output that is an input), `fail` (status 1: a file cannot be read or written), and
-- `--help` (status 0).
-- @module tagpose.tools.replay.command

local compat = require("tagpose.core.compat")
local frame = require("tagpose.tools.command")

local huge = math.huge

local M = {}

--- The usage line.
M.USAGE = "usage: tagpose-replay LOG.csv [--camera FILE] [--tag-size S[UNIT]]\n"
  .. "  [--method refined|seed] [--track] [--smooth] [--max-gap T(s|ms)] [--sigma PX]\n"
  .. "  [--fps F] [--out POSES.csv|-] [--svg PLOT.svg] [--rpy] [--unit NAME] [--title TEXT]\n"
  .. "  [--compare OTHER.csv ...]\n"

--- Frames per second of the `frame` column when the log has no `time` column (`--fps`).
M.FPS = 30

local USAGE = M.USAGE

local UNITS = { m = true, cm = true, mm = true, ["in"] = true, ft = true }

--- The command's frame (`tagpose.tools.command.new`): its ways out, its option readers, its
-- `main`.
M.command = frame.new("replay", USAGE)

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

local usage = M.usage

-- --tag-size S[UNIT] into opt
local function tag_size(opt, v)
  local num, unit = v:match("^(.-)%s*(%a*)$")
  opt.tag_size = compat.decimal(num)
  if not (opt.tag_size and opt.tag_size > 0 and opt.tag_size < huge)
    or (unit ~= "" and not UNITS[unit]) then
    usage("--tag-size: positive number (with an optional unit m, cm, mm, in, ft) expected,"
      .. " got " .. v)
  end
  opt.tag_size_unit = unit ~= "" and unit or nil
end

-- --max-gap T(s|ms) into opt: seconds, as the tracker's; a bare number, which counted frames
-- before, is refused rather than read in another unit
local function max_gap(opt, v)
  local num, unit = v:match("^(.-)%s*(m?s)$")
  local x = num and compat.decimal(num)
  if not (x and x >= 0 and x < huge) then
    usage("--max-gap: a time with its unit expected (0.5s, 500ms), got " .. v
      .. (compat.decimal(v) and " (a bare number counted frames before; the tracker's gap is"
      .. " in seconds: 3 frames at 30 fps are --max-gap 0.1s)" or ""))
  end
  opt.max_gap = unit == "ms" and x / 1000 or x
end

-- the options that take one value, and the field each sets
local VALUE = { ["--camera"] = "camera", ["--out"] = "out", ["--svg"] = "svg",
  ["--unit"] = "unit", ["--title"] = "title" }

--- The options of the command line.
-- @tparam {string,...} arg the arguments
-- @treturn table `{log =, camera =, tag_size =, tag_size_unit =, method =, track =, smooth =,
--   max_gap =, sigma =, fps =, out =, svg =, rpy =, unit =, title =, compare = {path, ...}}`
--   (`track` set by `--smooth` and `--max-gap` too; `max_gap` in seconds or nil, the
--   tracker's default; `fps` `FPS` unless given)
-- @raise an `EXIT` for `--help` and for a usage error
function M.parse(arg)
  local opt = { compare = {}, fps = M.FPS }
  local args = M.command.args(arg)
  local value = args.value
  for a in args.next do
    if a == "--help" or a == "-h" then
      M.command.help()
    elseif VALUE[a] then
      opt[VALUE[a]] = value(a)
    elseif a == "--tag-size" then
      tag_size(opt, value(a))
    elseif a == "--method" then
      opt.method = value(a)
      if opt.method ~= "refined" and opt.method ~= "seed" then
        usage("--method: refined or seed expected, got " .. opt.method)
      end
    elseif a == "--track" then
      opt.track = true
    elseif a == "--smooth" then
      opt.track, opt.smooth = true, true
    elseif a == "--max-gap" then
      max_gap(opt, value(a))
      opt.track = true
    elseif a == "--sigma" then
      opt.sigma = args.positive(a)
    elseif a == "--fps" then
      opt.fps, opt.fps_given = args.positive(a), true
    elseif a == "--rpy" then
      opt.rpy = true
    elseif a == "--compare" then
      opt.compare[#opt.compare + 1] = value(a)
      while args.peek() and args.peek():sub(1, 2) ~= "--" do
        opt.compare[#opt.compare + 1] = args.next()
      end
    elseif a:sub(1, 2) == "--" then
      usage("unknown option " .. a)
    elseif not opt.log then
      opt.log = a
    else
      usage("one corner log expected, got " .. opt.log .. " and " .. a)
    end
  end
  if not opt.log then usage() end
  return opt
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
