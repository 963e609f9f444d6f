--- Which live track each detection of a frame continues: gate, then assign.
--
-- A detection may continue a live track of its id whose predicted centre (its last centre moved
-- by its image velocity over the time since) lies within `gate` times the larger of the two
-- sides (pixels). Of those, each detection keeps its `CANDIDATES` nearest; the pairs, nearest
-- first, are assigned greedily, each detection and each track at most once. The work is linear
-- in the detections times the live tracks of their id, and the sort is over at most
-- `CANDIDATES` pairs per detection: 150 detections of one id crowded together cost about as
-- much as 150 separate ones.
--
-- Detections are described by parallel arrays indexed by their place in the frame: `ids[i]`
-- (nil for a malformed entry), `us[i]`, `vs[i]` (centre) and `ss[i]` (side), pixels.
-- @module tagpose.tracker.associate

local sqrt = math.sqrt
local sort = table.sort

local M = {}

--- Most candidate tracks a detection keeps (its nearest within the gate).
M.CANDIDATES = 8

-- the pairs of a frame, as parallel arrays, and their order
local pair_d, pair_det, pair_track, order = {}, {}, {}, {}

local function nearer(a, b)
  local da, db = pair_d[a], pair_d[b]
  if da ~= db then return da < db end
  return a < b
end

-- the candidate pairs of detection i among the tracks `list`, appended from np; returns np
local function gate(i, u, v, s, list, time, limit, np)
  local first = np + 1
  for k = 1, #list do
    local t = list[k]
    local dt = time - t.time
    local pu, pv = t.u + t.du * dt, t.v + t.dv * dt
    local side = s > t.side and s or t.side
    local d = sqrt((u - pu) * (u - pu) + (v - pv) * (v - pv)) / side
    if d < limit then
      -- keep the nearest CANDIDATES of this detection, in order (insertion into a short run)
      local last = np
      if np - first + 1 < M.CANDIDATES then
        np = np + 1
        last = np
      elseif d >= pair_d[np] then
        last = nil
      end
      if last then
        local j = last - 1
        while j >= first and pair_d[j] > d do
          pair_d[j + 1], pair_det[j + 1], pair_track[j + 1] = pair_d[j], pair_det[j],
            pair_track[j]
          j = j - 1
        end
        pair_d[j + 1], pair_det[j + 1], pair_track[j + 1] = d, i, t
      end
    end
  end
  return np
end

--- The centre and mean side of four corners (pixels): what a detection is gated by.
-- @tparam {number,...} px the corners, flat (`u1, v1, ..., u4, v4`)
-- @treturn number u
-- @treturn number v
-- @treturn number the mean of the four sides
function M.centre_and_side(px)
  local u, v, s = 0, 0, 0
  for j = 1, 7, 2 do
    local au, av = px[j], px[j + 1]
    local k = j < 7 and j + 2 or 1
    local bu, bv = px[k], px[k + 1]
    u, v = u + au, v + av
    s = s + sqrt((bu - au) * (bu - au) + (bv - av) * (bv - av))
  end
  return u / 4, v / 4, s / 4
end

--- Assign the detections of a frame to live tracks.
-- @tparam table set the live tracks (`tagpose.tracker.tracks`)
-- @tparam int n the frame's entries
-- @tparam table ids the entries' ids (nil: malformed)
-- @tparam table us centres' u
-- @tparam table vs centres' v
-- @tparam table ss sides
-- @tparam number time the frame's time (s)
-- @tparam number limit the gate, in sides
-- @tparam table match filled: `match[i]` the track detection i continues (nil: none)
-- @tparam number stamp a number not used in an earlier call (a track assigned here gets it as
--   its `taken`)
-- @treturn table match
function M.assign(set, n, ids, us, vs, ss, time, limit, match, stamp)
  local by_id, np = set.by_id, 0
  for i = 1, n do
    match[i] = nil
    local id = ids[i]
    local list = id ~= nil and by_id[id]
    if list then np = gate(i, us[i], vs[i], ss[i], list, time, limit, np) end
  end
  if np < 2 then
    -- (one pair, the common frame of one tag: its own order, no sort)
    if np == 1 then
      local t = pair_track[1]
      match[pair_det[1]], t.taken = t, stamp
      pair_track[1] = nil
    end
    return match
  end
  for a = 1, np do order[a] = a end
  for a = np + 1, #order do order[a] = nil end
  sort(order, nearer)
  for r = 1, np do
    local a = order[r]
    local i, t = pair_det[a], pair_track[a]
    if not match[i] and t.taken ~= stamp then
      match[i], t.taken = t, stamp
    end
  end
  for a = 1, np do pair_track[a] = nil end
  return match
end

return M
