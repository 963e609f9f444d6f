--- Blocks: the frame's blocks as the caller gets them.
--
-- The blocks found are kept when finite and not where an earlier one is (`OVERLAP`), then
-- returned nearest first (by `id` when tracking), each with its pose in the returned frame
-- (`tagpose.block.identity`), its tags and their faces, the other pose of a one-face block, and
-- its uncertainty (`tagpose.block.uncertainty`); the array carries the frame's fields
-- (`skipped`, `next_id`, `noise`, `up`, `floor`). See `tagpose.block.solve` for the tables.
-- @module tagpose.block.result

local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")
local identity = require("tagpose.block.identity")
local spread = require("tagpose.block.uncertainty")

local is_finite = compat.is_finite
local sqrt, huge = math.sqrt, math.huge
local mul, t_mul = rotation.multiply, rotation.transpose_multiply

local M = {}

compat.interpret_module()

--- Two blocks whose centres are closer than this (× block_size) are one cube: the later found
-- (fewer faces, or a larger error) is dropped and its tags reported in `skipped`.
M.OVERLAP = 0.5

local function finite_block(r, x, y, z, err)
  local s = x + y + z + err + r[1] + r[2] + r[3] + r[4] + r[5] + r[6] + r[7] + r[8] + r[9]
  return s == s and s > -huge and s < huge
end

--- The blocks found that are finite and not where an earlier one is (found in order of faces,
-- then error: a later block within `OVERLAP` of an earlier one is a tag that did not fit it,
-- such as the same tag detected twice); the others' tags go to the frame's `skipped`.
-- @tparam table fr the frame record (`tagpose.block.frame`)
-- @tparam {table,...} found the blocks found (`tagpose.block.search.find`)
-- @treturn {table,...} the blocks kept, each with its error `err` (px)
function M.keep(fr, found)
  local dets, blocks = fr.dets, {}
  local size = M.OVERLAP * fr.block_size
  local overlap2 = size * size
  -- the kept blocks by cell of a grid of that size: an overlapping one is in one of the 27
  -- cells around
  local grid = {}
  local function cell(i, j, k) return i .. "," .. j .. "," .. k end
  for _, f in ipairs(found) do
    local h = f.h
    local n = #h.members
    local err = sqrt(h.sse / (4 * n))
    local reason = nil
    local ci, cj, ck
    if not finite_block(h.r, h.x, h.y, h.z, err) then
      reason = "block: the fit is not finite"
    else
      ci, cj, ck = math.floor(h.x / size), math.floor(h.y / size), math.floor(h.z / size)
      -- the last kept block that overlaps (as a scan of all of them in order would find)
      local last = 0
      for i = ci - 1, ci + 1 do
        for j = cj - 1, cj + 1 do
          for k = ck - 1, ck + 1 do
            local list = grid[cell(i, j, k)]
            for q = 1, list and #list or 0 do
              local o = blocks[list[q]].h
              local dx, dy, dz = o.x - h.x, o.y - h.y, o.z - h.z
              if dx * dx + dy * dy + dz * dz < overlap2 and list[q] > last then last = list[q] end
            end
          end
        end
      end
      if last > 0 then
        local o, list = blocks[last].h, {}
        for m = 1, #o.members do list[m] = dets[o.members[m]].index end
        reason = "block: the tag does not fit the block of detection(s) "
          .. table.concat(list, ", ") .. " in its place"
      end
    end
    if reason then
      for m = 1, n do
        fr.skipped[#fr.skipped + 1] = { index = dets[h.members[m]].index, reason = reason }
      end
    else
      blocks[#blocks + 1] = f
      f.err = err
      local key = cell(ci, cj, ck)
      grid[key] = grid[key] or {}
      table.insert(grid[key], #blocks)
    end
  end
  return blocks
end

local function pose_table(r, x, y, z, err)
  local w, qx, qy, qz = rotation.to_quaternion(r)
  return {
    position = { x = x, y = y, z = z },
    rotation = rotation.to_nested(r),
    quaternion = { w = w, x = qx, y = qy, z = qz },
    error = err,
  }
end

-- orders for table.sort (module-level: a closure made per call stops LuaJIT's compiler)
local function nearer(a, b)
  local p, q = a.h, b.h
  return p.x * p.x + p.y * p.y + p.z * p.z < q.x * q.x + q.y * q.y + q.z * q.z
end
local function smaller_id(a, b) return a.id < b.id end

local out_r, face_r = {}, {} -- scratch rotations

-- One block's public table: its pose in the returned frame, tags and faces, the other pose of
-- a one-face block.
local function block_table(fr, f, prev, sigma2)
  local h, dets = f.h, fr.dets
  local r = identity.output_rotation(h.r, h.x, h.y, h.z, fr, prev, out_r)
  local b = pose_table(r, h.x, h.y, h.z, f.err)
  b.raw_rotation = rotation.to_nested(h.r)
  local tags, tag_faces = {}, {}
  -- each tag's face in the returned frame: G' = rᵀ·raw·G
  local rel = t_mul(r, h.r, {})
  for m = 1, #h.members do
    tags[m] = dets[h.members[m]].index
    tag_faces[m] = cube.face_of(mul(rel, h.places[m].r, face_r))
  end
  b.tags, b.tag_faces, b.faces, b.orientation = tags, tag_faces, #h.members, f.how
  if f.other then
    local o = f.other
    local orr = identity.output_rotation(o.r, o.x, o.y, o.z, fr, prev, out_r)
    local oerr = sqrt(o.sse / 4)
    if finite_block(orr, o.x, o.y, o.z, oerr) then
      b.alternative = pose_table(orr, o.x, o.y, o.z, oerr)
    end
  end
  spread.attach(fr, f, b, sigma2)
  return b
end

--- The array `tagpose.block.solve` returns: the blocks (nearest first, or by id when
-- tracking) and the frame's fields.
-- @tparam table fr the frame record
-- @tparam {table,...} blocks the blocks kept (`keep`)
-- @treturn {table,...}
function M.results(fr, blocks)
  local previous = fr.settings.previous
  local match, next_id = {}, 1
  if previous then
    next_id = identity.next_id(fr.settings)
    match = identity.match(blocks, previous, identity.TRACK_GATE * fr.block_size)
  else
    table.sort(blocks, nearer)
  end
  local out = {}
  local sigma2 = spread.noise(fr, blocks)
  for i, f in ipairs(blocks) do
    local prev = match[i] and previous[match[i]]
    local b = block_table(fr, f, prev, sigma2)
    if prev and is_finite(prev.id) then
      b.id = prev.id
    else
      b.id = next_id
      next_id = next_id + 1
    end
    out[i] = b
  end
  if previous then table.sort(out, smaller_id) end
  out.skipped = fr.skipped
  out.next_id = next_id
  out.noise = { sse = fr.noise_sse, dof = fr.noise_dof }
  -- the up and floor used (given, or found with "auto"), nil for none
  local up = fr.up
  out.up = up and { x = up[1], y = up[2], z = up[3] } or nil
  out.floor = fr.floor
  return out
end

-- (left to LuaJIT's interpreter, as `tagpose.block.search`'s driver loops)
compat.interpret(M.keep)
compat.interpret(M.results)

return M
