--- Tracks that keep apart the tags sharing an id in a frame (see `tagpose.tools.plot.tracker`,
-- which this is).
--
-- A tracker is `{keep =, max_tracks =, tracks = {[id] = {track, ...}}}`, a track
-- `{slot =, frame =, matched =, point =, gate =}` (and whatever fields its caller keeps in it).
-- @module tagpose.tools.plot.tracker

local compat = require("tagpose.core.compat")

local is_finite = compat.is_finite

local M = {}

--- `tagpose.tools.plot.by_tag` (documented there).
-- @tparam {table,...} rows
-- @tparam[opt] int first
-- @tparam[opt] int last
-- @treturn table tag → its rows
-- @treturn {any,...} the tags in the order they come
function M.by_tag(rows, first, last)
  local by_tag, tags = {}, {}
  for k = first or 1, last or #rows do
    local row = rows[k]
    local tag = row.tag
    if tag ~= nil then
      local list = by_tag[tag]
      if not list then
        list = {}
        by_tag[tag] = list
        tags[#tags + 1] = tag
      end
      list[#list + 1] = row
    end
  end
  return by_tag, tags
end

local Tracker = {}
Tracker.__index = Tracker

--- `tagpose.tools.plot.tracker` (documented there).
-- @tparam[opt] table options
-- @treturn table the tracker
function M.new(options)
  options = options or {}
  return setmetatable({ keep = options.keep or 1, max_tracks = options.max_tracks or 16,
    tracks = {} }, Tracker)
end

local function finite_point(p)
  if type(p) ~= "table" then return false end
  for i = 1, #p do
    if not is_finite(p[i]) then return false end
  end
  return #p > 0
end

-- the tracks of a list seen within `keep` frames before `frame` (not after: the log went back)
local function live(list, frame, keep)
  local out = {}
  for _, t in ipairs(list) do
    local age = frame - t.frame
    if (age >= 0 and age <= keep) then out[#out + 1] = t end
  end
  return out
end

-- the pairs of a point and a live track not yet matched in this frame, within the track's
-- gate, nearest first: {{d =, point =, track =}, ...} (d the squared distance, point and
-- track indices)
local function nearest_pairs(points, list, frame)
  local pairs_ = {}
  for i = 1, #points do
    local p = points[i]
    if finite_point(p) then
      for k, t in ipairs(list) do
        if t.matched ~= frame then
          local d = 0
          for c = 1, #p do d = d + (p[c] - (t.point[c] or 0)) ^ 2 end
          local gate = t.gate
          if gate == nil or d <= gate * gate then
            pairs_[#pairs_ + 1] = { d = d, point = i, track = k }
          end
        end
      end
    end
  end
  table.sort(pairs_, function(a, b)
    if a.d ~= b.d then return a.d < b.d end
    if a.point ~= b.point then return a.point < b.point end
    return a.track < b.track
  end)
  return pairs_
end

-- a new track in list for each point left without one, up to max_tracks, in the lowest free
-- slot
local function start_tracks(list, points, slots, tracks, max_tracks)
  for i = 1, #points do
    local p = points[i]
    if not slots[i] and finite_point(p) and #list < max_tracks then
      local used = {}
      for _, t in ipairs(list) do used[t.slot] = true end
      local slot = 1
      while used[slot] do slot = slot + 1 end
      local t = { slot = slot }
      list[#list + 1] = t
      slots[i], tracks[i] = slot, t
    end
  end
end

--- The tracks of the points of one id in a frame.
-- @tparam number frame
-- @param id
-- @tparam {table|false,...} points `{x, y[, z][, gate = r]}` each
-- @treturn {int,...} the slot of each point (nil: no track)
-- @treturn {table,...} the track of each point
function Tracker:assign(frame, id, points)
  local list = self.tracks[id]
  local slots, tracks = {}, {}
  list = list and live(list, frame, self.keep) or {}
  local taken = {}
  for _, pr in ipairs(nearest_pairs(points, list, frame)) do
    local i, t = pr.point, list[pr.track]
    if not slots[i] and not taken[t] then
      taken[t] = true
      slots[i], tracks[i] = t.slot, t
    end
  end
  start_tracks(list, points, slots, tracks, self.max_tracks)
  for i = 1, #points do
    local t = tracks[i]
    if t then
      t.frame, t.matched = frame, frame
      t.point, t.gate = points[i], points[i].gate
    end
  end
  if #list == 0 then list = nil end
  self.tracks[id] = list
  return slots, tracks
end

return M
