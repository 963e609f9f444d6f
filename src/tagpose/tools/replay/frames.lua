--- tagpose-replay's rows, a frame at a time: each frame's rows are fed to `tagpose.tracker`
-- with the frame's time (`tagpose.tools.replay.clock`), as a user's loop over the tracker
-- feeds it; with `--track` the poses are the tracker's (`tracker:update`), without it each
-- row is solved alone by `tagpose.solve` and the tracker gives the tracks only
-- (`tracker:assign`: the plot still tells apart the tags sharing an id). Then each row is
-- written to the pose log, counted for the summary and recorded for the figure.
--
-- With `--smooth`, `forward` runs the tracker over the whole log first (it keeps four numbers
-- a row) and `tracker:smooth()` gives each row's choice; the replay then runs a new tracker
-- over the log again (the same poses come out) and writes each row's smoothed choice, the
-- pose or its `alternative`, with the smoothed confidence.
--
-- `new` returns the replay's record, which `process` and `read` update and the summary
-- (`tagpose.tools.replay.summary`) reads:
--
--     {
--       opt =, camera =, sizes =,  -- the command's options, the camera, the tag sizes
--       tracker =, clock =,  -- the tracker, the frames' times (tagpose.tools.replay.clock)
--       writer =, recorder =, main_source =, compares = {...},  -- where rows go
--       rows = n, solved = n, failures = tally, malformed = tally,
--       errors = histogram, residuals = histogram, distances = histogram (the solved tags'
--       distances from the camera), iterations = {[n] = count},
--       tags = {[id] = true}, ntags = n, more_tags = boolean,  -- at most MAX_IDS ids
--       first_frame =, last_frame =,
--       repeated = {rows =, max =, tags =, ntags =, first =},  -- rows sharing (frame, tag)
--       order = {rows =, first =},  -- rows after a later frame
--       smoothed = {choice =, confidence =} or nil, switched = n,  -- --smooth
--       slots =,  -- the plot's line of each track (tagpose.tools.replay.slots)
--     }
--
-- Memory is bounded whatever the log (its length, its ids): the rows of one part of a frame
-- (a frame of more than `MAX_GROUP` rows is fed to the tracker in parts, with the same
-- time), the tracker's live tracks (`max_tracks`, and `max_gap`), the plot's slots, at most
-- `MAX_IDS` ids in the summary and in a frame's count of repeated keys, and the figure's
-- bounded series; with `--smooth`, four numbers a row in the first pass and two in the second.
-- @module tagpose.tools.replay.frames

local tagpose = require("tagpose")
local plot = require("tagpose.tools.plot")
local stats = require("tagpose.tools.replay.stats")
local clock_model = require("tagpose.tools.replay.clock")
local slots_model = require("tagpose.tools.replay.slots")
local command = require("tagpose.tools.command")

local add, note = stats.add, stats.note
local LN4 = 2 * math.log(2) -- the median of χ² with 2 degrees of freedom

local M = {}

--- Most rows of one frame fed together; a frame of more is fed in parts of this many (with
-- the same time; repeated keys are still counted across the parts).
M.MAX_GROUP = 1000
--- Most distinct tag ids the summary keeps (a log may carry a new id on every row), and the
-- most whose repeated keys are counted in one frame.
M.MAX_IDS = 10000

local MAX_GROUP, MAX_IDS = M.MAX_GROUP, M.MAX_IDS

--- The tracker of a replay: `tagpose.tracker` with the command's method, gap and σ.
-- @tparam table opt the options of `tagpose.tools.replay.command.parse`
-- @tparam table camera
-- @tparam number|table sizes
-- @tparam[opt] boolean smooth record for `tracker:smooth()`
-- @treturn table the tracker
function M.tracker(opt, camera, sizes, smooth)
  return tagpose.tracker.new(camera, sizes, { method = opt.method, max_gap = opt.max_gap,
    sigma = opt.sigma, order = opt.order, smooth = smooth or nil })
end

--- A replay's record (see the module's header), nothing read yet.
-- @tparam table opt the options of `tagpose.tools.replay.command.parse`
-- @tparam table camera
-- @tparam number|table sizes the tag size, or `{[id] = size, default = size}`
-- @tparam table tracker the replay's tracker (`tracker(opt, camera, sizes)`)
-- @tparam table out `{writer =, recorder =, main_source =, compares =}` (each optional but
--   `compares`)
-- @tparam table clock the frames' times (`tagpose.tools.replay.clock.new`)
-- @tparam[opt] table smoothed `{choice =, confidence =}` of `forward`
-- @treturn table
function M.new(opt, camera, sizes, tracker, out, clock, smoothed)
  return { opt = opt, camera = camera, sizes = sizes, writer = out.writer,
    recorder = out.recorder, main_source = out.main_source, compares = out.compares,
    tracker = tracker, clock = clock, smoothed = smoothed, switched = 0, fed = 0,
    slots = out.recorder and slots_model.new(tracker.max_gap) or nil,
    rows = 0, solved = 0, failures = stats.tally(), malformed = stats.tally(),
    errors = stats.histogram(), residuals = stats.histogram(), distances = stats.histogram(),
    iterations = {}, tags = {},
    ntags = 0, more_tags = false, first_frame = nil, last_frame = nil,
    repeated = { rows = 0, max = 1, tags = {}, ntags = 0, first = nil },
    order = { rows = 0, first = nil }, options = { method = opt.method, sigma = opt.sigma,
      order = opt.order },
    frame_counts = {}, frame_ids = 0, uncounted = 0, counted_frame = nil,
    previous_frame = nil, detections = {} }
end

--- The noise σ (px) the log's residuals give: from the median of the written poses' squared
-- residuals (χ² with the 2 degrees of freedom of a tag's 8 coordinates and 6 pose
-- parameters), robust to the odd bad detection. (The pose written, not the better fit of the
-- two: on an ambiguous far tag the smaller of two such sums is biased low.)
-- @tparam table run the replay's record
-- @treturn number|nil nil when no row was solved
function M.sigma(run)
  local median = stats.quantile(run.residuals, 0.5)
  return median and math.sqrt(median / LN4) or nil
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

-- a row's pose solved alone, or nil and the reason
local function solve_row(run, row)
  local sizes, tag = run.sizes, row.tag
  local size = type(sizes) == "number" and sizes or sizes[tag] or sizes.default
  if size == nil then return nil, "tracker: no tag size for id " .. stats.number(tag) end
  local ok, pose, reason = pcall(tagpose.solve, row.corners, run.camera, size, run.options)
  if not ok then return nil, tostring(pose) end
  return pose, reason
end

-- the frame's detections, as a robot's camera system hands them to the tracker
local function detections_of(run, group)
  local dets = run.detections
  for k = 1, #group do
    local row = group[k]
    local d = dets[k] or {}
    d.id, d.corners, dets[k] = row.tag, row.corners, d
  end
  for k = #group + 1, #dets do dets[k] = nil end
  return dets
end

-- the pose of each row of a group, its reason, track, and smoothed choice
local function solve_group(run, group, time)
  local tracking = run.opt.track
  local tracker = run.tracker
  local seen
  if tracking then
    seen = tracker:update(detections_of(run, group), time)
  else
    seen = tracker:assign(detections_of(run, group), time)
  end
  clock_model.check(run.clock, group, time, seen, tracker.max_gap)
  if seen.restarted and run.slots then slots_model.clear(run.slots) end
  local smoothed, fed = run.smoothed, run.fed
  for k, row in ipairs(group) do
    local e = seen[k]
    row.track = e.track
    local pose, reason
    if tracking then pose, reason = e.pose, e.reason else pose, reason = solve_row(run, row) end
    if reason then
      -- the command's option where the library names its own
      reason = command.order_hint((reason:gsub("^tracker: entry %d+: ", "tracker: ")))
    end
    row.pose, row.reason = pose, reason or (not pose and "no pose") or nil
    if pose and smoothed then
      local r = fed + k
      local choice = smoothed.choice[r]
      if choice == 2 and pose.alternative then
        row.pose = pose.alternative
        run.switched = run.switched + 1
      end
      if choice > 0 then row.confidence = smoothed.confidence[r] end
    end
  end
  run.fed = fed + #group
end

-- a solved row into the summary's counts: its error, iterations and squared residuals
local function count_solved(run, pose)
  run.solved = run.solved + 1
  add(run.errors, pose.error)
  local it = pose.iterations
  run.iterations[it] = (run.iterations[it] or 0) + 1
  add(run.residuals, 4 * pose.error * pose.error)
  local p = pose.position
  add(run.distances, math.sqrt(p.x * p.x + p.y * p.y + p.z * p.z))
end

-- the rows of a group in the log's order: to the pose log, the summary's counts, the figure;
-- returns the rows solved
local function record_rows(run, group, time)
  local writer, recorder, tags = run.writer, run.recorder, run.tags
  local solved_rows = {}
  for _, row in ipairs(group) do
    run.rows = run.rows + 1
    local pose = row.pose
    if writer then writer:write(row.frame, row.tag, pose, row.confidence) end
    if pose then
      count_solved(run, pose)
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
    if recorder then
      row.slot = row.track and slots_model.slot(run.slots, row.tag, row.track, time) or 1
      recorder:add(run.main_source, row.tag, row.slot, row.frame, pose, row.confidence, time)
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
  for _, tag in ipairs(tags) do count_repeated(run, tag, by_tag[tag]) end
  local time = clock_model.time_of(run.clock, group)
  solve_group(run, group, time)
  local solved_rows = record_rows(run, group, time)
  for _, c in ipairs(run.compares) do c:match(frame, solved_rows, group, time) end
end

--- Read a corner log to its end a frame at a time (at most `MAX_GROUP` rows together): each
-- group to `on_group`, each malformed row to `on_malformed`; the reader is closed.
-- @tparam table reader a `tagpose.tools.log.corner_reader`
-- @tparam function on_group called with an array of detections of one frame
-- @tparam[opt] function on_malformed called with `{line =, reason =}`
function M.groups(reader, on_group, on_malformed)
  local group = {}
  while true do
    local det, line, reason = reader:read()
    if det == nil then break end
    if det == false then
      if on_malformed then on_malformed({ line = line, reason = reason }) end
    else
      if #group > 0 and (det.frame ~= group[1].frame or #group >= MAX_GROUP) then
        on_group(group)
        group = {}
      end
      det.fields = nil
      group[#group + 1] = det
    end
  end
  if #group > 0 then on_group(group) end
  reader:close()
end

--- Read a corner log to its end, noting its malformed rows (see `groups`).
-- @tparam table run the replay's record
-- @tparam table reader a `tagpose.tools.log.corner_reader`
function M.read(run, reader)
  M.groups(reader, function(group) M.process(run, group) end,
    function(problem) note(run.malformed, problem) end)
end

--- The first pass of `--smooth`: the tracker over the whole log, then its smoothing.
-- @tparam table opt the command's options
-- @tparam table camera
-- @tparam number|table sizes
-- @tparam table reader a `tagpose.tools.log.corner_reader` of the log (closed here)
-- @tparam table clock the frames' times (its counts are the second pass's to make)
-- @treturn table `{choice =, confidence =}` per row fed, as `tracker:smooth()` gives them
function M.forward(opt, camera, sizes, reader, clock)
  local tracker = M.tracker(opt, camera, sizes, true)
  local run = { detections = {} }
  M.groups(reader, function(group)
    tracker:update(detections_of(run, group), clock_model.time_of(clock, group))
  end)
  local choice, confidence = tracker:smooth()
  return { choice = choice, confidence = confidence }
end

return M
