--- tagpose-replay: replay a corner log: solve every detection the robot's tag detector logged,
-- write the poses, summarise, and draw the curves.
--
--   tagpose-replay LOG.csv [--camera CAMERA.lua] [--tag-size S]
--     [--method refined|seed] [--track] [--max-gap N] [--out POSES.csv|-] [--svg PLOT.svg]
--     [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]
--
-- LOG.csv      a corner log (header frame,tag,u1,v1,u2,v2,u3,v3,u4,v4; further columns ignored;
--              blank lines and lines starting with # skipped)
-- --camera     a camera file (a Lua file returning {fx =, fy =, cx =, cy =, distortion =,
--              tag_size =}); default: camera.lua beside LOG.csv
-- --tag-size   the side of the tag's black square; default: the camera file's tag_size. Poses
--              come out in its unit (--unit names it for the plot's axes; default m)
-- --method     refined (default) or seed (the report's method exactly)
-- --track      pass each tag id's pose of the previous frame as the prior of the next;
--              --max-gap N also accepts a pose up to N frames old (and implies --track)
-- --out        write the pose log (frame,tag,x,y,z,qw,qx,qy,qz,error,iterations): one row per
--              readable input row, in input order; a row that failed keeps its frame and tag
--              with empty pose fields. "-" writes it to standard output (the summary then goes
--              to standard error)
-- --svg        draw x, y, z and the quaternion (or with --rpy roll, pitch, yaw in degrees) over
--              frames, one line per tag id; every --compare log is drawn dashed over it
-- --compare    other pose logs (or truth files frame,tag,x,y,z,qw,qx,qy,qz) to draw and to
--              measure against, matched by frame and tag; several may follow one --compare
--
-- A malformed row is reported with its line number and skipped. Exit status: 0 when the log
-- was replayed (whatever its rows gave), 1 when a file cannot be read or written, 2 on a usage
-- error.
-- @module tagpose.tools.replay

local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local plot = require("tagpose.tools.plot")

local sqrt, asin, deg, floor, min = math.sqrt, math.asin, math.deg, math.floor, math.min

local USAGE = "usage: tagpose-replay LOG.csv [--camera CAMERA.lua] [--tag-size S]\n"
  .. "  [--method refined|seed] [--track] [--max-gap N] [--out POSES.csv|-] [--svg PLOT.svg]\n"
  .. "  [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]\n"

-- the ways out of main: an exit status and what to say on standard error
local EXIT = {}

local function usage(msg)
  error(setmetatable({ status = 2, text = (msg and "replay: " .. msg .. "\n" or "") .. USAGE },
    EXIT), 0)
end

local function fail(msg)
  error(setmetatable({ status = 1, text = "replay: " .. msg .. "\n" }, EXIT), 0)
end

local M = {}

local function run(arg)
  -- the command line
  local opt = { compare = {}, max_gap = nil }
  do
    local i, n = 1, #arg
    local function value(name)
      i = i + 1
      local v = arg[i]
      if v == nil or (v:sub(1, 2) == "--" and #v > 2) then usage(name .. " needs a value") end
      return v
    end
    while i <= n do
      local a = arg[i]
      if a == "--help" or a == "-h" then
        io.stdout:write(USAGE)
        error(setmetatable({ status = 0, text = "" }, EXIT), 0)
      elseif a == "--camera" then
        opt.camera = value(a)
      elseif a == "--tag-size" then
        local v = value(a)
        opt.tag_size = tonumber(v)
        if not (opt.tag_size and opt.tag_size > 0 and opt.tag_size < math.huge) then
          usage("--tag-size: positive number expected, got " .. v)
        end
      elseif a == "--method" then
        opt.method = value(a)
        if opt.method ~= "refined" and opt.method ~= "seed" then
          usage("--method: refined or seed expected, got " .. opt.method)
        end
      elseif a == "--track" then
        opt.max_gap = opt.max_gap or 1
      elseif a == "--max-gap" then
        local v = value(a)
        opt.max_gap = tonumber(v)
        if not (opt.max_gap and opt.max_gap >= 1 and opt.max_gap < math.huge) then
          usage("--max-gap: number >= 1 expected, got " .. v)
        end
      elseif a == "--out" then
        opt.out = value(a)
      elseif a == "--svg" then
        opt.svg = value(a)
      elseif a == "--rpy" then
        opt.rpy = true
      elseif a == "--unit" then
        opt.unit = value(a)
      elseif a == "--title" then
        opt.title = value(a)
      elseif a == "--compare" then
        opt.compare[#opt.compare + 1] = value(a)
        while arg[i + 1] and arg[i + 1]:sub(1, 2) ~= "--" do
          i = i + 1
          opt.compare[#opt.compare + 1] = arg[i]
        end
      elseif a:sub(1, 2) == "--" then
        usage("unknown option " .. a)
      elseif not opt.log then
        opt.log = a
      else
        usage("one corner log expected, got " .. opt.log .. " and " .. a)
      end
      i = i + 1
    end
    if not opt.log then usage() end
  end

  -- where the summary goes: stdout, unless the pose log does
  local out = opt.out == "-" and io.stderr or io.stdout
  local function say(fmt, ...)
    out:write(select("#", ...) > 0 and fmt:format(...) or fmt, "\n")
  end

  local function exists(path)
    local f = io.open(path, "r")
    if f then f:close() end
    return f ~= nil
  end

  local function basename(path)
    return (path:match("([^/]+)$") or path)
  end

  local function number(v)
    if v == floor(v) and v > -1e15 and v < 1e15 then return ("%.0f"):format(v) end
    return ("%.6g"):format(v)
  end

  local function median(values)
    local n = #values
    if n == 0 then return nil end
    table.sort(values)
    if n % 2 == 1 then return values[(n + 1) / 2] end
    return 0.5 * (values[n / 2] + values[n / 2 + 1])
  end

  local function percentile95(values) -- of sorted values, nearest rank
    local n = #values
    if n == 0 then return nil end
    return values[min(n, floor(0.95 * n + 0.999999))]
  end

  -- the camera
  local camera_path = opt.camera
  if not camera_path then
    camera_path = (opt.log:match("^(.*)/[^/]*$") or ".") .. "/camera.lua"
    if not exists(camera_path) then
      usage("no camera file: " .. camera_path .. " does not exist; give --camera CAMERA.lua")
    end
  end
  local camera, cerr = log.read_camera(camera_path)
  if not camera then fail(cerr) end
  local problem = tagpose.camera.check(camera)
  if problem then fail(camera_path .. ": " .. problem) end
  local tag_size = opt.tag_size or camera.tag_size
  if not (type(tag_size) == "number" and tag_size > 0 and tag_size < math.huge) then
    usage(camera_path .. " has no positive tag_size; give --tag-size S")
  end

  -- the corner log
  local rows, problems = log.read_corners(opt.log)
  if not rows then
    fail(problems:find(opt.log, 1, true) and problems or opt.log .. ": " .. problems)
  end

  -- solve every row, in input order
  local options = { method = opt.method }
  local entries, last = {}, {}
  local errors, iterations, failures, tags, tag_list = {}, {}, {}, {}, {}
  local first_frame, last_frame
  for i, row in ipairs(rows) do
    local prior = nil
    if opt.max_gap then
      local prev = last[row.tag]
      local gap = prev and row.frame - prev.frame
      if gap and gap >= 1 and gap <= opt.max_gap then prior = prev.pose end
    end
    options.prior = prior
    local ok, pose, reason = pcall(tagpose.solve, row.corners, camera, tag_size, options)
    if not ok then pose, reason = nil, tostring(pose) end
    entries[i] = { frame = row.frame, tag = row.tag, pose = pose, line = row.line }
    if pose then
      last[row.tag] = { frame = row.frame, pose = pose }
      errors[#errors + 1] = pose.error
      iterations[#iterations + 1] = pose.iterations
    else
      failures[#failures + 1] = { line = row.line, frame = row.frame, tag = row.tag,
        reason = reason or "no pose" }
    end
    if not tags[row.tag] then
      tags[row.tag] = true
      tag_list[#tag_list + 1] = row.tag
    end
    if not first_frame or row.frame < first_frame then first_frame = row.frame end
    if not last_frame or row.frame > last_frame then last_frame = row.frame end
  end
  table.sort(tag_list)

  -- the pose log first, so that a summary never claims a file that was not written
  local written = nil
  if opt.out then
    local n, werr = log.write_poses(opt.out == "-" and io.stdout or opt.out, entries)
    if not n then fail(werr) end
    written = n
  end

  -- the summary
  local tag_names = {}
  for k, id in ipairs(tag_list) do tag_names[k] = number(id) end
  say("replay %s", opt.log)
  say("  camera %s: fx %s, fy %s, cx %s, cy %s%s; tag size %s", camera_path, number(camera.fx),
    number(camera.fy), number(camera.cx), number(camera.cy),
    camera.distortion and ", with distortion" or "", number(tag_size))
  say("  method %s, %s", opt.method or "refined", opt.max_gap
    and ("tracking each tag from its pose up to %s frame%s before"):format(number(opt.max_gap),
      opt.max_gap == 1 and "" or "s") or "no tracking")
  say("rows       %d%s", #rows, #rows > 0 and (" (%d tag%s: %s; frames %s to %s)"):format(#tag_list,
    #tag_list == 1 and "" or "s", table.concat(tag_names, ", "), number(first_frame),
    number(last_frame)) or "")
  say("solved     %d", #rows - #failures)
  say("failed     %d", #failures)
  if #failures > 0 then
    local counts, order = {}, {}
    for _, f in ipairs(failures) do
      if not counts[f.reason] then order[#order + 1] = f.reason end
      counts[f.reason] = (counts[f.reason] or 0) + 1
    end
    for k = 1, min(#failures, 20) do
      local f = failures[k]
      say("  line %d (frame %s, tag %s): %s", f.line, number(f.frame), number(f.tag), f.reason)
    end
    if #failures > 20 then
      say("  ... %d more (every failed row is in the pose log with empty pose fields); by reason:",
        #failures - 20)
      for _, reason in ipairs(order) do say("  %6d  %s", counts[reason], reason) end
    end
  end
  say("malformed  %d%s", #problems, #problems > 0 and " (skipped, not in the pose log)" or "")
  for _, p in ipairs(problems) do say("  line %d: %s", p.line, p.reason) end
  local med_error, med_iterations = median(errors), median(iterations)
  if med_error then
    say("median reprojection error %.3f px, median solveQuad iterations %s", med_error,
      number(med_iterations))
  else
    say("median reprojection error -, median solveQuad iterations - (no row solved)")
  end

  -- the logs to compare with: read, match by frame and tag, measure
  local unit = opt.unit or "m"
  local sources = { { label = "tagpose " .. (opt.method or "refined")
    .. (opt.max_gap and " tracked" or ""), entries = entries } }
  for _, path in ipairs(opt.compare) do
    local other, oproblems = log.read_poses(path)
    if not other then
      fail(oproblems:find(path, 1, true) and oproblems or path .. ": " .. oproblems)
    end
    sources[#sources + 1] = { label = basename(path):gsub("%.csv$", ""), entries = other }
    local index = {}
    for _, e in ipairs(other) do
      local key = number(e.frame) .. "/" .. number(e.tag)
      if e.pose and index[key] == nil then index[key] = e.pose end
    end
    local dt, dr = {}, {}
    for _, e in ipairs(entries) do
      local o = e.pose and index[number(e.frame) .. "/" .. number(e.tag)]
      if o then
        local p, q = e.pose.position, o.position
        dt[#dt + 1] = sqrt((p.x - q.x) ^ 2 + (p.y - q.y) ^ 2 + (p.z - q.z) ^ 2)
        local a, b = e.pose.quaternion, o.quaternion
        local na = sqrt(a.w ^ 2 + a.x ^ 2 + a.y ^ 2 + a.z ^ 2)
        local nb = sqrt(b.w ^ 2 + b.x ^ 2 + b.y ^ 2 + b.z ^ 2)
        local s = (a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z) < 0 and -1 or 1
        local chord = sqrt((a.w / na - s * b.w / nb) ^ 2 + (a.x / na - s * b.x / nb) ^ 2
          + (a.y / na - s * b.y / nb) ^ 2 + (a.z / na - s * b.z / nb) ^ 2)
        dr[#dr + 1] = deg(4 * asin(min(1, chord / 2)))
      end
    end
    local mt, mr = median(dt), median(dr)
    if mt then
      say("vs %s: %d rows matched; position difference median %.3g %s, p95 %.3g %s; rotation"
        .. " median %.3g deg, p95 %.3g deg", path, #dt, mt, unit, percentile95(dt), unit, mr,
        percentile95(dr))
    else
      say("vs %s: no solved row has a pose there with the same frame and tag", path)
    end
    for _, p in ipairs(oproblems) do say("  %s line %d: %s (skipped)", path, p.line, p.reason) end
  end

  if written then
    say("wrote %s (%d rows)", opt.out == "-" and "the pose log to standard output" or opt.out,
      written)
  end

  -- the figure
  if opt.svg then
    local title = opt.title or ("replay of " .. basename(opt.log))
    local svg, shown = plot.poses(sources, { title = title, rotation = opt.rpy and "rpy" or nil,
      length_unit = unit })
    local f, ferr = io.open(opt.svg, "w")
    if not f then fail(tostring(ferr)) end
    local ok, werr = f:write(svg)
    f:close()
    if not ok then fail(opt.svg .. ": " .. tostring(werr)) end
    say("wrote %s (%d panels, %d series: %d tag%s x %d log%s)", opt.svg, shown.panels,
      shown.series, #shown.tags, #shown.tags == 1 and "" or "s", #sources,
      #sources == 1 and "" or "s")
  end
  return 0
end

--- Run the command on its arguments (`arg` of the script).
-- @tparam {string,...} argv the command-line arguments
-- @treturn int the exit status: 0 replayed, 1 a file could not be read or written, 2 a usage
--   error
function M.main(argv)
  local ok, status = pcall(run, argv)
  if ok then return status end
  if getmetatable(status) == EXIT then
    io.stderr:write(status.text)
    return status.status
  end
  error(status, 0)
end

return M
