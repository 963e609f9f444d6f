--- A tracker of many tags: one frame's detections at a time, each physical tag's track kept.
--
-- Fed the detections of one frame with the frame's time, a tracker solves every tag with its
-- track's last pose as the prior (`tagpose.track`'s filter: the branch of the planar
-- ambiguity carried from frame to frame, through face-on crossings) and returns each
-- detection's pose with the id of its track:
--
-- * tags that share an id (lab tags are often all id 0) are told apart by where they are in
--   the image: a detection continues the track of its id whose predicted centre is nearest,
--   within `GATE` times the tag's side in pixels (each track is continued at most once);
-- * a track unseen for up to `max_gap` seconds is continued when its tag comes back (the
--   filter's motion model takes the time into account); after that it is dropped, so memory
--   is bounded by the tracks alive, however many ids come and go (and never more than
--   `max_tracks`: the least recently seen go first);
-- * track ids are never reused (1, 2, 3, ... for the tracker's life, `reset` included);
-- * a malformed entry (not a table, an id that is nil or NaN, corners that are not four
--   points) is skipped and reported with a reason, never raised: a detector's glitch never
--   stops the robot.
--
-- With `options.smooth`, the tracker also keeps four numbers per detection so that
-- `tracker:smooth()` can revise every choice with the evidence of the later frames
-- (forward-backward over each track): for replaying a recorded log.
--
-- Times are in seconds; pixels as the camera's; lengths in the unit of the tag size.
-- @module tagpose.tracker

local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local compat = require("tagpose.core.compat")
local track = require("tagpose.track")

local sqrt, huge = math.sqrt, math.huge
local is_finite, describe = compat.is_finite, args.describe

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

local Tracker = {}
Tracker.__index = Tracker
M.Tracker = Tracker

local OPTIONS = { method = true, max_gap = true, max_tracks = true, smooth = true }

local function raise(n, fname, message)
  args.raise(n, fname, message, 3)
end

-- the tag size of an id: a number, or nil
local function size_of(sizes, id)
  if type(sizes) == "number" then return sizes end
  local s = sizes[id]
  if s == nil then s = sizes.default end
  return s
end

--- A tracker for one camera.
-- @tparam table camera `{fx =, fy =, cx =, cy =}` (pixels; optionally `distortion`, `model`),
--   as for `tagpose.solve`
-- @tparam number|table tag_size side of the tags' black square, or a table
--   `{[id] = size, default = size}` (a detection whose id has no size, and no default, is
--   skipped with a reason)
-- @tparam[opt] table options
--
--   - `method`: passed to `tagpose.solve` (`"refined"`, the default, or `"seed"`);
--   - `max_gap`: seconds a track may go unseen and still be continued (default `MAX_GAP`);
--   - `max_tracks`: bound on the live tracks (default `MAX_TRACKS`);
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
  if type(tag_size) == "table" then
    for id, s in pairs(tag_size) do
      if not (is_finite(s) and s > 0) then
        raise(2, "new", "tag_size[" .. tostring(id) .. "]: positive number expected, got "
          .. describe(s))
      end
    end
  elseif not (is_finite(tag_size) and tag_size > 0) then
    raise(2, "new", "positive number or table of sizes expected for tag_size, got "
      .. describe(tag_size))
  end
  if options == nil then options = {} end
  if type(options) ~= "table" then
    raise(3, "new", "options table expected, got " .. type(options))
  end
  for k in pairs(options) do
    if not OPTIONS[k] then raise(3, "new", "unknown option '" .. tostring(k) .. "'") end
  end
  local method = options.method
  if method ~= nil and method ~= "refined" and method ~= "seed" then
    raise(3, "new", "options.method: 'refined' or 'seed' expected, got " .. describe(method))
  end
  local max_gap = options.max_gap == nil and M.MAX_GAP or options.max_gap
  if not (is_finite(max_gap) and max_gap >= 0) then
    raise(3, "new", "options.max_gap: non-negative number expected, got " .. describe(max_gap))
  end
  local max_tracks = options.max_tracks == nil and M.MAX_TRACKS or options.max_tracks
  if not args.is_count(max_tracks) then
    raise(3, "new", "options.max_tracks: positive integer expected, got "
      .. describe(max_tracks))
  end
  local self = setmetatable({
    camera = camera,
    tag_size = tag_size,
    method = method,
    max_gap = max_gap,
    max_tracks = max_tracks,
    recording = options.smooth == true,
    next_track = 1, -- the next track id (never reused)
    rows = 0, -- detections fed so far
    solve_options = { method = method }, -- reused for every solve
  }, Tracker)
  self:reset()
  return self
end

--- A tracker's methods.
-- @type Tracker

--- Forget every track (the robot was moved, the experiment restarts). Track ids keep
-- counting; what `smooth` recorded is kept (a track ends here).
function Tracker:reset()
  self.tracks = {} -- live tracks, any order
  self.by_id = {} -- id -> array of live tracks
  self.time = nil -- the last frame's time
  self.frames = 0
end

--- The live tracks.
-- @treturn int how many
function Tracker:count()
  return #self.tracks
end

-- the centre and mean side (px) of four corners already checked, or nil when degenerate
local function centre_and_side(c)
  local u, v, s = 0, 0, 0
  for j = 1, 4 do
    local a, b = c[j], c[j % 4 + 1]
    local au, av = a[1] or a.x, a[2] or a.y
    local bu, bv = b[1] or b.x, b[2] or b.y
    u, v = u + au, v + av
    s = s + sqrt((bu - au) * (bu - au) + (bv - av) * (bv - av))
  end
  return u / 4, v / 4, s / 4
end

-- what is wrong with an entry, or nil
local scratch = {}
local function malformed(det, i)
  if type(det) ~= "table" then
    return "tracker: entry " .. i .. " is not a detection {id =, corners =} (got "
      .. type(det) .. ")"
  end
  local id = det.id
  if id ~= id then return "tracker: entry " .. i .. " has no usable id (got NaN)" end
  if type(id) ~= "number" and type(id) ~= "string" then
    return "tracker: entry " .. i .. " has no usable id (got " .. describe(id) .. ")"
  end
  local ok, why = args.read_corners(det.corners, scratch)
  if not ok then return "tracker: entry " .. i .. ": corners: " .. why end
  return nil
end

-- remove a track from the live lists
local function drop(self, t)
  local list = self.by_id[t.id]
  if list then
    for k = #list, 1, -1 do
      if list[k] == t then table.remove(list, k) end
    end
    if #list == 0 then self.by_id[t.id] = nil end
  end
  -- swap the last live track into its slot
  local all = self.tracks
  local last = all[#all]
  all[t.slot], last.slot = last, t.slot
  all[#all] = nil
end

-- integration: the pose of one detection through the public solve (lazily required: the
-- facade requires this module); the lead engineer will switch it to the internal pipeline
local function solve(corners, camera, size, options)
  local ok, pose, why = pcall(require("tagpose").solve, corners, camera, size, options)
  if not ok then return nil, "tracker: " .. tostring(pose) end
  return pose, why
end

-- record one detection for smoothing: the row of its track's previous detection, and the
-- filter's numbers (see tagpose.track: the posterior of the frame's first candidate and the
-- joint with the previous frame's)
local function record(self, row, t, pose)
  local st = pose and pose.track
  local prev_row = t and t.pose_row or 0
  local p1, a, b = 1, 0.5, 0.5
  if st and track.is_state(st) then
    p1, a, b = st[5], st[6], st[7]
  elseif pose then
    p1 = 1
  end
  if not pose then prev_row, p1 = 0, -1 end
  local r = self.recorded
  local o = 4 * (row - 1)
  r[o + 1], r[o + 2], r[o + 3], r[o + 4] = prev_row, p1, a, b
end

local pairs_d, pairs_det, pairs_track = {}, {}, {}

--- Solve one frame's detections.
-- @tparam ?{table,...} detections the frame's tags as a camera system hands them out:
--   `{id = n, corners = {c1, c2, c3, c4}}` each, a corner `{x = u, y = v}` or `{u, v}` in the
--   detection order of `tagpose.solve`; other fields are ignored. `nil` is an empty frame.
-- @tparam[opt] number time the frame's time in seconds (default: `track.FRAME` after the
--   previous frame). A time earlier than the previous frame's ends every track first.
-- @treturn {table,...} one entry per detection, in order: `{index = i, id =, track = n,
--   pose = <tagpose.solve result> or nil, reason = <why not> or nil, new = <true when the
--   track starts here>}` (`track` is nil for a malformed entry); the array's field `skipped`
--   counts the malformed entries, and `restarted` is true when the time went back
-- @raise `bad argument #n to 'update' (...)` when `detections` is not a table or `time` not a
--   finite number
function Tracker:update(detections, time)
  if detections == nil then detections = {} end
  if type(detections) ~= "table" then
    raise(1, "update", "array of detections expected, got " .. type(detections))
  end
  if time ~= nil and not is_finite(time) then
    raise(2, "update", "finite number expected for time, got " .. describe(time))
  end
  local seen = { skipped = 0 }
  if time == nil then time = (self.time or 0) + track.FRAME end
  if self.time and time < self.time then
    self:reset()
    seen.restarted = true
  end
  self.time = time
  self.frames = self.frames + 1
  -- expire the tracks unseen for too long
  local all = self.tracks
  for k = #all, 1, -1 do
    local t = all[k]
    if time - t.time > self.max_gap then drop(self, t) end
  end
  -- read the entries; candidate continuations within the gate
  local n, np = #detections, 0
  local base_row = self.rows
  self.rows = base_row + n
  if self.recording and not self.recorded then self.recorded = {} end
  local us, vs, ss = {}, {}, {}
  for i = 1, n do
    local det = detections[i]
    local why = malformed(det, i)
    local result = { index = i }
    seen[i] = result
    if why then
      result.reason = why
      if type(det) == "table" and det.id == det.id then result.id = det.id end
      seen.skipped = seen.skipped + 1
    else
      result.id = det.id
      local u, v, s = centre_and_side(det.corners)
      us[i], vs[i], ss[i] = u, v, s
      local list = self.by_id[det.id]
      for k = 1, list and #list or 0 do
        local t = list[k]
        local dt = time - t.time
        local pu, pv = t.u + t.du * dt, t.v + t.dv * dt
        local side = s > t.side and s or t.side
        local d = sqrt((u - pu) * (u - pu) + (v - pv) * (v - pv)) / side
        if d < M.GATE then
          np = np + 1
          pairs_d[np], pairs_det[np], pairs_track[np] = d, i, t
        end
      end
    end
  end
  -- greedy assignment, nearest pairs first (insertion sort: few pairs per frame)
  for a = 2, np do
    local d, di, dtk = pairs_d[a], pairs_det[a], pairs_track[a]
    local b = a - 1
    while b >= 1 and pairs_d[b] > d do
      pairs_d[b + 1], pairs_det[b + 1], pairs_track[b + 1] = pairs_d[b], pairs_det[b],
        pairs_track[b]
      b = b - 1
    end
    pairs_d[b + 1], pairs_det[b + 1], pairs_track[b + 1] = d, di, dtk
  end
  local match, taken = {}, {}
  for a = 1, np do
    local i, t = pairs_det[a], pairs_track[a]
    if not match[i] and not taken[t] then
      match[i], taken[t] = t, true
    end
  end
  for a = 1, np do pairs_track[a] = nil end
  -- solve, continue or start the tracks
  local options = self.solve_options
  for i = 1, n do
    local result = seen[i]
    if not result.reason then
      local det = detections[i]
      local id = det.id
      local size = size_of(self.tag_size, id)
      local t = match[i]
      if not size then
        result.reason = "tracker: no tag size for id " .. tostring(id)
        seen.skipped = seen.skipped + 1
        if self.recording then record(self, base_row + i, nil, nil) end
      else
        options.prior = t and t.pose or nil
        options.time = time
        local pose, why = solve(det.corners, self.camera, size, options)
        options.prior = nil
        result.pose, result.reason = pose, why
        if not t then
          t = { id = id, track = self.next_track, side = ss[i], u = us[i], v = vs[i], du = 0,
            dv = 0, time = time }
          self.next_track = self.next_track + 1
          local list = self.by_id[id]
          if not list then
            list = {}
            self.by_id[id] = list
          end
          list[#list + 1] = t
          all[#all + 1] = t
          t.slot = #all
          result.new = true
        else
          local dt = time - t.time
          if dt > 0 then
            local m = M.VELOCITY_MEMORY
            t.du = (1 - m) * t.du + m * (us[i] - t.u) / dt
            t.dv = (1 - m) * t.dv + m * (vs[i] - t.v) / dt
          end
          t.u, t.v, t.side, t.time = us[i], vs[i], ss[i], time
          result.new = false
        end
        result.track = t.track
        if self.recording then record(self, base_row + i, t, pose) end
        if pose then t.pose, t.pose_row = pose, base_row + i end
      end
    elseif self.recording then
      record(self, base_row + i, nil, nil)
    end
  end
  -- bound the live tracks: the least recently seen go first
  while #all > self.max_tracks do
    local oldest, when = nil, huge
    for k = 1, #all do
      if all[k].time < when then oldest, when = all[k], all[k].time end
    end
    drop(self, oldest)
  end
  return seen
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
  local r = self.recorded or {}
  local rows = self.rows
  local choice, confidence, ps = {}, {}, {}
  for row = rows, 1, -1 do
    local o = 4 * (row - 1)
    local prev_row, p1, a, b = r[o + 1], r[o + 2], r[o + 3], r[o + 4]
    if p1 == nil or p1 < 0 then
      choice[row], confidence[row] = 0, 0
    else
      local p = ps[row]
      if p == nil then p = p1 end
      ps[row] = nil
      -- the causal pose is the first candidate when p1 >= 0.5
      local first = p1 >= 0.5
      if (p >= 0.5) == first then
        choice[row] = 1
      else
        choice[row] = 2
      end
      local q = p >= 0.5 and p or 1 - p
      confidence[row] = track.confidence(q)
      if prev_row > 0 then ps[prev_row] = a * p + b * (1 - p) end
    end
  end
  return choice, confidence
end

return M
