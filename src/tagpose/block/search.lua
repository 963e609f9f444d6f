--- Blocks: the search of one frame for its blocks.
--
-- From every candidate of every detection as a seed, the free detections that agree with it
-- form a hypothesis (`tagpose.block.group`), fitted jointly over all its corners and kept
-- together only while the fit is consistent with the members' own fits
-- (`tagpose.block.fit`); the best hypothesis (most members, then the lowest error) becomes a
-- block, its tags leave the pool, and the rest are grouped again. When no two free tags make a
-- block, what the blocks found show of the scene is taken (`tagpose.block.scene`, for the
-- "auto" options), then each free tag becomes a block seen with one face (the best-fitting
-- first), keeping both its candidates.
-- @module tagpose.block.search

local compat = require("tagpose.core.compat")
local group = require("tagpose.block.group")
local fit = require("tagpose.block.fit")
local scene = require("tagpose.block.scene")

local huge = math.huge

local M = {}

compat.interpret_module()

--- Joint fits a frame may spend: this many per detection, and `FIT_BASE` more. A frame of a few
-- blocks needs about one per detection (at most 8 for 7 tags on the dev set); a pile of
-- hundreds of tags at one place could otherwise refit its hypotheses after every block it
-- finds. Past the budget, tags left over become one-face blocks.
M.FITS_PER_TAG = 1
--- See `FITS_PER_TAG`.
M.FIT_BASE = 32

-- The search of a frame: each seed's hypothesis (`cache`, by key 2s + a), the keys to form
-- (again: none yet, or a member was taken since), the keys whose hypotheses are blocks of two
-- or more tags (`qualifying`), the keys whose hypotheses hold each detection, the hypotheses
-- fitted by set of detections, and the fits left. A round then costs what changed in it, not
-- the whole frame.
local function search(fr)
  local state = { cache = {}, pending = {}, qualifying = {}, holding = {}, fitted = {},
    budget = M.FITS_PER_TAG * #fr.dets + M.FIT_BASE, dead = {} }
  for s = 1, #fr.dets do
    for a = 1, #fr.dets[s].cands do state.pending[2 * s + a] = true end
  end
  return state
end

-- Detection m is taken: its own seeds are done, the hypotheses that held it are formed again.
local function take(state, m)
  for a = 1, 2 do
    local key = 2 * m + a
    state.dead[key], state.pending[key], state.qualifying[key] = true, nil, nil
  end
  local list = state.holding[m]
  if list then
    for i = 1, #list do
      local key = list[i]
      if not state.dead[key] then state.pending[key] = true end
    end
    state.holding[m] = nil
  end
end

-- The hypothesis of seed (s, a) among the free detections: fitted, or a twin of one fitted
-- over the same detections, or left unfitted (not a block) when the fits are spent.
local function form(fr, s, a, free, links, state)
  local h = group.seeded(fr, s, a, free, links)
  if #h.gated > 1 then
    local set = group.set_key(h)
    local same = state.fitted[set]
    local twin = same and group.twin_of(h, same, fr.body.symmetric)
    if twin then
      h = twin
    elseif state.budget > 0 then
      state.budget = state.budget - 1
      fit.hypothesis(fr, h)
      if not same then
        same = {}
        state.fitted[set] = same
      end
      same[#same + 1] = h
    end
  end
  local key = 2 * s + a
  for m = 1, #h.gated do
    local j = h.gated[m]
    local list = state.holding[j]
    if not list then
      list = {}
      state.holding[j] = list
    end
    list[#list + 1] = key
  end
  return h
end

-- The keys of a table keyed by hypothesis keys (whole numbers), in ascending order.
local function sorted_keys(t)
  local keys = {}
  for key in pairs(t) do keys[#keys + 1] = key end
  table.sort(keys)
  return keys
end

-- The best hypothesis of two or more tags among the free detections (most members, then the
-- lowest cost, the first seed in order on a tie), or nil. The pending seeds are formed first,
-- in order.
local function best_hypothesis(fr, free, links, state)
  local cache, qualifying = state.cache, state.qualifying
  local keys = sorted_keys(state.pending)
  for i = 1, #keys do
    local key = keys[i]
    local s = math.floor((key - 1) / 2)
    local h = form(fr, s, key - 2 * s, free, links, state)
    cache[key] = h
    qualifying[key] = #h.members > 1 and h.cost < huge or nil
  end
  state.pending = {}
  keys = sorted_keys(qualifying)
  local best = nil
  for i = 1, #keys do
    local h = cache[keys[i]]
    if group.better(h, best) then best = h end
  end
  return best
end

-- The detections in order of their single-tag error (the smallest first, then by index): the
-- order in which tags that make no block with others become one-face blocks.
local function by_error(dets)
  local order = {}
  for k = 1, #dets do order[k] = k end
  table.sort(order, function(p, q)
    local a, b = dets[p].best_sse, dets[q].best_sse
    return a < b or (a == b and p < q)
  end)
  return order
end

--- The blocks of a frame, in the order found: `{h = hypothesis, other = the other pose of a
-- one-face block or nil, how = what decided its orientation}` each. Detections that make no
-- block (no pose in front of the camera) are added to the frame's `skipped`.
-- @tparam table fr the frame record (`tagpose.block.frame`)
-- @treturn {table,...}
function M.find(fr)
  local dets = fr.dets
  local free, remaining = {}, #dets
  for s = 1, #dets do free[s] = true end
  local found, state = {}, search(fr)
  local singles, next_single = by_error(dets), 1
  local links = group.links(fr)
  local inferred = not (fr.settings.auto_up or fr.settings.auto_floor)
  while remaining > 0 do
    local h, other, how = best_hypothesis(fr, free, links, state), nil, "faces"
    if not h and not inferred then
      -- every block of two or more faces is found: what they show of the scene
      scene.infer(fr, found)
      inferred = true
    elseif not h then
      -- no two tags make a block: each free tag is one (the best-fitting first)
      while not free[singles[next_single]] do next_single = next_single + 1 end
      local s = singles[next_single]
      h, other, how = fit.single(fr, s)
      if not h then
        free[s] = false
        take(state, s)
        remaining = remaining - 1
        fr.skipped[#fr.skipped + 1] = { index = dets[s].index,
          reason = "block: no pose puts the tag in front of the camera" }
      end
    end
    if h then
      for m = 1, #h.members do
        free[h.members[m]] = false
        take(state, h.members[m])
        remaining = remaining - 1
      end
      found[#found + 1] = { h = h, other = other, how = how }
    end
  end
  return found
end

-- The driver loops over a few tags and blocks branch a lot and call much: on LuaJIT their
-- traces outgrow the machine-code area (512 KB by default), which is then flushed and refilled
-- every hundred frames or so. Left to the interpreter (the kernels they call still compile
-- their own loops) they run about three times faster there. Whether the VM can do that is
-- compat's to know (`compat.interpret`; a no-op on PUC Lua).
compat.interpret(M.find)
compat.interpret(best_hypothesis)
compat.interpret(form)

return M
