--- tagpose-replay: replay a corner log: solve every detection the robot's tag detector logged,
-- write the poses, summarise, and draw the curves.
--
--   tagpose-replay LOG.csv [--camera FILE] [--tag-size S[UNIT]]
--     [--method refined|seed] [--track] [--max-gap N] [--out POSES.csv|-] [--svg PLOT.svg]
--     [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]
--
-- LOG.csv      a corner log (header frame,tag,u1,v1,u2,v2,u3,v3,u4,v4; further columns ignored;
--              blank lines and lines starting with # skipped; see tagpose.tools.log)
-- --camera     a calibration file (tagpose.calibration): a Lua camera file (read as data),
--              ROS camera_calibration or CameraInfo YAML, or OpenCV FileStorage YAML; default:
--              camera.lua beside LOG.csv
-- --tag-size   the side of the tag's black square, optionally with its unit (0.024, 24mm);
--              default: the camera file's tag_size (a number, or {[id] = size, default =
--              size}). Poses come out in its unit; the plot's axes name it (--unit overrides)
-- --method     refined (default) or seed (the report's method exactly)
-- --track      pass each track's pose of the previous frame as the prior of the next;
--              --max-gap N also accepts a pose up to N frames old (and implies --track)
-- --out        write the pose log (frame,tag,x,y,z,qw,qx,qy,qz,error,iterations): one row per
--              readable input row, in input order; a row that failed keeps its frame and tag
--              with empty pose fields. "-" writes it to standard output (the summary then goes
--              to standard error)
-- --svg        draw x, y, z and the quaternion (or with --rpy roll, pitch, yaw in degrees) over
--              frames, one line per track; every --compare log is drawn dashed over it
-- --compare    other pose logs (or truth files frame,tag,x,y,z,qw,qx,qy,qz) to draw and to
--              measure against, matched by frame and tag; several may follow one --compare
--
-- The log is read, solved and written row by row: memory holds the rows of one frame, the
-- live tracks and, for the plot, at most `plot.MAX_POINTS` points per track. Rows that share a
-- (frame, tag) key (lab tags are often all id 0) are kept apart as tracks, by image position
-- (each detection joins the track of its id whose last centre is nearest, within twice that
-- detection's diagonal plus 10 px); a track's pose is the prior of its own next detection only.
-- A malformed row is reported with its line number and skipped. Exit status: 0 when the log
-- was replayed (whatever its rows gave), 1 when a file cannot be read or written, 2 on a usage
-- error.
-- @module tagpose.tools.replay

local tagpose = require("tagpose")
local calibration = require("tagpose.calibration")
local compat = require("tagpose.compat")
local log = require("tagpose.tools.log")
local plot = require("tagpose.tools.plot")

local sqrt, asin, deg, floor, ceil, min, max = math.sqrt, math.asin, math.deg, math.floor,
  math.ceil, math.min, math.max
local huge, mlog = math.huge, math.log
local is_finite = compat.is_finite

local USAGE = "usage: tagpose-replay LOG.csv [--camera FILE] [--tag-size S[UNIT]]\n"
  .. "  [--method refined|seed] [--track] [--max-gap N] [--out POSES.csv|-] [--svg PLOT.svg]\n"
  .. "  [--rpy] [--unit NAME] [--title TEXT] [--compare OTHER.csv ...]\n"

--- Most rows of one frame solved together; a frame of more is solved in parts of this many
-- (repeated keys are still counted across the parts).
local MAX_GROUP = 1000
--- Most tracks of one tag id (further detections of the id in a frame are solved without a
-- prior and not drawn).
local MAX_TRACKS = 16
--- Most failures and malformed rows listed one by one (the rest are counted by reason).
local LISTED = 20
--- Most distinct reasons counted.
local REASONS = 50

local UNITS = { m = true, cm = true, mm = true, ["in"] = true, ft = true }

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

local function number(v)
  if v == floor(v) and v > -1e15 and v < 1e15 then return ("%.0f"):format(v) end
  return ("%.6g"):format(v)
end

local function compare_ids(a, b)
  if type(a) == type(b) then return a < b end
  return type(a) == "number"
end

-- quantiles in bounded memory: counts in bins of 1/1000 of a decade (0.23 %)
local BINS = 1000
local LOG10 = mlog(10)

local function histogram()
  return { n = 0, zero = 0, bins = {} }
end

local function add(h, v)
  if not is_finite(v) or v < 0 then return end
  h.n = h.n + 1
  if v < 1e-300 then
    h.zero = h.zero + 1
    return
  end
  local k = floor(mlog(v) / LOG10 * BINS)
  h.bins[k] = (h.bins[k] or 0) + 1
end

-- the value of nearest rank ceil(q n) (the lower median for q = 0.5), to the bin's centre
local function quantile(h, q)
  if h.n == 0 then return nil end
  local rank = max(1, ceil(q * h.n - 1e-9))
  if rank <= h.zero then return 0 end
  local keys = {}
  for k in pairs(h.bins) do keys[#keys + 1] = k end
  table.sort(keys)
  local acc = h.zero
  for _, k in ipairs(keys) do
    acc = acc + h.bins[k]
    if acc >= rank then return 10 ^ ((k + 0.5) / BINS) end
  end
  return nil
end

-- a list of at most LISTED entries, and counts by reason
local function tally()
  return { n = 0, listed = {}, counts = {}, order = {}, other = 0 }
end

local function note(t, entry)
  t.n = t.n + 1
  if #t.listed < LISTED then t.listed[#t.listed + 1] = entry end
  local r = entry.reason
  if t.counts[r] then
    t.counts[r] = t.counts[r] + 1
  elseif #t.order < REASONS then
    t.order[#t.order + 1] = r
    t.counts[r] = 1
  else
    t.other = t.other + 1
  end
end

local function parse_command_line(arg)
  local opt = { compare = {}, max_gap = nil }
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
      local num, unit = v:match("^(.-)%s*(%a*)$")
      opt.tag_size = compat.decimal(num)
      if not (opt.tag_size and opt.tag_size > 0 and opt.tag_size < huge)
        or (unit ~= "" and not UNITS[unit]) then
        usage("--tag-size: positive number (with an optional unit m, cm, mm, in, ft) expected,"
          .. " got " .. v)
      end
      opt.tag_size_unit = unit ~= "" and unit or nil
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
      if not (opt.max_gap and opt.max_gap >= 1 and opt.max_gap < huge) then
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
  return opt
end

local function exists(path)
  local f = io.open(path, "r")
  if f then f:close() end
  return f ~= nil
end

local function basename(path)
  return (path:match("([^/]+)$") or path)
end

-- the last two components of a path: what tells logs named corners.csv apart
local function short_name(path)
  return path:match("([^/]+/[^/]+)$") or basename(path)
end

local function describe_lens(camera)
  local d = camera.distortion
  if not d then return "no lens distortion" end
  local names = camera.model == "fisheye" and { "k1", "k2", "k3", "k4" }
    or { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
  local parts = {}
  for _, k in ipairs(names) do
    if d[k] ~= nil and (d[k] ~= 0 or k == "k1") then
      parts[#parts + 1] = k .. " " .. number(d[k])
    end
  end
  return (camera.model == "fisheye" and "fisheye lens " or "Brown-Conrady lens ")
    .. table.concat(parts, ", ")
end

local function describe_sizes(sizes)
  if type(sizes) == "number" then return number(sizes) end
  local ids = {}
  for k in pairs(sizes) do
    if k ~= "default" then ids[#ids + 1] = k end
  end
  table.sort(ids)
  local parts = {}
  if sizes.default then parts[1] = number(sizes.default) .. " (default)" end
  for k = 1, min(#ids, 10) do
    parts[#parts + 1] = number(sizes[ids[k]]) .. " (tag " .. number(ids[k]) .. ")"
  end
  if #ids > 10 then parts[#parts + 1] = "..." end
  return table.concat(parts, ", ")
end

-- the rotation between two quaternions, degrees
local function rotation_difference(a, b)
  local na = sqrt(a.w ^ 2 + a.x ^ 2 + a.y ^ 2 + a.z ^ 2)
  local nb = sqrt(b.w ^ 2 + b.x ^ 2 + b.y ^ 2 + b.z ^ 2)
  local s = (a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z) < 0 and -1 or 1
  local chord = sqrt((a.w / na - s * b.w / nb) ^ 2 + (a.x / na - s * b.x / nb) ^ 2
    + (a.y / na - s * b.y / nb) ^ 2 + (a.z / na - s * b.z / nb) ^ 2)
  return deg(4 * asin(min(1, chord / 2)))
end

local function distance(p, q)
  return sqrt((p.x - q.x) ^ 2 + (p.y - q.y) ^ 2 + (p.z - q.z) ^ 2)
end

local function position_point(pose)
  if not pose then return false end
  local p = pose.position
  return { p.x, p.y, p.z }
end

-------------------------------------------------------------------------------------------------
-- a pose log to compare with, read alongside in frame order

local Compare = {}
Compare.__index = Compare

local function open_compare(path, recorder)
  local reader, err = log.pose_reader(path)
  if not reader then fail(err:find(path, 1, true) and err or path .. ": " .. err) end
  local label = basename(path):gsub("%.csv$", "")
  local self = setmetatable({ path = path, reader = reader, source = recorder and
    recorder:source(label), recorder = recorder, tracker = plot.tracker(), problems = tally(),
    dt = histogram(), dr = histogram(), matched = 0, frame = nil, rows = {}, last = nil,
    out_of_order = 0, first_out_of_order = nil, unmatched_frame = 0, lookahead = nil,
    done = false }, Compare)
  return self
end

function Compare:peek()
  while not self.lookahead and not self.done do
    local e, line, reason = self.reader:read()
    if e == nil then
      self.done = true
      self.reader:close()
    elseif e == false then
      note(self.problems, { line = line, reason = reason })
    else
      self.lookahead = e
    end
  end
  return self.lookahead
end

-- draw the rows of one frame of this log (a list of entries of the same frame)
function Compare:draw(frame, rows)
  if not self.recorder then return end
  local by_tag, tags = {}, {}
  for _, e in ipairs(rows) do
    local list = by_tag[e.tag]
    if not list then
      list = {}
      by_tag[e.tag] = list
      tags[#tags + 1] = e.tag
    end
    list[#list + 1] = e
  end
  for _, tag in ipairs(tags) do
    local list = by_tag[tag]
    local points = {}
    for k, e in ipairs(list) do points[k] = position_point(e.pose) end
    local slots = self.tracker:assign(frame, tag, points)
    for k, e in ipairs(list) do
      self.recorder:add(self.source, tag, slots[k] or 1, frame, e.pose)
    end
  end
end

-- consume the rows before `frame` (drawn only), then gather those of `frame`
function Compare:take(frame)
  if self.frame == frame then return self.rows end
  local pending, pending_frame = {}, nil
  local function flush()
    if pending_frame ~= nil then self:draw(pending_frame, pending) end
    pending, pending_frame = {}, nil
  end
  while true do
    local e = self:peek()
    if not e or e.frame >= frame then break end
    self.lookahead = nil
    if self.last and e.frame < self.last then
      self.out_of_order = self.out_of_order + 1
      self.first_out_of_order = self.first_out_of_order or e.line
    end
    self.last = e.frame
    if e.frame ~= pending_frame or #pending >= MAX_GROUP then flush() end
    pending_frame = e.frame
    pending[#pending + 1] = e
  end
  flush()
  local rows = {}
  while true do
    local e = self:peek()
    if not e or e.frame ~= frame then break end
    self.lookahead = nil
    self.last = e.frame
    if #rows < MAX_GROUP then
      rows[#rows + 1] = e
    else
      self.unmatched_frame = self.unmatched_frame + 1
      self:draw(frame, { e })
    end
  end
  self:draw(frame, rows)
  self.frame, self.rows = frame, rows
  return rows
end

-- match the solved rows of a frame (entries {tag =, pose =}) with this log's, nearest first
function Compare:match(frame, solved)
  local rows = self:take(frame)
  if #rows == 0 then return end
  local by_tag = {}
  for i, e in ipairs(rows) do
    if e.pose and not e.used then
      local list = by_tag[e.tag] or {}
      by_tag[e.tag] = list
      list[#list + 1] = i
    end
  end
  local pairs_ = {}
  for k, s in ipairs(solved) do
    for _, i in ipairs(by_tag[s.tag] or {}) do
      pairs_[#pairs_ + 1] = { distance(s.pose.position, rows[i].pose.position), k, i }
    end
  end
  table.sort(pairs_, function(a, b)
    if a[1] ~= b[1] then return a[1] < b[1] end
    if a[2] ~= b[2] then return a[2] < b[2] end
    return a[3] < b[3]
  end)
  local used = {}
  for _, p in ipairs(pairs_) do
    local k, i = p[2], p[3]
    if not used[k] and not rows[i].used then
      used[k], rows[i].used = true, true
      self.matched = self.matched + 1
      add(self.dt, p[1])
      add(self.dr, rotation_difference(solved[k].pose.quaternion, rows[i].pose.quaternion))
    end
  end
end

function Compare:finish()
  self:take(huge)
end

-------------------------------------------------------------------------------------------------

local function run(arg)
  local opt = parse_command_line(arg)

  -- where the summary goes: stdout, unless the pose log does
  local out = opt.out == "-" and io.stderr or io.stdout
  local function say(fmt, ...)
    out:write(select("#", ...) > 0 and fmt:format(...) or fmt, "\n")
  end

  -- the camera
  local camera_path = opt.camera
  if not camera_path then
    camera_path = (opt.log:match("^(.*)/[^/]*$") or ".") .. "/camera.lua"
    if not exists(camera_path) then
      usage("no camera file: " .. camera_path .. " does not exist; give --camera FILE")
    end
  end
  local camera, info = calibration.read(camera_path)
  if not camera then fail(info) end
  local problem = tagpose.camera.check(camera)
  if problem then fail(camera_path .. ": " .. problem) end
  local sizes = opt.tag_size or info.tag_size
  if sizes == nil then
    usage(camera_path .. " has no tag_size; give --tag-size S")
  end
  local function size_of(tag)
    if type(sizes) == "number" then return sizes end
    return sizes[tag] or sizes.default
  end
  local unit = opt.unit or opt.tag_size_unit or (opt.tag_size and "tag-size units")
    or info.unit or "m"

  -- the corner log, the pose log, the figure's recorder, the logs to compare with
  local reader, rerr = log.corner_reader(opt.log)
  if not reader then fail(rerr:find(opt.log, 1, true) and rerr or opt.log .. ": " .. rerr) end
  local writer
  if opt.out then
    local werr
    writer, werr = log.pose_writer(opt.out == "-" and io.stdout or opt.out)
    if not writer then fail(werr) end
  end
  local recorder, main_source
  if opt.svg then
    recorder = plot.recorder({ rotation = opt.rpy and "rpy" or "quaternion" })
    main_source = recorder:source("tagpose " .. (opt.method or "refined")
      .. (opt.max_gap and " tracked" or ""))
  end
  local compares = {}
  for _, path in ipairs(opt.compare) do compares[#compares + 1] = open_compare(path, recorder) end

  -- what the summary needs, in bounded memory
  local rows, solved = 0, 0
  local failures, malformed = tally(), tally()
  local errors, iterations = histogram(), {}
  local tags, ntags = {}, 0
  local first_frame, last_frame
  local repeated = { rows = 0, max = 1, tags = {}, ntags = 0, first = nil }
  local order = { rows = 0, first = nil }
  local untracked = 0
  local tracker = plot.tracker({ keep = opt.max_gap or 1, max_tracks = MAX_TRACKS })
  local options = { method = opt.method }
  local frame_counts, counted_frame = {}, nil
  local previous_frame = nil

  -- solve the rows of one frame (or part of one), write them in their order
  local function process(group)
    local frame = group[1].frame
    if previous_frame ~= nil and frame < previous_frame then
      order.rows = order.rows + #group
      order.first = order.first or group[1].line
    end
    previous_frame = frame
    if counted_frame ~= frame then frame_counts, counted_frame = {}, frame end
    local by_tag, order_of_tags = {}, {}
    for _, row in ipairs(group) do
      local list = by_tag[row.tag]
      if not list then
        list = {}
        by_tag[row.tag] = list
        order_of_tags[#order_of_tags + 1] = row.tag
      end
      list[#list + 1] = row
    end
    for _, tag in ipairs(order_of_tags) do
      local list = by_tag[tag]
      local before = frame_counts[tag] or 0
      local now = before + #list
      frame_counts[tag] = now
      if now > 1 then
        repeated.rows = repeated.rows + #list + (before == 1 and 1 or 0)
        repeated.first = repeated.first or list[before == 0 and 2 or 1].line
        if now > repeated.max then repeated.max = now end
        if not repeated.tags[tag] then
          repeated.tags[tag] = true
          repeated.ntags = repeated.ntags + 1
        end
      end
      -- each row's track, by the centre of its corners
      local points = {}
      for k, row in ipairs(list) do
        local c = row.corners
        local u = (c[1][1] + c[2][1] + c[3][1] + c[4][1]) / 4
        local v = (c[1][2] + c[2][2] + c[3][2] + c[4][2]) / 4
        local diagonal = sqrt((c[1][1] - c[3][1]) ^ 2 + (c[1][2] - c[3][2]) ^ 2)
        points[k] = { u, v, gate = 2 * diagonal + 10 }
      end
      local slots, tracks = tracker:assign(frame, tag, points)
      for k, row in ipairs(list) do
        local track = tracks[k]
        local prior = nil
        if opt.max_gap and track and track.pose then
          local gap = frame - track.pose_frame
          if gap >= 1 and gap <= opt.max_gap then prior = track.pose end
        end
        options.prior = prior
        local size = size_of(tag)
        local pose, reason
        if size == nil then
          reason = "no tag size for tag " .. number(tag) .. " (the tag_size table has no default)"
        else
          local ok
          ok, pose, reason = pcall(tagpose.solve, row.corners, camera, size, options)
          if not ok then pose, reason = nil, tostring(pose) end
        end
        if pose and track then track.pose, track.pose_frame = pose, frame end
        row.pose, row.reason, row.slot = pose, reason or (not pose and "no pose") or nil, slots[k]
        if not slots[k] and is_finite(points[k][1]) and is_finite(points[k][2]) then
          untracked = untracked + 1
        end
      end
    end
    -- in the log's order: the pose log, the summary's counts, the figure
    local solved_rows = {}
    for _, row in ipairs(group) do
      rows = rows + 1
      local pose = row.pose
      if writer then writer:write(row.frame, row.tag, pose) end
      if pose then
        solved = solved + 1
        add(errors, pose.error)
        local it = pose.iterations
        iterations[it] = (iterations[it] or 0) + 1
        solved_rows[#solved_rows + 1] = row
      else
        note(failures, { line = row.line, frame = row.frame, tag = row.tag, reason = row.reason })
      end
      if not tags[row.tag] then
        tags[row.tag] = true
        ntags = ntags + 1
      end
      if not first_frame or row.frame < first_frame then first_frame = row.frame end
      if not last_frame or row.frame > last_frame then last_frame = row.frame end
      if recorder and (row.slot or not pose) then
        recorder:add(main_source, row.tag, row.slot or 1, row.frame, pose)
      end
    end
    for _, c in ipairs(compares) do c:match(frame, solved_rows) end
  end

  local group = {}
  while true do
    local det, line, reason = reader:read()
    if det == nil then break end
    if det == false then
      note(malformed, { line = line, reason = reason })
    else
      if #group > 0 and (det.frame ~= group[1].frame or #group >= MAX_GROUP) then
        process(group)
        group = {}
      end
      det.fields = nil
      group[#group + 1] = det
    end
  end
  if #group > 0 then process(group) end
  reader:close()
  for _, c in ipairs(compares) do c:finish() end

  -- the pose log first, so that a summary never claims a file that was not written
  local written = nil
  if writer then
    local n, werr = writer:close()
    if not n then fail(werr) end
    written = n
  end

  -- the summary
  local tag_list = {}
  for id in pairs(tags) do tag_list[#tag_list + 1] = id end
  table.sort(tag_list, compare_ids)
  local tag_names = {}
  for k = 1, min(#tag_list, 20) do tag_names[k] = number(tag_list[k]) end
  if #tag_list > 20 then tag_names[#tag_names + 1] = "..." end
  say("replay %s", opt.log)
  say("  camera %s (%s): fx %s, fy %s, cx %s, cy %s, %s; tag size %s%s", camera_path,
    info.format, number(camera.fx), number(camera.fy), number(camera.cx), number(camera.cy),
    describe_lens(camera), describe_sizes(sizes), unit ~= "tag-size units" and " " .. unit or "")
  if info.ignored and #info.ignored > 0 then
    say("  (not read from %s: %s)", camera_path, table.concat(info.ignored, ", "))
  end
  say("  method %s, %s", opt.method or "refined", opt.max_gap
    and ("tracking each tag from its pose up to %s frame%s before"):format(number(opt.max_gap),
      opt.max_gap == 1 and "" or "s") or "no tracking")
  say("rows       %d%s", rows, rows > 0 and (" (%d tag%s: %s; frames %s to %s)"):format(ntags,
    ntags == 1 and "" or "s", table.concat(tag_names, ", "), number(first_frame),
    number(last_frame)) or "")
  say("solved     %d", solved)
  say("failed     %d", failures.n)
  local function list_reasons(t, what)
    if t.n > #t.listed then
      say("  ... %d more (%s); by reason:", t.n - #t.listed, what)
      for _, reason in ipairs(t.order) do say("  %6d  %s", t.counts[reason], reason) end
      if t.other > 0 then say("  %6d  (other reasons)", t.other) end
    end
  end
  for _, f in ipairs(failures.listed) do
    say("  line %d (frame %s, tag %s): %s", f.line, number(f.frame), number(f.tag), f.reason)
  end
  list_reasons(failures, "every failed row is in the pose log with empty pose fields")
  say("malformed  %d%s", malformed.n, malformed.n > 0 and " (skipped, not in the pose log)" or "")
  for _, p in ipairs(malformed.listed) do say("  line %d: %s", p.line, p.reason) end
  list_reasons(malformed, "skipped")
  if repeated.rows > 0 then
    local ids = {}
    for id in pairs(repeated.tags) do ids[#ids + 1] = id end
    table.sort(ids, compare_ids)
    local names = {}
    for k = 1, min(#ids, 10) do names[k] = number(ids[k]) end
    if #ids > 10 then names[#names + 1] = "..." end
    say("repeated   %d rows share their frame and tag with another row (tag%s %s, up to %d in"
      .. " a frame; first at line %d): kept apart as tracks by image position", repeated.rows,
      #ids == 1 and "" or "s", table.concat(names, ", "), repeated.max, repeated.first)
  end
  if untracked > 0 then
    say("untracked  %d detections beyond %d tracks of one id in a frame: solved without a"
      .. " prior, not drawn", untracked, MAX_TRACKS)
  end
  if order.rows > 0 then
    say("order      %d rows come after a later frame (first at line %d): they get no prior,"
      .. " and the plot and comparisons assume frame order", order.rows, order.first)
  end
  local med_error = quantile(errors, 0.5)
  if med_error then
    local its, count = {}, 0
    for it in pairs(iterations) do its[#its + 1] = it end
    table.sort(its)
    local med_iterations
    for _, it in ipairs(its) do
      count = count + iterations[it]
      if count >= ceil(solved / 2) then
        med_iterations = it
        break
      end
    end
    say("median reprojection error %.3g px, median solveQuad iterations %s", med_error,
      number(med_iterations))
  else
    say("median reprojection error -, median solveQuad iterations - (no row solved)")
  end

  for _, c in ipairs(compares) do
    if c.matched > 0 then
      local lu = unit == "tag-size units" and "" or " " .. unit
      say("vs %s: %d rows matched; position difference median %.3g%s, p95 %.3g%s; rotation"
        .. " median %.3g deg, p95 %.3g deg", c.path, c.matched, quantile(c.dt, 0.5), lu,
        quantile(c.dt, 0.95), lu, quantile(c.dr, 0.5), quantile(c.dr, 0.95))
    else
      say("vs %s: no solved row has a pose there with the same frame and tag", c.path)
    end
    for _, p in ipairs(c.problems.listed) do
      say("  %s line %d: %s (skipped)", c.path, p.line, p.reason)
    end
    if c.problems.n > #c.problems.listed then
      say("  %s: %d more malformed rows", c.path, c.problems.n - #c.problems.listed)
    end
    if c.out_of_order > 0 then
      say("  %s: %d rows come after a later frame (first at line %d): not compared", c.path,
        c.out_of_order, c.first_out_of_order)
    end
  end

  if written then
    say("wrote %s (%d rows)", opt.out == "-" and "the pose log to standard output" or opt.out,
      written)
  end

  -- the figure
  if recorder then
    local title = opt.title or ("replay of " .. short_name(opt.log))
    local svg, shown = plot.draw(recorder, { title = title, length_unit = unit })
    local f, ferr = io.open(opt.svg, "w")
    if not f then fail(tostring(ferr)) end
    local ok, werr = f:write(svg)
    f:close()
    if not ok then fail(opt.svg .. ": " .. tostring(werr)) end
    local ntracks = shown.tracks
    local nsources = #compares + 1
    say("wrote %s (%d panels, %d series: %s%d tag%s x %d log%s)", opt.svg, shown.panels,
      shown.series, ntracks > #shown.tags and (ntracks .. " tracks of ") or "", #shown.tags,
      #shown.tags == 1 and "" or "s", nsources, nsources == 1 and "" or "s")
    if recorder.dropped > 0 then
      say("  %d points out of frame order not drawn", recorder.dropped)
    end
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
