--- A tracker of many tags: one frame's detections at a time, each physical tag's track kept.
--
-- Fed the detections of one frame with the frame's time, a tracker solves every tag (the
-- pipeline of `tagpose.solve`, run directly) and chooses its pose with its track's tracking
-- filter (`tagpose.track`: the branch of the planar ambiguity carried from frame to frame,
-- through face-on crossings); it returns each detection's pose with the id of its track
-- (`tracker:assign` returns the tracks alone, without solving):
--
-- * tags that share an id (lab tags are often all id 0) are told apart by where they are in
--   the image: a detection continues the track of its id whose predicted centre is nearest,
--   within `GATE` times the tag's side in pixels (each track is continued at most once;
--   `tagpose.tracker.associate`);
-- * a track unseen for up to `max_gap` seconds is continued when its tag comes back (the
--   filter's motion model takes the time into account); after that it is dropped, so memory
--   is bounded by the tracks alive, however many ids come and go (and never more than
--   `max_tracks`: the least recently seen go first; `tagpose.tracker.tracks`);
-- * track ids are never reused (1, 2, 3, ... for the tracker's life, `reset` included);
-- * a malformed entry (not a table, an id that is nil or NaN, corners that are not four
--   points) is skipped and reported with a reason, never raised: a detector's glitch never
--   stops the robot.
--
-- The tracker keeps its own state for every track (the filter's, the image position) and its
-- own copy of the camera, compared with the caller's at each frame (a camera changed is checked
-- again and followed): the poses it returns are the caller's to keep or change. With
-- `options.smooth`, it also keeps four numbers per detection so that `tracker:smooth()` can
-- revise every choice with the evidence of the later frames (`tagpose.tracker.smooth`): for
-- replaying a recorded log.
--
-- Times are in seconds (times that look like milliseconds are said once on standard error,
-- and in `warning`); pixels as the camera's; lengths in the unit of the tag size.
-- @module tagpose.tracker

local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local compat = require("tagpose.core.compat")
local pipeline = require("tagpose.core.pipeline")
local result = require("tagpose.result")
local solvequad = require("tagpose.core.solvequad")
local track = require("tagpose.track")
local tracks = require("tagpose.tracker.tracks")
local associate = require("tagpose.tracker.associate")
local smooth = require("tagpose.tracker.smooth")

local finish = result.finish
local centre_and_side = associate.centre_and_side
local is_finite, describe, size_of = compat.is_finite, args.describe, args.size_of

local M = {}

--- A detection continues a track when its centre is within `GATE` tag sides (pixels) of the
-- track's predicted centre.
M.GATE = 1.5
--- Default time (s) a track may go unseen and still be continued.
M.MAX_GAP = 0.5
--- Default bound on the live tracks.
M.MAX_TRACKS = 1000
--- Weight of a new frame in a track's image velocity.
M.VELOCITY_MEMORY = 0.5
--- Steps shorter than this (s) leave a track's image velocity as it was: two frames
-- microseconds apart (a camera driver that republishes) say nothing about the velocity.
M.MIN_STEP = 1e-3

local Tracker = {}
Tracker.__index = Tracker
M.Tracker = Tracker

local OPTIONS = { "method", "max_gap", "max_tracks", "smooth", "sigma", "order" }

-- Raise a misuse at the caller of the entry point (`depth`: the helpers between them).
local function raise(n, fname, message, depth)
  args.raise(n, fname, message, 3 + (depth or 0))
end

-- the call the corner-order hint names
local CALL = "tagpose.tracker.new(camera, tag_size, options)"


-- What is wrong with a tag_size argument, or nil.
local function check_sizes(tag_size)
  if type(tag_size) ~= "table" then
    if not args.is_positive(tag_size) then
      return "positive number or table of sizes expected for tag_size, got " .. describe(tag_size)
    end
    return args.check_size(tag_size, "tag_size")
  end
  local any = false
  for id, s in pairs(tag_size) do
    if type(id) ~= "number" and type(id) ~= "string" then
      return "tag_size: ids (numbers or strings) expected as keys, got " .. type(id)
    end
    local name = "tag_size[" .. tostring(id) .. "]"
    if not args.is_positive(s) then
      return name .. ": positive number expected, got " .. describe(s)
    end
    local problem = args.check_size(s, name)
    if problem then return problem end
    any = true
  end
  if not any then return "tag_size: a table with at least one size (or `default`) expected" end
  return nil
end

-- Read the options of `new` into the tracker record; raises on a misuse.
local function read_options(self, options)
  if options == nil then options = {} end
  if type(options) ~= "table" then
    raise(3, "new", "options table expected, got " .. type(options), 1)
  end
  local unknown = args.unknown_keys(options, OPTIONS, "options")
  if unknown then raise(3, "new", unknown, 1) end
  local method = options.method
  if method ~= nil and method ~= "refined" and method ~= "seed" then
    raise(3, "new", "options.method: 'refined' or 'seed' expected, got " .. describe(method), 1)
  end
  local max_gap = options.max_gap == nil and M.MAX_GAP or options.max_gap
  if not (is_finite(max_gap) and max_gap >= 0) then
    raise(3, "new", "options.max_gap: non-negative number expected, got " .. describe(max_gap), 1)
  end
  local max_tracks = options.max_tracks == nil and M.MAX_TRACKS or options.max_tracks
  if not args.is_count(max_tracks) then
    raise(3, "new", "options.max_tracks: positive integer expected, got "
      .. describe(max_tracks), 1)
  end
  local sigma = options.sigma
  if sigma ~= nil and not args.is_positive(sigma) then
    raise(3, "new", "options.sigma: positive number expected, got " .. describe(sigma), 1)
  end
  local opencv, why = args.read_order(options.order)
  if opencv == nil then raise(3, "new", why, 1) end
  -- (a gap beyond the filter's longest step is a time in milliseconds: said, not refused)
  if max_gap > track.MAX_STEP then
    io.stderr:write(("tagpose.tracker: warning: options.max_gap is %.4g s, beyond the longest"
      .. " step the tracking filter models (%g s): milliseconds? (max_gap is in seconds: 0.5,"
      .. " not 500)\n"):format(max_gap, track.MAX_STEP))
  end
  self.opencv = opencv
  self.seed, self.max_gap, self.max_tracks = method == "seed", max_gap, max_tracks
  self.recording = options.smooth == true
  if self.recording then self.recorded = {} end
  -- what the end of every solve is told (`tagpose.result`): the tracker's own, σ² for the
  -- covariance included, which also keeps the noise measured on its tracks so far
  local ctx = result.context(self.work)
  ctx.seed, ctx.sigma2, ctx.in_place = self.seed, sigma and sigma * sigma or false, true
  self.context = ctx
end

--- A tracker for one camera.
-- @tparam table camera `{fx =, fy =, cx =, cy =}` (pixels; optionally `distortion`, `model`),
--   as for `tagpose.solve`; the tracker keeps a copy (a camera changed afterwards needs a new
--   tracker)
-- @tparam number|table tag_size side of the tags' black square, or a table
--   `{[id] = size, default = size}` (a detection whose id has no size, and no default, is
--   skipped with a reason)
-- @tparam[opt] table options
--
--   - `method`: `"refined"` (the default) or `"seed"` (the report's method: one pose per tag,
--     no tracking filter);
--   - `max_gap`: seconds a track may go unseen and still be continued (default `MAX_GAP`;
--     one beyond `tagpose.track.MAX_STEP` is said on standard error: milliseconds?);
--   - `max_tracks`: bound on the live tracks (default `MAX_TRACKS`);
--   - `sigma`: the corner noise in pixels, for the poses' `covariance` (default: each track's
--     running estimate from its residuals; a new track's first pose, the single-frame default
--     of `tagpose.solve`);
--   - `order`: the corners' order, `"apriltag"` (default) or `"opencv"` (as for
--     `tagpose.solve`);
--   - `smooth`: true to record what `tracker:smooth()` needs (four numbers per detection).
-- @treturn table the tracker
-- @raise `bad argument #n to 'new' (...)` for a camera, size or option it cannot use
-- @usage
-- local tr = tagpose.tracker.new({fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5}, 0.024)
-- for _, seen in ipairs(tr:update(robot.camera_system.tags, robot.system.time)) do
--   if seen.pose then print(seen.track, seen.pose.position.z, seen.pose.confidence) end
-- end
function M.new(camera, tag_size, options)
  local problem = camera_model.check(camera)
  if problem then raise(1, "new", problem) end
  problem = check_sizes(tag_size)
  if problem then raise(2, "new", problem) end
  local self = setmetatable({
    camera = camera_model.copy(camera), -- what the solves use
    given = camera, -- the caller's camera, compared with the copy at each frame
    tag_size = tag_size,
    size = type(tag_size) ~= "table" and tag_size or nil, -- the size of every id, if one
    next_track = 1, -- the next track id (never reused)
    rows = 0, -- detections fed so far
    work = pipeline.new(), -- the pipeline's workspace
    -- per entry of a frame (reused): id, centre, side, corners (flat), why it is malformed
    ids = {}, us = {}, vs = {}, ss = {}, pxs = {}, why = {}, match = {},
  }, Tracker)
  read_options(self, options)
  self:reset()
  return self
end

--- A tracker's methods.
-- @type Tracker

--- Forget every track (the robot was moved, the experiment restarts). Track ids keep
-- counting; what `smooth` recorded is kept (a track ends here).
function Tracker:reset()
  self.live = tracks.new()
  self.time = nil -- the last frame's time
  self.frames = 0
  self.last_step, self.steady = nil, 0
end

--- The live tracks.
-- @treturn int how many
function Tracker:count()
  return self.live.count
end

-- Read entry i of a frame: its id, centre, side and corners into the frame's arrays; or the
-- reason it is malformed.
local function read_entry(self, det, i)
  self.ids[i] = nil
  if type(det) ~= "table" then
    return "tracker: entry " .. i .. " is not a detection {id =, corners =} (got "
      .. type(det) .. ")"
  end
  local id = det.id
  if id ~= id then return "tracker: entry " .. i .. " has no usable id (got NaN)" end
  if type(id) ~= "number" and type(id) ~= "string" then
    return "tracker: entry " .. i .. " has no usable id (got " .. describe(id) .. ")"
  end
  local px = self.pxs[i]
  if not px then
    px = {}
    self.pxs[i] = px
  end
  local ok, why = args.read_corners(det.corners, px, self.opencv)
  if not ok then return "tracker: entry " .. i .. ": corners: " .. why end
  -- (no track for corners that are not all finite: a detector's glitch, not a tag)
  if ok ~= true then return "tracker: entry " .. i .. ": corner " .. ok .. " is not finite" end
  self.ids[i] = id
  self.us[i], self.vs[i], self.ss[i] = centre_and_side(px)
  return nil
end

-- The frame's pose of entry i (its corners in w.px): nil and why, or the pose and, for the
-- smoothing record, the posterior of the frame's first candidate and the filter's two numbers.
local function solve(self, i, t, size, time)
  local w = self.work
  local half, camera = 0.5 * size, self.camera
  local ok, why = pipeline.prepare(w, camera)
  if not ok then return nil, why end
  local state = false -- the track's filter state (none with the report's method)
  if self.seed then
    ok, why = pipeline.seed(w, half, solvequad.TOLERANCE, solvequad.MAX_ITERATIONS)
  else
    ok, why = pipeline.refined(w, half, pipeline.REFINED_TOLERANCE, solvequad.MAX_ITERATIONS)
    state = t and t.state or track.new_state()
  end
  if not ok then return nil, why end
  local ctx = self.context
  ctx.camera, ctx.half, ctx.side, ctx.time, ctx.prior = camera, half, self.ss[i], time, state
  local p
  p, why = finish(ctx)
  if not p then return nil, why end
  if not state then return p, 1, 0.5, 0.5 end
  return p, state.first, state.back_first, state.back_second, state
end

-- Continue track t with entry i (seen at `time`), or start a new track; returns it.
local function advance(self, i, id, t, time)
  local u, v = self.us[i], self.vs[i]
  if not t then
    t = { id = id, number = self.next_track, side = self.ss[i], u = u, v = v, du = 0, dv = 0,
      time = time, state = nil, row = 0 }
    self.next_track = self.next_track + 1
    tracks.add(self.live, t)
    return t, true
  end
  local dt = time - t.time
  if dt >= M.MIN_STEP then
    local m = M.VELOCITY_MEMORY
    t.du = (1 - m) * t.du + m * (u - t.u) / dt
    t.dv = (1 - m) * t.dv + m * (v - t.v) / dt
  end
  t.u, t.v, t.side, t.time = u, v, self.ss[i], time
  if self.live.newest ~= t then tracks.touch(self.live, t) end
  return t, false
end

-- Entry i of the frame, well formed (its id), continuing track t (or nil): the number of its
-- track, true when the track starts here, and its pose or the reason it has none (with a
-- pose, its smoothing record is kept); no track for an id without a tag size (skipped).
local function detection(self, i, id, t, time, row)
  local size = self.size or size_of(self.tag_size, id)
  if not size then return nil, nil, nil, "tracker: no tag size for id " .. tostring(id) end
  -- (the pipeline reads the corners where read_entry put them)
  self.work.px = self.pxs[i]
  local p, first, a, b, state -- (none when only assigning tracks)
  if self.solving then p, first, a, b, state = solve(self, i, t, size, time) end
  local new
  t, new = advance(self, i, id, t, time)
  if state then t.state = state end
  if not p then return t.number, new, nil, args.name_order(first, CALL) end
  if self.recording then smooth.record(self.recorded, row, t.row, first, a, b) end
  t.row = row
  return t.number, new, p, nil
end

-- A time step that looks like milliseconds or frame numbers: steps beyond max_gap at a
-- steady cadence (every frame then starts new tracks). Returns a message, or nil.
local function cadence(self, dt)
  local gap = self.max_gap
  local last = self.last_step
  if dt > gap and last and last > gap and dt < 1.5 * last and last < 1.5 * dt then
    self.steady = self.steady + 1
  else
    self.steady = 0
  end
  self.last_step = dt
  if self.steady < 2 then return nil end
  return ("tracker: frames arrive %.4g time units apart, steadily, beyond max_gap (%.4g s): "
    .. "every frame starts new tracks; these times look like milliseconds or frame numbers "
    .. "(pass seconds)"):format(dt, gap)
end

local EMPTY = {}

-- `update` (solving) and `assign` (fname): the arguments checked at the caller's level.
local function feed(self, detections, time, fname, solving)
  if detections == nil then detections = EMPTY end
  if type(detections) ~= "table" then
    args.raise(1, fname, "array of detections expected, got " .. type(detections), 3)
  end
  if args.is_detection(detections) then args.raise(1, fname, args.ONE_DETECTION, 3) end
  if time ~= nil and not is_finite(time) then
    args.raise(2, fname, "finite number expected for time, got " .. describe(time), 3)
  end
  local given = self.given
  if not camera_model.same(given, self.camera) then
    -- the caller changed the camera: checked as at new, and followed
    local problem = camera_model.check(given)
    if problem then args.raise(0, fname, "the tracker's camera was changed: " .. problem, 3) end
    self.camera = camera_model.copy(given)
  end
  self.solving = solving
  -- (room for one entry, the common frame, made with the array: filled key by key a table's
  -- parts grow through a resize at each power of two; each entry is made whole, at once)
  local seen = { nil, skipped = 0 }
  if time == nil then time = (self.time or 0) + track.FRAME end
  if self.time and time < self.time then
    self:reset()
    seen.restarted = true
  end
  if self.time then seen.warning = cadence(self, time - self.time) end
  -- said on standard error too, once per tracker (the caller may never look at `warning`)
  if seen.warning and not self.warned then
    self.warned = true
    io.stderr:write("tagpose.tracker: warning: ", (seen.warning:gsub("^tracker: ", "")), "\n")
  end
  self.time = time
  self.frames = self.frames + 1
  local live = self.live
  local oldest = live.oldest
  if oldest and time - oldest.time > self.max_gap then tracks.expire(live, time, self.max_gap) end
  local n = #detections
  local base = self.rows
  self.rows = base + n
  local ids, why = self.ids, self.why
  for i = 1, n do why[i] = read_entry(self, detections[i], i) end
  local match = associate.assign(live, n, ids, self.us, self.vs, self.ss, time, M.GATE,
    self.match, self.frames)
  local skipped, recording = 0, self.recording
  for i = 1, n do
    local id, number, new, pose, reason = ids[i], nil, nil, nil, why[i]
    if id ~= nil then
      number, new, pose, reason = detection(self, i, id, match[i], time, base + i)
    else
      local det = detections[i]
      if type(det) == "table" and det.id == det.id then id = det.id end
    end
    -- (skipped: malformed, or no tag size for its id)
    if number == nil then skipped = skipped + 1 end
    seen[i] = { index = i, id = id, track = number, new = new, pose = pose, reason = reason }
    -- (a row without a pose: malformed, skipped, or no pose from its corners)
    if recording and not pose then smooth.record(self.recorded, base + i, 0, -1, 0.5, 0.5) end
  end
  seen.skipped = skipped
  if live.count > self.max_tracks then tracks.evict(live, self.max_tracks) end
  return seen
end

--- Solve one frame's detections.
-- @tparam ?{table,...} detections the frame's tags as a camera system hands them out:
--   `{id = n, corners = {c1, c2, c3, c4}}` each, a corner `{x = u, y = v}` or `{u, v}` in the
--   detection order of `tagpose.solve`; other fields are ignored. `nil` is an empty frame.
-- @tparam[opt] number time the frame's time in seconds (default: `tagpose.track.FRAME` after
--   the previous frame). A time earlier than the previous frame's ends every track first.
-- @treturn {table,...} one entry per detection, in order: `{index = i, id =, track = n,
--   pose = <a pose as `tagpose.solve` returns it> or nil, reason = <why not> or nil,
--   new = <true when the track starts here>}` (`track` is nil for a malformed entry); the
--   array's field `skipped` counts the entries skipped (malformed, or an id without a tag
--   size; an entry whose corners give no pose has a track and a reason), `restarted` is true
--   when the time went back, and `warning` says when the times look like milliseconds or frame
--   numbers (steps far beyond `max_gap` at a steady cadence; said on standard error too, the
--   first time)
-- @raise `bad argument #n to 'update' (...)` when `detections` is not an array (one detection
--   passed alone included) or `time` not a finite number
function Tracker:update(detections, time)
  return (feed(self, detections, time, "update", true))
end

--- Each detection's track without solving it: `update`'s association alone (its gate, gaps,
-- restarts and warnings; a track started here gets its filter state at its first `update`),
-- for a caller who solves the tags itself or only tells apart the tags sharing an id.
-- @tparam ?{table,...} detections as for `update`
-- @tparam[opt] number time as for `update`
-- @treturn {table,...} `update`'s entries without `pose` (with `smooth`, rows without a pose)
-- @raise `bad argument #n to 'assign' (...)` as `update`
function Tracker:assign(detections, time)
  return (feed(self, detections, time, "assign", false))
end

--- Revise every recorded choice with the evidence of the later frames of its track.
-- Needs `options.smooth`. Rows are numbered in the order the detections were fed to
-- `update` (all frames, malformed entries included).
-- @treturn {int,...} per row: 1 when the smoothed choice is the pose `update` returned, 2
--   when it is that pose's `alternative`, 0 for a row without a pose
-- @treturn {number,...} per row: the confidence of the smoothed choice (calibrated as the
--   pose's own; 0 for a row without a pose)
-- @raise when the tracker was not made with `options.smooth`
function Tracker:smooth()
  if not self.recording then
    error("tracker:smooth() needs tagpose.tracker.new(..., {smooth = true})", 2)
  end
  return smooth.run(self.recorded or EMPTY, self.rows, track.confidence)
end

return M
