--- The pose logs tagpose-replay compares with (`--compare`): read alongside the corner log in
-- frame order, drawn dashed on the figure, and matched with the solved rows by frame and tag
-- (nearest first) to measure the position and rotation differences.
-- @module tagpose.tools.replay.compare

local log = require("tagpose.tools.log")
local plot = require("tagpose.tools.plot")
local stats = require("tagpose.tools.replay.stats")
local command = require("tagpose.tools.replay.command")
local frames = require("tagpose.tools.replay.frames")

local sqrt, asin, deg, min, huge = math.sqrt, math.asin, math.deg, math.min, math.huge
local add, note = stats.add, stats.note

local MAX_GROUP = frames.MAX_GROUP

local M = {}

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

local Compare = {}
Compare.__index = Compare

--- Open a pose log to compare with.
-- @tparam string path
-- @tparam[opt] table recorder the figure's `plot.recorder`, to draw the log on
-- @treturn table the log: `path`, `matched` (rows matched), `dt` and `dr` (histograms of the
--   position and rotation differences), `problems` (a tally of its malformed rows),
--   `out_of_order`, `first_out_of_order`; `match(frame, solved)`, `finish()`
-- @return nil, string when it cannot be read
function M.open(path, recorder)
  local reader, err = log.pose_reader(path)
  if not reader then return nil, err:find(path, 1, true) and err or path .. ": " .. err end
  local label = command.basename(path):gsub("%.csv$", "")
  local self = setmetatable({ path = path, reader = reader, source = recorder and
    recorder:source(label), recorder = recorder, tracker = plot.tracker(),
    track_count = frames.track_count(),
    problems = stats.tally(), dt = stats.histogram(), dr = stats.histogram(), matched = 0,
    frame = nil, rows = {}, last = nil, out_of_order = 0, first_out_of_order = nil,
    unmatched_frame = 0, lookahead = nil, done = false }, Compare)
  return self
end

-- the next entry of the log, not taken (nil at the end; malformed rows noted)
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
  local by_tag, tags = plot.by_tag(rows)
  for _, tag in ipairs(tags) do
    local list = by_tag[tag]
    local points = {}
    for k, e in ipairs(list) do points[k] = position_point(e.pose) end
    local known = self.tracker.tracks[tag]
    local slots = self.tracker:assign(frame, tag, points)
    frames.bound_tracks(self.tracker, self.track_count, frame, known and #known or 0, tag)
    for k, e in ipairs(list) do
      self.recorder:add(self.source, tag, slots[k] or 1, frame, e.pose)
    end
  end
end

-- consume the rows before `frame`, drawing them a frame at a time
function Compare:skip_to(frame)
  local pending, pending_frame = {}, nil
  while true do
    local e = self:peek()
    if not e or e.frame >= frame then break end
    self.lookahead = nil
    if self.last and e.frame < self.last then
      self.out_of_order = self.out_of_order + 1
      self.first_out_of_order = self.first_out_of_order or e.line
    end
    self.last = e.frame
    if e.frame ~= pending_frame or #pending >= MAX_GROUP then
      if pending_frame ~= nil then self:draw(pending_frame, pending) end
      pending = {}
    end
    pending_frame = e.frame
    pending[#pending + 1] = e
  end
  if pending_frame ~= nil then self:draw(pending_frame, pending) end
end

-- consume the rows before `frame` (drawn only), then gather those of `frame`
function Compare:take(frame)
  if self.frame == frame then return self.rows end
  self:skip_to(frame)
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

--- Match the solved rows of a frame (entries `{tag =, pose =}`) with this log's, nearest
-- first, each row of either at most once.
-- @tparam number frame
-- @tparam {table,...} solved
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
      pairs_[#pairs_ + 1] = { d = distance(s.pose.position, rows[i].pose.position), k = k, i = i }
    end
  end
  table.sort(pairs_, function(a, b)
    if a.d ~= b.d then return a.d < b.d end
    if a.k ~= b.k then return a.k < b.k end
    return a.i < b.i
  end)
  local used = {}
  for _, p in ipairs(pairs_) do
    local k, i = p.k, p.i
    if not used[k] and not rows[i].used then
      used[k], rows[i].used = true, true
      self.matched = self.matched + 1
      add(self.dt, p.d)
      add(self.dr, rotation_difference(solved[k].pose.quaternion, rows[i].pose.quaternion))
    end
  end
end

--- Consume (and draw) the rest of the log.
function Compare:finish()
  self:take(huge)
end

return M
