--- The pose logs tagpose-replay compares with (`--compare`): read alongside the corner log in
-- frame order, matched with the solved rows by frame and tag (nearest position first) to
-- measure the position and rotation differences, and drawn dashed on the figure.
--
-- A compared row is drawn on the line of the replay's track it is matched with, so that the
-- dashed line of `tag 0 #2` is the one that belongs with `tag 0 #2` (the tracks are the
-- tracker's: the plot has one association). A row matched with no solved row takes the line
-- of a row of its frame and tag left over (a row that failed), else the line its tag last
-- had in this log, else the first. On a figure over time, a row is drawn at its frame's time
-- in the corner log, a frame the corner log does not have at the time interpolated between
-- the two frames around it (from the last two at the end; before the first, at the frame
-- rate).
-- @module tagpose.tools.replay.compare

local log = require("tagpose.tools.log")
local stats = require("tagpose.tools.replay.stats")
local command = require("tagpose.tools.replay.command")
local frames = require("tagpose.tools.replay.frames")
local nearest = require("tagpose.tools.replay.nearest")

local sqrt, asin, deg, min, huge = math.sqrt, math.asin, math.deg, math.min, math.huge
local add, note = stats.add, stats.note

local MAX_GROUP, MAX_IDS = frames.MAX_GROUP, frames.MAX_IDS

local M = {}

--- Rotations more than this many degrees apart are counted (`apart`): a row whose rotation is
-- this far from the truth is on the wrong branch of the planar ambiguity (as
-- `examples/accuracy.lua` counts its flips).
M.APART = 30

-- the rotation between two quaternions, degrees
local function rotation_difference(a, b)
  local na = sqrt((a.w * a.w) + (a.x * a.x) + (a.y * a.y) + (a.z * a.z))
  local nb = sqrt((b.w * b.w) + (b.x * b.x) + (b.y * b.y) + (b.z * b.z))
  local s = (a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z) < 0 and -1 or 1
  local dw, dx = a.w / na - s * b.w / nb, a.x / na - s * b.x / nb
  local dy, dz = a.y / na - s * b.y / nb, a.z / na - s * b.z / nb
  local chord = sqrt(dw * dw + dx * dx + dy * dy + dz * dz)
  return deg(4 * asin(min(1, chord / 2)))
end

local Compare = {}
Compare.__index = Compare

--- Open a pose log to compare with.
-- @tparam string path
-- @tparam[opt] table recorder the figure's `plot.recorder`, to draw the log on
-- @tparam[opt=30] number fps the frame rate, for the time of a row before the corner log's
--   first frame on a figure over time
-- @treturn table the log: `path`, `matched` (rows matched), `dt` and `dr` (histograms of the
--   position and rotation differences), `apart` (rows matched whose rotations are more than
--   `APART` degrees apart: against a truth file, the wrong rows), `problems` (a tally of its
--   malformed rows),
--   `out_of_order`, `first_out_of_order`; `match(frame, solved[, group[, time]])`, `finish()`
-- @return nil, string when it cannot be read
function M.open(path, recorder, fps)
  local reader, err = log.pose_reader(path)
  if not reader then return nil, err:find(path, 1, true) and err or path .. ": " .. err end
  local label = command.basename(path):gsub("%.csv$", "")
  local self = setmetatable({ path = path, reader = reader, source = recorder and
    recorder:source(label), recorder = recorder, last_slot = {}, slotted = 0,
    problems = stats.tally(), dt = stats.histogram(), dr = stats.histogram(), matched = 0,
    apart = 0, fps = fps or 30, times = {},
    frame = nil, rows = {}, last = nil, out_of_order = 0, first_out_of_order = nil,
    lookahead = nil, done = false }, Compare)
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

-- draw a row of this log on the line `slot` (nil: its tag's last, else the first)
function Compare:draw(e, slot)
  if not self.recorder or e.drawn then return end
  e.drawn = true
  local last = self.last_slot
  if slot then
    if last[e.tag] == nil then
      -- (the tags remembered stay bounded: past MAX_IDS they are forgotten)
      if self.slotted >= MAX_IDS then
        last, self.slotted = {}, 0
        self.last_slot = last
      end
      self.slotted = self.slotted + 1
    end
    last[e.tag] = slot
  end
  self.recorder:add(self.source, e.tag, slot or last[e.tag] or 1, e.frame, e.pose, nil,
    self:time_of(e.frame))
end

-- the time of a frame: the corner log's, else interpolated between the last two frames it
-- gave (before its first, at the frame rate); nil before any
function Compare:time_of(frame)
  local t = self.times
  if not t.f1 then return nil end
  if frame == t.f1 then return t.t1 end
  if t.f0 then return t.t0 + (frame - t.f0) * (t.t1 - t.t0) / (t.f1 - t.f0) end
  return t.t1 + (frame - t.f1) / self.fps
end

-- consume the rows before `frame`, drawing them
function Compare:skip_to(frame)
  while true do
    local e = self:peek()
    if not e or e.frame >= frame then break end
    self.lookahead = nil
    if self.last and e.frame < self.last then
      self.out_of_order = self.out_of_order + 1
      self.first_out_of_order = self.first_out_of_order or e.line
    end
    self.last = e.frame
    self:draw(e)
  end
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
      self:draw(e)
    end
  end
  self.frame, self.rows = frame, rows
  return rows
end

-- draw the rows of a frame: on the line of the solved row each is matched with, or of a row
-- of its tag left over (in order), or as `draw` does
function Compare:draw_frame(rows, group, taken)
  local left = {}
  for _, row in ipairs(group) do
    if not taken[row] then
      local list = left[row.tag] or { next = 1 }
      left[row.tag] = list
      list[#list + 1] = row
    end
  end
  for _, e in ipairs(rows) do
    local slot = e.partner and e.partner.slot
    if not slot and not e.drawn then
      local list = left[e.tag]
      local row = list and list[list.next]
      if row then list.next, slot = list.next + 1, row.slot end
    end
    self:draw(e, slot)
  end
end

--- Match the solved rows of a frame (entries `{tag =, pose =, slot =}`) with this log's,
-- nearest first, each row of either at most once; then draw this log's rows of the frame.
-- @tparam number frame
-- @tparam {table,...} solved
-- @tparam[opt] {table,...} group every row of the frame (solved or not), for the lines of the
--   rows matched with none
-- @tparam[opt] number time the frame's time (s), for a figure over time
function Compare:match(frame, solved, group, time)
  local t = self.times
  if time ~= nil and frame ~= t.f1 then
    t.f0, t.t0, t.f1, t.t1 = t.f1, t.t1, frame, time
  end
  local rows = self:take(frame)
  if #rows == 0 then return end
  -- per tag: the solved rows and this log's rows not yet matched, each in its order
  local by_tag, tags = {}, {}
  for k, s in ipairs(solved) do
    local set = by_tag[s.tag]
    if not set then
      set = { ks = {}, a = {}, is = {}, b = {} }
      by_tag[s.tag], tags[#tags + 1] = set, s.tag
    end
    set.ks[#set.ks + 1], set.a[#set.a + 1] = k, s.pose.position
  end
  for i, e in ipairs(rows) do
    local set = by_tag[e.tag]
    if set and e.pose and not e.used then
      set.is[#set.is + 1], set.b[#set.b + 1] = i, e.pose.position
    end
  end
  local taken = {}
  for _, tag in ipairs(tags) do
    local set = by_tag[tag]
    local ka, kb, ds = nearest.match(set.a, set.b)
    for p = 1, #ka do
      local s, e = solved[set.ks[ka[p]]], rows[set.is[kb[p]]]
      e.used, e.partner, taken[s] = true, s, true
      self.matched = self.matched + 1
      add(self.dt, ds[p])
      local dr = rotation_difference(s.pose.quaternion, e.pose.quaternion)
      add(self.dr, dr)
      if dr > M.APART then self.apart = self.apart + 1 end
    end
  end
  if self.recorder then self:draw_frame(rows, group or solved, taken) end
end

--- Consume (and draw) the rest of the log.
function Compare:finish()
  self:take(huge)
end

return M
