--- The lines of tagpose-replay's plot: each track of `tagpose.tracker` (numbered 1, 2, 3, ...
-- for the tracker's life) drawn as a small number per tag id, its slot (`tag 0 #1`,
-- `tag 0 #2`): a new track takes the lowest slot of its id whose track has ended (unseen for
-- more than the tracker's `max_gap`, the tracker's own rule), so that a tag that comes back
-- after a long gap continues its line and the plot has as many lines per id as tags were in
-- view together.
--
-- Memory is bounded whatever the log: past `MAX` slots taken since the last sweep, the ids
-- whose tracks have all ended are dropped, then the least recently seen until at most `MAX`
-- are left (their next tracks start again from slot 1).
-- @module tagpose.tools.replay.slots

local M = {}

--- Most slots taken between two sweeps, and most kept by a sweep.
M.MAX = 2000

--- An empty set of slots.
-- @tparam number gap the time (s) after which an unseen track has ended
-- @treturn table
function M.new(gap)
  return { gap = gap, by_id = {}, count = 0, added = 0, forgotten = 0 }
end

--- Forget every slot (the tracker ended every track: the time went back).
-- @tparam table set
function M.clear(set)
  set.by_id, set.count = {}, 0
end

local function older(a, b)
  if a.time ~= b.time then return a.time < b.time end
  if type(a.id) ~= type(b.id) then return type(a.id) == "number" end
  return a.id < b.id
end

-- drop the ids whose tracks have all ended, then the least recently seen down to MAX
local function sweep(set, time)
  local ids = {}
  for id, list in pairs(set.by_id) do
    if time - list.time > set.gap then
      set.by_id[id] = nil
      set.count = set.count - #list
    else
      ids[#ids + 1] = { id = id, time = list.time, n = #list }
    end
  end
  if set.count > M.MAX then
    table.sort(ids, older)
    for _, e in ipairs(ids) do
      if set.count <= M.MAX then break end
      set.by_id[e.id] = nil
      set.count = set.count - e.n
      set.forgotten = set.forgotten + e.n
    end
  end
  set.added = 0
end

--- The slot of a track of an id, seen at `time`.
-- @tparam table set
-- @param id the tag id
-- @tparam int track the tracker's track number
-- @tparam number time the frame's time (s)
-- @treturn int the slot (1, 2, ...)
function M.slot(set, id, track, time)
  local list = set.by_id[id]
  if not list then
    list = { of = {}, time = time }
    set.by_id[id] = list
  end
  list.time = time
  local s = list.of[track]
  if s then
    list[s].time = time
    return s
  end
  for k = 1, #list do
    local e = list[k]
    if time - e.time > set.gap then
      list.of[e.track] = nil
      e.track, e.time = track, time
      list.of[track] = k
      return k
    end
  end
  s = #list + 1
  list[s], list.of[track] = { track = track, time = time }, s
  set.count, set.added = set.count + 1, set.added + 1
  if set.added > M.MAX then sweep(set, time) end
  return s
end

return M
