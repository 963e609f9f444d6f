--- The nearest-first matching of two sets of positions, in O(N log N) for sets of N well
-- spread positions: the pairs that taking all pairs in order of distance (ties: the lower
-- index of the first set, then of the second), each position of either set at most once,
-- would give, found without listing the N^2 pairs.
--
-- The pair nearest first is the pair that is each other's nearest (in that order), and
-- so is every pair that such a greedy matching keeps: a pair that is each other's nearest
-- among the positions left is matched, and the rest matched alike (the nearest-neighbour
-- chain). Each nearest is asked of a k-d tree of the other set, from which matched positions
-- are taken out; positions given more than once are one leaf of the tree, whose indices are
-- taken in increasing order. The distances are computed as the caller's `sqrt(dx^2 + dy^2 +
-- dz^2)`, and the tree prunes a branch only when its plane is farther than the best (never on
-- an equal distance), so that the result is the greedy matching's exactly. A few positions
-- (at most `SMALL` pairs) are matched by listing every pair.
-- @module tagpose.tools.replay.nearest

local sqrt, floor, huge, sort = math.sqrt, math.floor, math.huge, table.sort

local M = {}

-- the distance the replay measures (the same operations in the same order)
local function distance(p, q)
  local dx, dy, dz = p.x - q.x, p.y - q.y, p.z - q.z
  return sqrt(dx * dx + dy * dy + dz * dz)
end
M.distance = distance

local AXES = { "x", "y", "z" }

local function by_position(a, b)
  local pa, pb = a.p, b.p
  if pa.x ~= pb.x then return pa.x < pb.x end
  if pa.y ~= pb.y then return pa.y < pb.y end
  if pa.z ~= pb.z then return pa.z < pb.z end
  return a.i < b.i
end

local sorters = {}
for _, axis in ipairs(AXES) do
  sorters[axis] = function(a, b)
    local u, v = a.p[axis], b.p[axis]
    if u ~= v then return u < v end
    return a.first < b.first
  end
end

-- a balanced k-d tree over nodes[lo..hi] (the node at the middle of a range splits it)
local function build(tree, lo, hi)
  if lo > hi then return 0 end
  local nodes = tree.nodes
  local best, spread = "x", -1
  for _, axis in ipairs(AXES) do
    local a, b = huge, -huge
    for k = lo, hi do
      local v = nodes[k].p[axis]
      if v < a then a = v end
      if v > b then b = v end
    end
    if b - a > spread then best, spread = axis, b - a end
  end
  if hi > lo then
    local part = {}
    for k = lo, hi do part[#part + 1] = nodes[k] end
    sort(part, sorters[best])
    for k = lo, hi do nodes[k] = part[k - lo + 1] end
  end
  local mid = floor((lo + hi) / 2)
  nodes[mid].axis = best
  local count = #nodes[mid].ids + build(tree, lo, mid - 1) + build(tree, mid + 1, hi)
  tree.count[mid] = count
  return count
end

-- the tree of a set of positions: one node a distinct position, holding its indices in order
local function tree_of(points)
  local all = {}
  for i, p in ipairs(points) do all[i] = { p = p, i = i } end
  sort(all, by_position)
  local nodes, at = {}, {}
  for _, e in ipairs(all) do
    local last = nodes[#nodes]
    local p = e.p
    if last and last.p.x == p.x and last.p.y == p.y and last.p.z == p.z then
      last.ids[#last.ids + 1] = e.i
    else
      last = { p = p, ids = { e.i }, next = 1, first = e.i }
      nodes[#nodes + 1] = last
    end
  end
  local tree = { nodes = nodes, count = {}, at = at, dead = {}, n = #points }
  build(tree, 1, #nodes)
  for k, node in ipairs(nodes) do
    for _, i in ipairs(node.ids) do at[i] = k end
  end
  return tree
end

-- the nearest alive position of the tree to q in nodes[lo..hi], into tree.best_d, .best_i
local function search(tree, q, lo, hi)
  if lo > hi or tree.count[floor((lo + hi) / 2)] == 0 then return end
  local mid = floor((lo + hi) / 2)
  local node = tree.nodes[mid]
  if node.next <= #node.ids then
    local d, i = distance(q, node.p), node.ids[node.next]
    if d < tree.best_d or (d == tree.best_d and i < tree.best_i) then
      tree.best_d, tree.best_i = d, i
    end
  end
  local axis = node.axis
  local diff = q[axis] - node.p[axis]
  if diff < 0 then
    search(tree, q, lo, mid - 1)
    if sqrt(diff * diff) <= tree.best_d then search(tree, q, mid + 1, hi) end
  else
    search(tree, q, mid + 1, hi)
    if sqrt(diff * diff) <= tree.best_d then search(tree, q, lo, mid - 1) end
  end
end

-- the nearest alive index to q and its distance, or nil when none is left
local function nearest(tree, q)
  tree.best_d, tree.best_i = huge, huge
  search(tree, q, 1, #tree.nodes)
  if tree.best_i == huge then return nil end
  return tree.best_i, tree.best_d
end

-- take index i out of the tree
local function remove(tree, i)
  local k = tree.at[i]
  local node = tree.nodes[k]
  tree.dead[i] = true
  while node.next <= #node.ids and tree.dead[node.ids[node.next]] do node.next = node.next + 1 end
  local lo, hi = 1, #tree.nodes
  while true do
    local mid = floor((lo + hi) / 2)
    tree.count[mid] = tree.count[mid] - 1
    if mid == k then break end
    if k < mid then hi = mid - 1 else lo = mid + 1 end
  end
  tree.n = tree.n - 1
end

-- the pairs in order: distance, then index in a, then in b
local function before(u, v)
  if u[1] ~= v[1] then return u[1] < v[1] end
  if u[2] ~= v[2] then return u[2] < v[2] end
  return u[3] < v[3]
end

-- the matching of a few positions (na x nb at most SMALL pairs) by its definition: every pair
-- in order, each position taken once
local function by_every_pair(a, b, ka, kb, ds)
  local all = {}
  for i = 1, #a do
    for j = 1, #b do all[#all + 1] = { distance(a[i], b[j]), i, j } end
  end
  sort(all, before)
  local used_a, used_b = {}, {}
  for _, e in ipairs(all) do
    local i, j = e[2], e[3]
    if not used_a[i] and not used_b[j] then
      used_a[i], used_b[j] = true, true
      ka[#ka + 1], kb[#kb + 1], ds[#ds + 1] = i, j, e[1]
    end
  end
  return ka, kb, ds
end

--- Most pairs matched by listing every pair (the common frame of a tag or two, where a tree
-- costs more than it saves).
M.SMALL = 16

--- Match two sets of positions nearest first.
-- @tparam {table,...} a positions `{x =, y =, z =}` (finite numbers)
-- @tparam {table,...} b positions
-- @treturn {int,...} the indices into `a` of the pairs
-- @treturn {int,...} the indices into `b`, pair by pair
-- @treturn {number,...} the distances, pair by pair (in no particular order of pairs)
function M.match(a, b)
  local ka, kb, ds = {}, {}, {}
  if #a == 0 or #b == 0 then return ka, kb, ds end
  if #a == 1 and #b == 1 then return { 1 }, { 1 }, { distance(a[1], b[1]) } end
  if #a * #b <= M.SMALL then return by_every_pair(a, b, ka, kb, ds) end
  local trees = { tree_of(a), tree_of(b) }
  local sets = { a, b }
  -- the chain: side (1: a, 2: b) and index of each link, each link's nearest the next
  local side, index, n = {}, {}, 0
  local start = 1
  while trees[1].n > 0 and trees[2].n > 0 do
    if n == 0 then
      while trees[1].dead[start] do start = start + 1 end
      n, side[1], index[1] = 1, 1, start
    end
    local s, i = side[n], index[n]
    local other = 3 - s
    local j, d = nearest(trees[other], sets[s][i])
    if n > 1 and index[n - 1] == j then
      local ia, ib = i, j
      if s == 2 then ia, ib = j, i end
      ka[#ka + 1], kb[#kb + 1], ds[#ds + 1] = ia, ib, d
      remove(trees[1], ia)
      remove(trees[2], ib)
      side[n], index[n], side[n - 1], index[n - 1] = nil, nil, nil, nil
      n = n - 2
    else
      n = n + 1
      side[n], index[n] = other, j
    end
  end
  return ka, kb, ds
end

return M
