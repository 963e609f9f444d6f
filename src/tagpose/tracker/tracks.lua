--- The live tracks of a tracker: by id, and in the order they were last seen, so that expiring
-- the unseen and evicting the least recently seen never scan the others.
--
-- A track is a record `{id =, number =, u =, v =, du =, dv =, side =, time =, state =,
-- row =}`: the tag id, the track's number (`tagpose.tracker`'s track id), the centre `(u, v)`
-- and side of its last detection (pixels), its image velocity (pixels per second), the time it
-- was last seen (s), its tracking filter's state (`tagpose.track`) and the row of its last pose
-- (for smoothing). The set keeps them in a doubly linked list from the least to the most
-- recently seen (`older`, `newer`), and per id in an array (`slot` is the track's index in it).
-- @module tagpose.tracker.tracks

local M = {}

--- An empty set.
-- @treturn table `{by_id = {}, count = 0, oldest = nil, newest = nil}`
function M.new()
  return { by_id = {}, count = 0, oldest = nil, newest = nil }
end

-- unlink t from the recency list
local function unlink(set, t)
  local older, newer = t.older, t.newer
  if older then older.newer = newer else set.oldest = newer end
  if newer then newer.older = older else set.newest = older end
  t.older, t.newer = nil, nil
end

-- link t as the most recently seen
local function push(set, t)
  local last = set.newest
  t.older, t.newer = last, nil
  if last then last.newer = t else set.oldest = t end
  set.newest = t
end

--- Add a track (as the most recently seen).
-- @tparam table set
-- @tparam table t a track record
function M.add(set, t)
  local list = set.by_id[t.id]
  if not list then
    list = {}
    set.by_id[t.id] = list
  end
  local n = #list + 1
  list[n], t.slot = t, n
  set.count = set.count + 1
  push(set, t)
end

--- Mark a track as seen now (the most recently seen).
-- @tparam table set
-- @tparam table t a track of the set
function M.touch(set, t)
  if set.newest ~= t then
    unlink(set, t)
    push(set, t)
  end
end

--- Remove a track.
-- @tparam table set
-- @tparam table t a track of the set
function M.drop(set, t)
  unlink(set, t)
  local list = set.by_id[t.id]
  local n = #list
  local last = list[n]
  list[t.slot], last.slot = last, t.slot
  list[n] = nil
  if n == 1 then set.by_id[t.id] = nil end
  set.count = set.count - 1
end

--- Remove the tracks last seen more than `gap` seconds before `time`.
-- @tparam table set
-- @tparam number time now (s)
-- @tparam number gap the longest a track may go unseen (s)
function M.expire(set, time, gap)
  local t = set.oldest
  while t and time - t.time > gap do
    M.drop(set, t)
    t = set.oldest
  end
end

--- Remove the least recently seen tracks until at most `limit` are left.
-- @tparam table set
-- @tparam int limit
function M.evict(set, limit)
  while set.count > limit do M.drop(set, set.oldest) end
end

return M
