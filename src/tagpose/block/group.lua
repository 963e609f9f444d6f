--- Blocks: grouping the frame's tags into hypotheses of one cube each.
--
-- Two tags may be on one cube when a candidate of each implies the same block: centres that
-- agree across the line of sight (`PERP_GATE`; along it a single tag's depth is poor,
-- `ALONG_GATE`, `ALONG_K`) and block rotations that agree modulo the cube's symmetries
-- (`ROTATION_GATE`). `links` records, once a frame, for every candidate the other detections
-- that agree with it; a hypothesis seeded by one candidate takes the free detections linked to
-- it, one per face.
--
-- With a symmetric block (`tagpose.block.body`) the rotations agree modulo the cube's
-- rotations, and the one between them says where on the block the other tag is; with an
-- identified one they agree themselves, each tag at its id's place.
--
-- A hypothesis record (`new`): `members` (indices into the frame's detections), `places` (each
-- member's place on the block, `tagpose.block.body`), `cands` (each member's candidate index),
-- `score` (each member's agreement distance), `start` (the seed candidate: the fit's start),
-- `gated` (the members before the fit), and after a fit `r, x, y, z` (the block pose), `sse`
-- (pixels only) and `cost` (with the priors; `math.huge` when the fit failed).
-- @module tagpose.block.group

local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")
local symmetric_angle = require("tagpose.block.identity").symmetric_angle

local sqrt, abs, rad, huge = math.sqrt, math.abs, math.rad, math.huge
local INVERSE = cube.INVERSE
local t_mul = rotation.transpose_multiply

local M = {}

require("tagpose.core.compat").interpret_module()

--- Grouping gate across the line of sight: implied centres closer than this (× block_size).
M.PERP_GATE = 0.3
--- Grouping gate along the line of sight (× block_size), where a single tag's depth is poor...
M.ALONG_GATE = 1.2
--- ... or wider, `ALONG_K` standard deviations of the difference of the two tags' depths
-- (each estimated as distance · σ / apparent size, σ the frame's corner noise).
M.ALONG_K = 5
--- Grouping gate on rotation: candidates whose block frames differ by less than this, modulo
-- the cube's symmetries (radians).
M.ROTATION_GATE = rad(60)
--- A hypothesis whose start is within this angle (radians, modulo the symmetries) of the
-- result of a fitted one over the same tags is not fitted again.
M.TWIN_ANGLE = rad(10)

local work = {} -- scratch: 3×3 products

--- A hypothesis of one member (see the module's header).
-- @tparam int s the member: a detection's index in the frame
-- @tparam table place its place on the block
-- @tparam int a its candidate's index
-- @tparam table start the candidate the fit starts from
-- @treturn table
function M.new(s, place, a, start)
  return { members = { s }, places = { place }, cands = { a }, score = { 0 }, start = start,
    gated = nil, r = nil, x = 0, y = 0, z = 0, sse = huge, cost = huge }
end

-- Does candidate b of another detection agree with the block of candidate a? Returns a distance
-- (smaller is better) and, for a symmetric block, the index of b's place in a's block frame
-- (the cube rotation of b's tag frame written in a's block frame); or nil.
local function agree(a, b, symmetric, block_size, sigma)
  local dx, dy, dz = b.x - a.x, b.y - a.y, b.z - a.z
  local d2 = dx * dx + dy * dy + dz * dz
  local pg, ag = M.PERP_GATE * block_size, M.ALONG_GATE * block_size
  -- along the line of sight, what the two tags' depths allow (distance · σ / apparent size)
  local sa, sb = a.depth * sigma, b.depth * sigma
  local spread = M.ALONG_K * sqrt(sa * sa + sb * sb)
  if spread > ag then ag = spread end
  if d2 > pg * pg + ag * ag then return nil end
  local mx, my, mz = a.x + b.x, a.y + b.y, a.z + b.z
  local along = (dx * mx + dy * my + dz * mz) / sqrt(mx * mx + my * my + mz * mz)
  local perp2 = d2 - along * along
  if perp2 > pg * pg or abs(along) > ag then return nil end
  local k, angle
  if symmetric then
    k, angle = cube.nearest(t_mul(a.r, b.r, work))
  else
    -- each tag at its place: the block frames must agree themselves
    angle = rotation.angle(a.r, b.r)
  end
  if angle > M.ROTATION_GATE then return nil end
  return sqrt(perp2) / pg + angle / M.ROTATION_GATE, k
end

--- The most candidates of other detections one candidate is compared with (the nearest
-- centres): a cube shows at most three faces, so this only bites in frames of many tags piled
-- together, where it keeps the grouping linear in their number.
M.NEIGHBOURS = 12

-- an order for table.sort (module-level: a closure made per call stops LuaJIT's compiler)
local function by_detection(a, b) return a[4] < b[4] end
local function by_score(a, b) return a[2] < b[2] or (a[2] == b[2] and a[4] < b[4]) end

-- At most this many times NEIGHBOURS candidates are scanned each way along x: in a pile of
-- tags at one place (copies of one tag) the nearest are then near ones, not the very nearest.
local SCAN = 4

-- Insert candidate i at squared distance d2 into the nearest list `out` (n long, at most cap,
-- nearest first); the new length.
local function insert(out, n, cap, d2, i)
  if n < cap then
    n = n + 1
    out[n] = out[n] or {}
  end
  local e = out[n]
  local k = n
  while k > 1 and out[k - 1][1] > d2 do
    out[k] = out[k - 1]
    k = k - 1
  end
  out[k] = e
  e[1], e[2] = d2, i
  return n
end

-- The candidates near candidate i of the frame's flat list C (`x, y, z, det` arrays, and
-- `order`: the candidates by x, `rank`: each one's place in it): `{d2, index}` for the
-- NEIGHBOURS nearest candidates of other detections within the coarsest gate, into `out`,
-- nearest first; their count. Scans outward along x until x alone is farther than the
-- farthest kept: a dense pile of tags costs about NEIGHBOURS per candidate, not all of them.
local function neighbours(C, i, reach2, out)
  local X, Y, Z, D, order = C.x, C.y, C.z, C.det, C.order
  local cx, cy, cz, det = X[i], Y[i], Z[i], D[i]
  local cap, n, total = M.NEIGHBOURS, 0, #order
  for dir = -1, 1, 2 do
    local p, last = C.rank[i] + dir, C.rank[i] + dir * SCAN * cap
    while p >= 1 and p <= total and p ~= last do
      local o = order[p]
      local dx = X[o] - cx
      local limit = n < cap and reach2 or out[n][1]
      if dx * dx > limit then break end
      if D[o] ~= det then
        local dy, dz = Y[o] - cy, Z[o] - cz
        local d2 = dx * dx + dy * dy + dz * dz
        if d2 <= limit and (n < cap or d2 < out[n][1]) then n = insert(out, n, cap, d2, o) end
      end
      p = p + dir
    end
  end
  return n
end

--- For every candidate a of every detection s (key 2s + a), the other detections with a
-- candidate that agrees with it: `links[key]` a list of `{place, score, b, j}` — for each such
-- detection j its best agreeing candidate b, and where that candidate puts j's tag on the
-- block of a — in the order of j. Each pair of candidates is tried once.
-- @tparam table fr the frame record (`tagpose.block.frame`)
-- @treturn table links
function M.links(fr)
  local dets, block_size, body = fr.dets, fr.block_size, fr.body
  local symmetric, places = body.symmetric, body.places
  local sigma = sqrt(fr.sigma2)
  -- the coarsest gate: no agreeing pair is further apart than this
  local deepest = 0
  for s = 1, #dets do
    for a = 1, #dets[s].cands do
      local d = dets[s].cands[a].depth
      if d > deepest then deepest = d end
    end
  end
  local pg = M.PERP_GATE * block_size
  local ag = math.max(M.ALONG_GATE * block_size, M.ALONG_K * sqrt(2) * deepest * sigma)
  local reach2 = pg * pg + ag * ag
  -- the candidates as flat arrays, sorted by x; each one's neighbours (a list and a set of keys
  -- 2j + b), then every pair in either's list once
  local C = { x = {}, y = {}, z = {}, det = {}, key = {}, order = {}, rank = {} }
  for s = 1, #dets do
    for a = 1, #dets[s].cands do
      local c, i = dets[s].cands[a], #C.x + 1
      C.x[i], C.y[i], C.z[i], C.det[i], C.key[i], C.order[i] = c.x, c.y, c.z, s, 2 * s + a, i
    end
  end
  table.sort(C.order, function(p, q) return C.x[p] < C.x[q] or (C.x[p] == C.x[q] and p < q) end)
  for p = 1, #C.order do C.rank[C.order[p]] = p end
  local near, lists, sets = {}, {}, {}
  for i = 1, #C.x do
    local list, set = {}, {}
    for k = 1, neighbours(C, i, reach2, near) do
      local key = C.key[near[k][2]]
      list[k], set[key] = key, true
    end
    lists[C.key[i]], sets[C.key[i]] = list, set
  end
  -- by[key][j]: the link of candidate key to detection j
  local by = {}
  for key in pairs(sets) do by[key] = {} end
  for ka, list in pairs(lists) do
    for k = 1, #list do
      local kb = list[k]
      if ka < kb or not sets[kb][ka] then
        -- the pair from the lower detection's side: s, a and j, b
        local lo, hi = ka, kb
        if hi < lo then lo, hi = kb, ka end
        local s, a, j, b = math.floor(lo / 2), lo % 2, math.floor(hi / 2), hi % 2
        if a == 0 then s, a = s - 1, 2 end
        if b == 0 then j, b = j - 1, 2 end
        local ds, dj = dets[s], dets[j]
        local score, g = agree(ds.cands[a], dj.cands[b], symmetric, block_size, sigma)
        if score then
          -- j seen from s's candidate a, and s seen from j's candidate b
          local row_a, row_b = by[lo], by[hi]
          local link = row_a[j]
          if not link or score < link[2] then
            row_a[j] = { symmetric and places[g] or dj.place, score, b, j }
          end
          link = row_b[s]
          if not link or score < link[2] then
            row_b[s] = { symmetric and places[INVERSE[g]] or ds.place, score, a, s }
          end
        end
      end
    end
  end
  -- each candidate's links, the NEIGHBOURS best (others may have linked to it beyond its own
  -- nearest), in the order of the detections
  local links = {}
  for key, row in pairs(by) do
    local list = {}
    for _, link in pairs(row) do list[#list + 1] = link end
    if #list > M.NEIGHBOURS then
      table.sort(list, by_score)
      for k = #list, M.NEIGHBOURS + 1, -1 do list[k] = nil end
    end
    table.sort(list, by_detection)
    links[key] = list
  end
  return links
end

--- The hypothesis seeded by candidate a of detection s among the free detections.
-- @tparam table fr the frame record
-- @tparam int s
-- @tparam int a
-- @tparam {boolean,...} free which detections are still free
-- @tparam table links `links(fr)`
-- @treturn table the hypothesis, with `gated` its members
function M.seeded(fr, s, a, free, links)
  local dets = fr.dets
  local h = M.new(s, dets[s].place, a, dets[s].cands[a])
  local row = links[2 * s + a]
  for i = 1, #row do
    local link = row[i]
    local j = link[4]
    if free[j] then
      local best_p, best_score, best_b = link[1], link[2], link[3]
      -- one tag per place (per face of a symmetric block, whatever its turn): the closer claim
      -- keeps it
      local clash = nil
      for m = 1, #h.members do
        if h.places[m].key == best_p.key then clash = m end
      end
      if not clash then
        local m = #h.members + 1
        h.members[m], h.places[m], h.cands[m], h.score[m] = j, best_p, best_b, best_score
      elseif clash > 1 and best_score < h.score[clash] then
        h.members[clash], h.places[clash], h.cands[clash], h.score[clash] = j, best_p, best_b,
          best_score
      end
    end
  end
  local gated = {}
  for m = 1, #h.members do gated[m] = h.members[m] end
  h.gated = gated
  return h
end

--- The key of a hypothesis's set of detections (its gated members, in any order).
-- @tparam table h
-- @treturn string
function M.set_key(h)
  local list = {}
  for m = 1, #h.gated do list[m] = h.gated[m] end
  table.sort(list)
  return table.concat(list, ",")
end

--- An already fitted hypothesis over the same detections whose result is where this one's
-- start is (its fit would only repeat that one), or nil.
-- @tparam table h a hypothesis not fitted yet
-- @tparam {table,...} fitted the hypotheses fitted this frame over h's set of detections, in
--   the order fitted
-- @tparam boolean symmetric whether the block is symmetric (`tagpose.block.body`)
-- @treturn table|nil
function M.twin_of(h, fitted, symmetric)
  for i = 1, #fitted do
    local f = fitted[i]
    if f.cost < huge then
      if symmetric_angle(f.r, h.start.r, symmetric) < M.TWIN_ANGLE then return f end
    end
  end
  return nil
end

--- Is hypothesis a better than b: more faces, then the lower cost.
-- @tparam table a
-- @tparam[opt] table b
-- @treturn boolean
function M.better(a, b)
  if not b then return true end
  local na, nb = #a.members, #b.members
  if na ~= nb then return na > nb end
  return a.cost < b.cost
end

return M
