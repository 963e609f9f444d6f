--- Blocks: grouping the frame's tags into hypotheses of one cube each.
--
-- Two tags may be on one cube when a candidate of each implies the same block: centres that
-- agree across the line of sight (`PERP_GATE`; along it a single tag's depth is poor,
-- `ALONG_GATE`, `ALONG_K`) and block rotations that agree modulo the cube's symmetries
-- (`ROTATION_GATE`). `links` records, once a frame, for every candidate the other detections
-- that agree with it; a hypothesis seeded by one candidate takes the free detections linked to
-- it, one per face.
--
-- A hypothesis record (`new`): `members` (indices into the frame's detections), `g` (each
-- member's face: the flat tag → block rotation), `cands` (each member's candidate index),
-- `score` (each member's agreement distance), `start` (the seed candidate: the fit's start),
-- `gated` (the members before the fit), and after a fit `r, x, y, z` (the block pose), `sse`
-- (pixels only) and `cost` (with the priors; `math.huge` when the fit failed).
-- @module tagpose.block.group

local rotation = require("tagpose.rotation")
local cube = require("tagpose.cube")

local sqrt, abs, rad, huge = math.sqrt, math.abs, math.rad, math.huge
local ROTATIONS, INVERSE = cube.ROTATIONS, cube.INVERSE
local IDENTITY = ROTATIONS[1]
local t_mul = rotation.transpose_multiply

local M = {}

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
-- @tparam {number,...} g its face rotation
-- @tparam int a its candidate's index
-- @tparam table start the candidate the fit starts from
-- @treturn table
function M.new(s, g, a, start)
  return { members = { s }, g = { g }, cands = { a }, score = { 0 }, start = start,
    gated = nil, r = nil, x = 0, y = 0, z = 0, sse = huge, cost = huge }
end

-- Does candidate b of another detection agree with the block of candidate a? Returns a distance
-- (smaller is better) and, when the faces are not known, the index of the face rotation G of b
-- in a's block frame (b's tag frame written in a's block frame); or nil.
local function agree(a, b, faces, block_size, sigma)
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
  if faces then
    -- known faces: the block frames must agree themselves
    angle = rotation.angle(a.r, b.r)
  else
    k, angle = cube.nearest(t_mul(a.r, b.r, work))
  end
  if angle > M.ROTATION_GATE then return nil end
  return sqrt(perp2) / pg + angle / M.ROTATION_GATE, k
end

--- For every candidate a of every detection s (key 2s + a), the other detections with a
-- candidate that agrees with it: `links[key][j] = {G, score, b}` for the best such candidate b
-- of detection j, G its face in a's block frame. Each pair of candidates is tried once.
-- @tparam table fr the frame record (`tagpose.block.frame`)
-- @treturn table links
function M.links(fr)
  local dets, block_size, faces = fr.dets, fr.block_size, fr.settings.faces
  local sigma = sqrt(fr.sigma2)
  local links = {}
  for s = 1, #dets do
    for a = 1, #dets[s].cands do links[2 * s + a] = {} end
  end
  for s = 1, #dets do
    local ds = dets[s]
    for j = s + 1, #dets do
      local dj = dets[j]
      for a = 1, #ds.cands do
        local ca, row_a = ds.cands[a], links[2 * s + a]
        for b = 1, #dj.cands do
          local score, k = agree(ca, dj.cands[b], faces, block_size, sigma)
          if score then
            -- j seen from s's candidate a, and s seen from j's candidate b
            local link = row_a[j]
            if not link or score < link[2] then
              row_a[j] = { faces and dj.face_r or ROTATIONS[k], score, b }
            end
            local row_b = links[2 * j + b]
            link = row_b[s]
            if not link or score < link[2] then
              row_b[s] = { faces and ds.face_r or ROTATIONS[INVERSE[k]], score, a }
            end
          end
        end
      end
    end
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
  local dets, faces = fr.dets, fr.settings.faces
  local h = M.new(s, faces and dets[s].face_r or IDENTITY, a, dets[s].cands[a])
  local row = links[2 * s + a]
  for j = 1, #dets do
    local link = row[j]
    if link and free[j] then
      local best_g, best_score, best_b = link[1], link[2], link[3]
      -- one tag per face: the closer claim keeps it
      local clash = nil
      for m = 1, #h.members do
        local gm = h.g[m]
        if gm[3] == best_g[3] and gm[6] == best_g[6] and gm[9] == best_g[9] then clash = m end
      end
      if not clash then
        local m = #h.members + 1
        h.members[m], h.g[m], h.cands[m], h.score[m] = j, best_g, best_b, best_score
      elseif clash > 1 and best_score < h.score[clash] then
        h.members[clash], h.g[clash], h.cands[clash], h.score[clash] = j, best_g, best_b,
          best_score
      end
    end
  end
  local gated = {}
  for m = 1, #h.members do gated[m] = h.members[m] end
  h.gated = gated
  return h
end

--- Are the detections of a list all free?
-- @tparam {int,...} list
-- @tparam {boolean,...} free
-- @treturn boolean
function M.all_free(list, free)
  for i = 1, #list do
    if not free[list[i]] then return false end
  end
  return true
end

--- An already fitted hypothesis over the same detections whose result is where this one's
-- start is (its fit would only repeat that one), or nil.
-- @tparam table h a hypothesis not fitted yet
-- @tparam {table,...} fitted the hypotheses fitted this frame
-- @tparam table faces the known faces (or nil)
-- @treturn table|nil
function M.twin_of(h, fitted, faces)
  local n = #h.gated
  for i = 1, #fitted do
    local f = fitted[i]
    if #f.gated == n and f.cost < huge then
      local same = true
      for k = 1, n do
        local found = false
        for m = 1, n do
          if f.gated[m] == h.gated[k] then found = true end
        end
        if not found then same = false end
      end
      if same then
        local _, angle
        if faces then
          angle = rotation.angle(f.r, h.start.r)
        else
          _, angle = cube.nearest(t_mul(f.r, h.start.r, work))
        end
        if angle < M.TWIN_ANGLE then return f end
      end
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
