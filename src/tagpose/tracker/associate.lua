--- Which live track each detection of a frame continues: gate, then assign.
--
-- A detection may continue a live track of its id whose predicted centre (its last centre moved
-- by its image velocity over the time since) lies within `gate` times the larger of the two
-- sides (pixels). Of those, each detection keeps its `CANDIDATES` nearest (ties: the track
-- added to the id's list first); the pairs, nearest first, are assigned greedily, each
-- detection and each track at most once.
--
-- The work is O(N log N) a frame for N detections and tracks: an id with at most `LINEAR` live
-- tracks is gated by a look at each of them; one with more, by a k-d tree of its tracks'
-- predicted centres built once in the frame (a subtree whose nearest point is farther than the
-- gate, or than the detection's `CANDIDATES`-th nearest so far, is not entered), so that 1000
-- detections of one id crowded together cost about what 1000 of separate ids do. The sort is
-- over at most `CANDIDATES` pairs per detection, and none for a frame of one pair.
--
-- Detections are described by parallel arrays indexed by their place in the frame: `ids[i]`
-- (nil for a malformed entry), `us[i]`, `vs[i]` (centre) and `ss[i]` (side), pixels.
-- @module tagpose.tracker.associate

local sqrt, floor = math.sqrt, math.floor
local sort = table.sort

local M = {}

--- Most candidate tracks a detection keeps (its nearest within the gate).
M.CANDIDATES = 8
--- Most live tracks of one id gated by a look at each (more: through a k-d tree).
M.LINEAR = 32
--- Most tracks in a leaf of the k-d tree.
M.LEAF = 6

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

-- The k-d trees of a frame: per id with more than `LINEAR` live tracks (`trees[id]`, its root
-- node), over points that hold a track's predicted centre, its side, its place in the id's list
-- and the track; `idx` orders the points, a node is a run `lo..hi` of it with its two halves
-- (`left` 0: a leaf), the bounds of its centres, its largest side and its least place.
local trees, any_tree = {}, false
local pu, pv, pside, pslot, ptrack, idx = {}, {}, {}, {}, {}, {}
local nlo, nhi, nleft, nright = {}, {}, {}, {}
local nminu, nmaxu, nminv, nmaxv, nside, nslot = {}, {}, {}, {}, {}, {}
local npoints, nnodes = 0, 0

-- Is point a before point b along `coord` (pu or pv; ties: the place in the list)?
local function before(a, b, coord)
  local ca, cb = coord[a], coord[b]
  return ca < cb or (ca == cb and pslot[a] < pslot[b])
end

-- Reorder idx[lo..hi] so that idx[k] is the point of rank k along `coord`, those before it
-- to its left (a quickselect: the median of three as the pivot, Lomuto's partition, which
-- ends whatever the comparisons say).
local function select(lo, hi, k, coord)
  while hi > lo do
    local m = floor((lo + hi) / 2)
    if before(idx[m], idx[lo], coord) then idx[m], idx[lo] = idx[lo], idx[m] end
    if before(idx[hi], idx[lo], coord) then idx[hi], idx[lo] = idx[lo], idx[hi] end
    if before(idx[m], idx[hi], coord) then idx[m], idx[hi] = idx[hi], idx[m] end
    local pivot, i = idx[hi], lo
    for j = lo, hi - 1 do
      if before(idx[j], pivot, coord) then
        idx[i], idx[j] = idx[j], idx[i]
        i = i + 1
      end
    end
    idx[i], idx[hi] = idx[hi], idx[i]
    if i == k then return end
    if k < i then hi = i - 1 else lo = i + 1 end
  end
end

-- The node of idx[lo..hi] and its subtree; returns the node.
local function build(lo, hi)
  nnodes = nnodes + 1
  local node = nnodes
  local p = idx[lo]
  local minu, maxu, minv, maxv, side, slot = pu[p], pu[p], pv[p], pv[p], pside[p], pslot[p]
  for r = lo + 1, hi do
    p = idx[r]
    local u, v = pu[p], pv[p]
    if u < minu then minu = u end
    if u > maxu then maxu = u end
    if v < minv then minv = v end
    if v > maxv then maxv = v end
    if pside[p] > side then side = pside[p] end
    if pslot[p] < slot then slot = pslot[p] end
  end
  nlo[node], nhi[node], nminu[node], nmaxu[node], nminv[node], nmaxv[node] = lo, hi, minu,
    maxu, minv, maxv
  nside[node], nslot[node], nleft[node], nright[node] = side, slot, 0, 0
  if hi - lo >= M.LEAF then
    local mid = floor((lo + hi) / 2)
    select(lo, hi, mid, maxu - minu >= maxv - minv and pu or pv)
    nleft[node] = build(lo, mid)
    nright[node] = build(mid + 1, hi)
  end
  return node
end

-- The k-d tree of the tracks `list` at `time`: its root. (Only tracks whose predicted centre
-- is finite: no other is within a gate.)
local function tree(list, time)
  local first = npoints + 1
  for k = 1, #list do
    local t = list[k]
    local dt = time - t.time
    local u, v = t.u + t.du * dt, t.v + t.dv * dt
    if u - u == 0 and v - v == 0 then
      npoints = npoints + 1
      local p = npoints
      pu[p], pv[p], pside[p], pslot[p], ptrack[p], idx[p] = u, v, t.side, k, t, p
    end
  end
  if npoints < first then return 0 end
  return build(first, npoints)
end

-- the nearest tracks of one detection: distance, place in the list, track (at most CANDIDATES,
-- nearest first), and the stack of nodes to visit with their bounds
local best_d, best_slot, best_track = {}, {}, {}
local stack, stack_lb = {}, {}

-- The least distance (in sides) from (u, v) of side s to a track of a node: no more than any of
-- its tracks' (each step of the arithmetic is monotonic).
local function bound(node, u, v, s)
  local du, dv = 0, 0
  if u < nminu[node] then du = nminu[node] - u elseif u > nmaxu[node] then du = u - nmaxu[node] end
  if v < nminv[node] then dv = nminv[node] - v elseif v > nmaxv[node] then dv = v - nmaxv[node] end
  local side = nside[node]
  if s > side then side = s end
  return sqrt(du * du + dv * dv) / side
end

-- The candidate pairs of detection i among the tracks of the tree `root`, appended from np
-- (as `gate` appends them); returns np.
local function gate_tree(i, u, v, s, root, limit, np)
  local most, n, top = M.CANDIDATES, 0, 1
  stack[1], stack_lb[1] = root, bound(root, u, v, s)
  while top > 0 do
    local node, lb = stack[top], stack_lb[top]
    top = top - 1
    -- (a node that cannot hold a nearer track, or as near with an earlier place, is left)
    if lb < limit and not (n == most and (lb > best_d[n] or (lb == best_d[n]
      and nslot[node] >= best_slot[n]))) then
      local left = nleft[node]
      if left == 0 then
        for r = nlo[node], nhi[node] do
          local p = idx[r]
          local side = pside[p]
          if s > side then side = s end
          local du, dv = u - pu[p], v - pv[p]
          local d = sqrt(du * du + dv * dv) / side
          local k = pslot[p]
          if d < limit and (n < most or d < best_d[n] or (d == best_d[n] and k < best_slot[n]))
          then
            if n < most then n = n + 1 end
            local j = n - 1
            while j >= 1 and (best_d[j] > d or (best_d[j] == d and best_slot[j] > k)) do
              best_d[j + 1], best_slot[j + 1], best_track[j + 1] = best_d[j], best_slot[j],
                best_track[j]
              j = j - 1
            end
            best_d[j + 1], best_slot[j + 1], best_track[j + 1] = d, k, ptrack[p]
          end
        end
      else
        -- the nearer half visited first (pushed last)
        local right = nright[node]
        local a, b = bound(left, u, v, s), bound(right, u, v, s)
        if a <= b then
          stack[top + 1], stack_lb[top + 1], stack[top + 2], stack_lb[top + 2] = right, b, left, a
        else
          stack[top + 1], stack_lb[top + 1], stack[top + 2], stack_lb[top + 2] = left, a, right, b
        end
        top = top + 2
      end
    end
  end
  for j = 1, n do
    np = np + 1
    pair_d[np], pair_det[np], pair_track[np] = best_d[j], i, best_track[j]
    best_track[j] = nil
  end
  return np
end

--- The centre and mean side of four corners (pixels): what a detection is gated by.
-- @tparam {number,...} px the corners, flat (`u1, v1, ..., u4, v4`)
-- @treturn number u
-- @treturn number v
-- @treturn number the mean of the four sides
function M.centre_and_side(px)
  -- (written out: the sums in the order of a loop over the corners, from 0)
  local u1, v1, u2, v2, u3, v3, u4, v4 = px[1], px[2], px[3], px[4], px[5], px[6], px[7], px[8]
  local du1, dv1, du2, dv2 = u2 - u1, v2 - v1, u3 - u2, v3 - v2
  local du3, dv3, du4, dv4 = u4 - u3, v4 - v3, u1 - u4, v1 - v4
  local s = sqrt(du1 * du1 + dv1 * dv1) + sqrt(du2 * du2 + dv2 * dv2)
    + sqrt(du3 * du3 + dv3 * dv3) + sqrt(du4 * du4 + dv4 * dv4)
  return (0 + u1 + u2 + u3 + u4) / 4, (0 + v1 + v2 + v3 + v4) / 4, s / 4
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
  if any_tree then
    for id in pairs(trees) do trees[id] = nil end
    for p = 1, npoints do ptrack[p] = nil end
    any_tree, npoints, nnodes = false, 0, 0
  end
  for i = 1, n do
    match[i] = nil
    local id = ids[i]
    local list = id ~= nil and by_id[id]
    if list then
      if #list <= M.LINEAR then
        np = gate(i, us[i], vs[i], ss[i], list, time, limit, np)
      else
        local root = trees[id]
        if not root then
          root = tree(list, time)
          trees[id], any_tree = root, true
        end
        if root > 0 then np = gate_tree(i, us[i], vs[i], ss[i], root, limit, np) end
      end
    end
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
