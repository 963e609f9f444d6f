--- tagpose-replay's rows, a frame at a time: each row joins a track of its tag id (by image
-- position), is solved (with its track's previous pose as the prior when tracking), written
-- to the pose log, counted for the summary and recorded for the figure.
--
-- `new` returns the replay's record, which `process` and `read` update and the summary
-- (`tagpose.tools.replay.summary`) reads:
--
--     {
--       opt =, camera =, sizes =,  -- the command's options, the camera, the tag sizes
--       writer =, recorder =, main_source =, compares = {...},  -- where rows go
--       rows = n, solved = n, failures = tally, malformed = tally,
--       errors = histogram, iterations = {[n] = count},
--       tags = {[id] = true}, ntags = n, more_tags = boolean,  -- at most MAX_IDS ids
--       first_frame =, last_frame =,
--       repeated = {rows =, max =, tags =, ntags =, first =},  -- rows sharing (frame, tag)
--       order = {rows =, first =},  -- rows after a later frame
--       untracked = n,  -- detections past MAX_TRACKS tracks of an id
--       forgotten = n,  -- live tracks dropped past MAX_LIVE (the least recently seen)
--       ...                         -- and the per-frame state of the tracks
--     }
--
-- Memory is bounded whatever the log (its length, its ids): the rows of one part of a frame,
-- at most twice `MAX_LIVE` tracks (a tracker keeps an id's tracks until the id comes back, so
-- the ids whose tracks have ended are swept out as new ones come, and the live ones down to
-- `MAX_LIVE`: `bound_tracks`), at most
-- `MAX_IDS` ids in the summary and in a frame's count of repeated keys, and the figure's
-- bounded series. A track keeps its last pose only when tracking (`--track`), for the prior.
-- @module tagpose.tools.replay.frames

local tagpose = require("tagpose")
local compat = require("tagpose.core.compat")
local plot = require("tagpose.tools.plot")
local stats = require("tagpose.tools.replay.stats")

local sqrt = math.sqrt
local is_finite = compat.is_finite
local add, note = stats.add, stats.note

local M = {}

--- Most rows of one frame solved together; a frame of more is solved in parts of this many
-- (repeated keys are still counted across the parts).
M.MAX_GROUP = 1000
--- Most tracks of one tag id (further detections of the id in a frame are solved without a
-- prior and not drawn).
M.MAX_TRACKS = 16
--- Most distinct tag ids the summary keeps (a log may carry a new id on every row), and the
-- most whose repeated keys are counted in one frame.
M.MAX_IDS = 10000
--- Most live tracks kept (over all ids; the least recently seen are dropped past it).
M.MAX_LIVE = 1000

local MAX_GROUP, MAX_IDS = M.MAX_GROUP, M.MAX_IDS

--- A count of the tracks a `tagpose.tools.plot.tracker` may hold, for `bound_tracks`.
-- @treturn table
function M.track_count()
  return { added = 0, forgotten = 0 }
end

local function by_age(a, b)
  if a.frame ~= b.frame then return a.frame < b.frame end
  if type(a.id) ~= type(b.id) then return type(a.id) == "number" end
  return a.id < b.id
end

--- Keep a tracker's tracks bounded: after `tracker:assign` gave id `id` tracks, count the new
-- ones; past `MAX_LIVE` new tracks since the last sweep, drop every id whose tracks have all
-- ended (none seen within `tracker.keep` frames of `frame`: the tracker would drop them when
-- the id came back), then the least recently seen ids (older frames first, then smaller ids)
-- until at most `MAX_LIVE` tracks are left. Each sweep costs the tracks it looks at, once per
-- `MAX_LIVE` new tracks.
-- @tparam table tracker a `tagpose.tools.plot.tracker`
-- @tparam table count a `track_count()` (its `forgotten` counts the live tracks dropped)
-- @tparam number frame the frame just assigned
-- @tparam int before the number of tracks of the id before `assign`
-- @param id the id just assigned
function M.bound_tracks(tracker, count, frame, before, id)
  local list = tracker.tracks[id]
  local now = list and #list or 0
  local limit = M.MAX_LIVE
  if now > before then count.added = count.added + now - before end
  if count.added <= limit then return end
  local ids, total = {}, 0
  for key, l in pairs(tracker.tracks) do
    local last = -math.huge
    for _, t in ipairs(l) do
      if t.frame and t.frame > last then last = t.frame end
    end
    if frame - last > tracker.keep then
      tracker.tracks[key] = nil
    else
      ids[#ids + 1] = { id = key, frame = last, n = #l }
      total = total + #l
    end
  end
  if total > limit then
    table.sort(ids, by_age)
    for _, e in ipairs(ids) do
      if total <= limit then break end
      tracker.tracks[e.id] = nil
      total = total - e.n
      count.forgotten = count.forgotten + e.n
    end
  end
  count.added = 0
end

--- A replay's record (see the module's header), nothing read yet.
-- @tparam table opt the options of `tagpose.tools.replay.command.parse`
-- @tparam table camera
-- @tparam number|table sizes the tag size, or `{[id] = size, default = size}`
-- @tparam table out `{writer =, recorder =, main_source =, compares =}` (each optional but
--   `compares`)
-- @treturn table
function M.new(opt, camera, sizes, out)
  return { opt = opt, camera = camera, sizes = sizes, writer = out.writer,
    recorder = out.recorder, main_source = out.main_source, compares = out.compares,
    rows = 0, solved = 0, failures = stats.tally(), malformed = stats.tally(),
    errors = stats.histogram(), iterations = {}, tags = {}, ntags = 0, more_tags = false,
    first_frame = nil, last_frame = nil,
    repeated = { rows = 0, max = 1, tags = {}, ntags = 0, first = nil },
    order = { rows = 0, first = nil }, untracked = 0,
    tracker = plot.tracker({ keep = opt.max_gap or 1, max_tracks = M.MAX_TRACKS }),
    track_count = M.track_count(), options = { method = opt.method }, frame_counts = {},
    frame_ids = 0, uncounted = 0, counted_frame = nil, previous_frame = nil }
end

-- count the rows of a tag that share their frame with another of the tag (among the first
-- MAX_IDS ids of the frame: the rows of further ids are counted as uncounted)
local function count_repeated(run, tag, list)
  local repeated = run.repeated
  local before = run.frame_counts[tag]
  if before == nil then
    if run.frame_ids >= MAX_IDS then
      run.uncounted = run.uncounted + #list
      return
    end
    run.frame_ids = run.frame_ids + 1
    before = 0
  end
  local now = before + #list
  run.frame_counts[tag] = now
  if now > 1 then
    repeated.rows = repeated.rows + #list + (before == 1 and 1 or 0)
    repeated.first = repeated.first or list[before == 0 and 2 or 1].line
    if now > repeated.max then repeated.max = now end
    if not repeated.tags[tag] and repeated.ntags < MAX_IDS then
      repeated.tags[tag] = true
      repeated.ntags = repeated.ntags + 1
    end
  end
end

-- a row's pose, or nil and the reason
local function solve_row(run, row, tag)
  local sizes = run.sizes
  local size = type(sizes) == "number" and sizes or sizes[tag] or sizes.default
  if size == nil then
    return nil, "no tag size for tag " .. stats.number(tag) .. " (the tag_size table has no"
      .. " default)"
  end
  local ok, pose, reason = pcall(tagpose.solve, row.corners, run.camera, size, run.options)
  if not ok then return nil, tostring(pose) end
  return pose, reason
end

-- solve the rows of one tag id in a frame, each with the prior of its track
local function solve_rows(run, frame, tag, list)
  local max_gap = run.opt.max_gap
  -- each row's track, by the centre of its corners
  local points = {}
  for k, row in ipairs(list) do
    local c = row.corners
    local u = (c[1][1] + c[2][1] + c[3][1] + c[4][1]) / 4
    local v = (c[1][2] + c[2][2] + c[3][2] + c[4][2]) / 4
    local diagonal = sqrt((c[1][1] - c[3][1]) ^ 2 + (c[1][2] - c[3][2]) ^ 2)
    points[k] = { u, v, gate = 2 * diagonal + 10 }
  end
  local tracker = run.tracker
  local known = tracker.tracks[tag]
  local slots, tracks = tracker:assign(frame, tag, points)
  M.bound_tracks(tracker, run.track_count, frame, known and #known or 0, tag)
  for k, row in ipairs(list) do
    local track = tracks[k]
    local prior = nil
    if max_gap and track and track.pose then
      local gap = frame - track.pose_frame
      if gap >= 1 and gap <= max_gap then prior = track.pose end
    end
    run.options.prior = prior
    local pose, reason = solve_row(run, row, tag)
    if pose and track and max_gap then track.pose, track.pose_frame = pose, frame end
    row.pose, row.reason, row.slot = pose, reason or (not pose and "no pose") or nil, slots[k]
    if not slots[k] and is_finite(points[k][1]) and is_finite(points[k][2]) then
      run.untracked = run.untracked + 1
    end
  end
end

-- the rows of a group in the log's order: to the pose log, the summary's counts, the figure;
-- returns the rows solved
local function record_rows(run, group)
  local writer, recorder, tags = run.writer, run.recorder, run.tags
  local solved_rows = {}
  for _, row in ipairs(group) do
    run.rows = run.rows + 1
    local pose = row.pose
    if writer then writer:write(row.frame, row.tag, pose) end
    if pose then
      run.solved = run.solved + 1
      add(run.errors, pose.error)
      local it = pose.iterations
      run.iterations[it] = (run.iterations[it] or 0) + 1
      solved_rows[#solved_rows + 1] = row
    else
      note(run.failures, { line = row.line, frame = row.frame, tag = row.tag,
        reason = row.reason })
    end
    if not tags[row.tag] then
      if run.ntags < MAX_IDS then
        tags[row.tag] = true
        run.ntags = run.ntags + 1
      else
        run.more_tags = true
      end
    end
    if not run.first_frame or row.frame < run.first_frame then run.first_frame = row.frame end
    if not run.last_frame or row.frame > run.last_frame then run.last_frame = row.frame end
    if recorder and (row.slot or not pose) then
      recorder:add(run.main_source, row.tag, row.slot or 1, row.frame, pose)
    end
  end
  return solved_rows
end

--- Solve the rows of one frame (or part of one) and write them in their order.
-- @tparam table run the replay's record
-- @tparam {table,...} group detections of `tagpose.tools.log.corner_reader`, of one frame
function M.process(run, group)
  local frame = group[1].frame
  if run.previous_frame ~= nil and frame < run.previous_frame then
    run.order.rows = run.order.rows + #group
    run.order.first = run.order.first or group[1].line
  end
  run.previous_frame = frame
  if run.counted_frame ~= frame then
    run.frame_counts, run.frame_ids, run.counted_frame = {}, 0, frame
  end
  local by_tag, tags = plot.by_tag(group)
  for _, tag in ipairs(tags) do
    local list = by_tag[tag]
    count_repeated(run, tag, list)
    solve_rows(run, frame, tag, list)
  end
  local solved_rows = record_rows(run, group)
  for _, c in ipairs(run.compares) do c:match(frame, solved_rows) end
end

--- Read a corner log to its end, a frame at a time (at most `MAX_GROUP` rows together),
-- noting its malformed rows; the reader is closed.
-- @tparam table run the replay's record
-- @tparam table reader a `tagpose.tools.log.corner_reader`
function M.read(run, reader)
  local group = {}
  while true do
    local det, line, reason = reader:read()
    if det == nil then break end
    if det == false then
      note(run.malformed, { line = line, reason = reason })
    else
      if #group > 0 and (det.frame ~= group[1].frame or #group >= MAX_GROUP) then
        M.process(run, group)
        group = {}
      end
      det.fields = nil
      group[#group + 1] = det
    end
  end
  if #group > 0 then M.process(run, group) end
  reader:close()
end

return M
