--- Blocks: identity across frames and the frame a block is returned in.
--
-- A block found again (its centre within `TRACK_GATE` of a block of the previous frame, the
-- least total distance first) keeps that block's `id` and takes, of its 24 symmetric
-- equivalents, the frame nearest the previous rotation, so its orientation never jumps between
-- equivalents. A new block takes the canonical frame: block z the face axis closest to up
-- (the frame's up, default the camera's −y), block x the remaining face axis closest to the
-- direction from the camera to the block's centre (`tagpose.rigid.cube.canonical`). That is
-- for a symmetric block (`tagpose.block.body`); an identified one is returned in its layout's
-- frame, found again or not.
-- @module tagpose.block.identity

local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")

local sqrt = math.sqrt
local is_finite = compat.is_finite
local t_mul = rotation.transpose_multiply

local M = {}

compat.interpret_module()

--- Tracking gate: a block is the previous frame's block when their centres are closer than
-- this (× block_size).
M.TRACK_GATE = 0.75

local work = {} -- scratch: 3×3 products

--- Angle between rotation r and the nearest symmetric equivalent of ref (of a symmetric
-- block; ref itself for an identified one, `tagpose.block.body`).
-- @tparam {number,...} r flat rotation
-- @tparam {number,...} ref flat rotation
-- @tparam boolean symmetric whether the block is symmetric
-- @treturn number radians
function M.symmetric_angle(r, ref, symmetric)
  if not symmetric then return rotation.angle(r, ref) end
  local _, angle = cube.nearest(t_mul(r, ref, work))
  return angle
end

--- The previous block nearest a centre within a gate, or nil.
-- @tparam[opt] {table,...} previous the previous blocks (`tagpose.block.options` records)
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @tparam number gate
-- @treturn table|nil
function M.nearest_previous(previous, x, y, z, gate)
  if not previous then return nil end
  local best, best_d = nil, gate * gate
  for i = 1, #previous do
    local p = previous[i]
    local d = ((p.x - x) * (p.x - x)) + ((p.y - y) * (p.y - y)) + ((p.z - z) * (p.z - z))
    if d < best_d then best, best_d = p, d end
  end
  return best
end

-- orders for table.sort (module-level: a closure made per call stops LuaJIT's compiler)
local function first_smaller(a, b) return a[1] < b[1] end

--- Match blocks to the previous frame's: the pairs within the gate, the least distance first.
-- @tparam {table,...} found the blocks, each with a hypothesis `h` (`h.x, h.y, h.z`)
-- @tparam {table,...} previous the previous blocks
-- @tparam number gate
-- @treturn table match: `match[i]` the index into `previous` of block i's match, or nil
function M.match(found, previous, gate)
  local used, candidates = {}, {}
  for i = 1, #found do
    local h = found[i].h
    for j = 1, #previous do
      local q = previous[j]
      local dx, dy, dz = h.x - q.x, h.y - q.y, h.z - q.z
      local d = sqrt(dx * dx + dy * dy + dz * dz)
      if d < gate then candidates[#candidates + 1] = { d, i, j } end
    end
  end
  table.sort(candidates, first_smaller)
  local match = {}
  for _, pr in ipairs(candidates) do
    local i, j = pr[2], pr[3]
    if not match[i] and not used[j] then match[i], used[j] = j, true end
  end
  return match
end

--- The rotation a block is returned with: the fit's own for an identified block (its layout's
-- frame), else the equivalent nearest its previous rotation when tracked, else the canonical
-- one.
-- @tparam {number,...} r the fit's flat rotation
-- @tparam number x the block's centre
-- @tparam number y
-- @tparam number z
-- @tparam table fr the frame record (`body`, `up`, `default_up`)
-- @tparam[opt] table prev the previous block it continues
-- @tparam {number,...} out flat rotation to fill
-- @treturn {number,...} out
function M.output_rotation(r, x, y, z, fr, prev, out)
  if not fr.body.symmetric then
    for i = 1, 9 do out[i] = r[i] end
    return out
  end
  if prev then return cube.closest(r, prev.r, out) end
  local up = fr.up or fr.default_up
  return cube.canonical(r, up[1], up[2], up[3], x, y, z, out)
end

--- The id the next new block takes: the previous frame's `next_id`, or one more than the
-- largest previous id.
-- @tparam table settings the options read
-- @treturn number
function M.next_id(settings)
  local next_id = settings.next_id
  if is_finite(next_id) then return next_id end
  next_id = 0
  for _, p in ipairs(settings.previous) do
    if is_finite(p.id) and p.id > next_id then next_id = p.id end
  end
  return next_id + 1
end

return M
