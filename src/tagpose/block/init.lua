--- Blocks: the pose of cubes from the tags on their faces.
--
-- A block is a cube of side `block_size` carrying a tag (black square of side `tag_size`) on
-- its faces. Its frame has the origin at the cube's centre and the axes along the face normals
-- (`tagpose.layout.cube` lists the faces and the tag frame on each). By default every face carries
-- a tag of any id, centred on the face, its z axis pointing into the block; the faces cannot be
-- told apart, so a block's rotation is defined up to the cube's 24 symmetries and a canonical
-- one is returned. With `options.faces` (tag id → face) the block frame is absolute.
--
-- The stages, per frame, each a module of its own:
--
-- 1. `tagpose.block.options`: the options, read once;
-- 2. `tagpose.block.frame`: every detection solved alone by the single-tag pipeline
--    (`tagpose.core.pipeline`): one or two candidate poses (the planar ambiguity), each implying a
--    block centre and rotation; the frame's corner noise;
-- 3. `tagpose.block.group` and `tagpose.block.fit`: from every candidate as a seed, the free
--    detections that agree with it form a hypothesis, fitted jointly over all its corners and
--    kept together only while the fit is consistent with the members' own fits (an F-test);
--    the best hypothesis (most members, then the lowest error) becomes a block, its tags leave
--    the pool, and the rest are grouped again; a block seen with one face keeps both
--    candidates;
-- 4. `tagpose.block.scene`: with `up = "auto"` or `floor = "auto"`, what the blocks seen with
--    two or more faces show of up and the floor, for those seen with one;
-- 5. `tagpose.block.identity`: ids and frames across frames (`options.previous`), or the
--    canonical frame.
--
-- Lengths are in the unit of `tag_size`, angles in radians, errors in pixels.
-- @module tagpose.block

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.layout.cube")
local read_options = require("tagpose.block.options").read
local frame = require("tagpose.block.frame")
local group = require("tagpose.block.group")
local fit = require("tagpose.block.fit")
local scene = require("tagpose.block.scene")
local identity = require("tagpose.block.identity")
local spread = require("tagpose.block.uncertainty")

local is_finite = compat.is_finite
local sqrt, huge = math.sqrt, math.huge
local mul, t_mul = rotation.multiply, rotation.transpose_multiply

local M = {}

--- Two blocks whose centres are closer than this (× block_size) are one cube: the later found
-- (fewer faces, or a larger error) is dropped and its tags reported in `skipped`.
M.OVERLAP = 0.5

--- A block more than this many times its tags' size is taken for a mix of units (metres and
-- millimetres), and refused.
M.MAX_RATIO = 100

-- A tag of each size must fit on a face, and be in the block size's unit; or what is wrong.
local function fits_block(tag_size, block_size)
  local sizes = type(tag_size) == "table" and tag_size or { tag_size }
  for key, size in pairs(sizes) do
    local name = type(tag_size) == "table" and "tag_size[" .. tostring(key) .. "]" or "tag_size"
    if not (block_size > size) then
      return ("block_size must exceed %s, got %g <= %g"):format(name, block_size, size)
    end
    if block_size > M.MAX_RATIO * size then
      return ("block_size %g is %.0f times %s %g: both must be in one unit (a tag covers a "
        .. "fair part of its face)"):format(block_size, block_size / size, name, size)
    end
  end
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

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
    local twin = same and group.twin_of(h, same, fr.settings.faces)
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

local function ascending(p, q) return p < q end

-- The best hypothesis of two or more tags among the free detections (most members, then the
-- lowest cost, the first seed in order on a tie), or nil. The pending seeds are formed first,
-- in order.
local function best_hypothesis(fr, free, links, state)
  local cache, qualifying, keys = state.cache, state.qualifying, {}
  for key in pairs(state.pending) do keys[#keys + 1] = key end
  table.sort(keys, ascending)
  for i = 1, #keys do
    local key = keys[i]
    local s = math.floor((key - 1) / 2)
    local h = form(fr, s, key - 2 * s, free, links, state)
    cache[key] = h
    qualifying[key] = #h.members > 1 and h.cost < huge or nil
  end
  state.pending = {}
  keys = {}
  for key in pairs(qualifying) do keys[#keys + 1] = key end
  table.sort(keys, ascending)
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

-- The frame's blocks, in the order found: `{h = hypothesis, other = the other pose of a
-- one-face block or nil, how = what decided its orientation}` each.
local function find(fr)
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

local function finite_block(r, x, y, z, err)
  local s = x + y + z + err + r[1] + r[2] + r[3] + r[4] + r[5] + r[6] + r[7] + r[8] + r[9]
  return s == s and s > -huge and s < huge
end

-- The blocks found that are finite and not where an earlier one is (found in order of faces,
-- then error: a later block within OVERLAP of an earlier one is a tag that did not fit it, such
-- as the same tag detected twice); the others' tags go to `skipped`.
local function keep(fr, found)
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
  return a.h.x ^ 2 + a.h.y ^ 2 + a.h.z ^ 2 < b.h.x ^ 2 + b.h.y ^ 2 + b.h.z ^ 2
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
    tag_faces[m] = cube.face_of(mul(rel, h.g[m], face_r))
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

-- The returned array: the blocks (nearest first, or by id when tracking) and the frame's
-- fields.
local function results(fr, blocks)
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

--- Solve the poses of the blocks whose tags one frame shows.
-- @tparam {table,...} detections array of `{id = n, corners = {...}}`, `corners` as
--   `tagpose.solve` takes them (four points `{u, v}` or `{x =, y =}` in detection order, pixels)
-- @tparam table camera `{fx =, fy =, cx =, cy =}` in pixels, optionally `distortion` and
--   `model` (see `tagpose.camera`)
-- @tparam number|table tag_size side of the tags' black squares (> 0); lengths come out in its
--   unit. Or the sides by tag id, `{[id] = size, default = size}` (`default` optional: a tag
--   with no size is skipped, with its reason)
-- @tparam number block_size side of the cube (> `tag_size`)
-- @tparam[opt] table options
--
--   - `up`: a vector `{x =, y =, z =}` (or `{x, y, z}`) in the camera frame pointing up
--     (against gravity), when known: a block resting on a face has a face axis along it, which
--     decides between the two poses of a block seen with one face and steadies every fit; it
--     also sets the canonical z. Default: none (and `(0, -1, 0)` for the canonical choice).
--     `"auto"`: when the frame has blocks seen with two or more faces, up is their face axis
--     nearest the camera's -y, used for the blocks seen with one face (this assumes that all
--     the blocks in view rest on a face, on the floor or on each other, and that the camera is
--     rolled and pitched by less than 45 degrees);
--   - `up_tolerance`: standard deviation of a block's tilt from `up`, radians (default 2°);
--   - `floor` (needs `up`): the height of the camera's centre above the floor the blocks rest
--     on, when known: a block resting on the floor or on other blocks has its centre at
--     `block_size/2 + k·block_size` above it, which fixes the depth a single tag measures
--     poorly. It helps only when known to about a millimetre: a height error moves a centre
--     along the line of sight by the error over the sine of the ray's angle below horizontal.
--     A block further than 0.3 block from every level is left free;
--     `"auto"` (with `up`, a vector or `"auto"`): when the frame has blocks seen with two or
--     more faces, the floor is where they rest (each at the level nearest its height above the
--     lowest), used for the blocks seen with one face and, for each of those blocks, the floor
--     the others show (this assumes that all the blocks in view rest on the floor or on each
--     other);
--   - `floor_tolerance`: standard deviation of a resting centre's height from its level, in
--     length units (default `block_size / 50`; `block_size / 100` with `floor = "auto"`);
--   - `previous`: the blocks returned for the previous frame: a block found again keeps its
--     `id` and the symmetric frame nearest its previous rotation, and a one-face block keeps
--     the candidate that continues a decided orientation;
--   - `faces`: a table tag id → face (`"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`, or the
--     nested 3×3 tag → block rotation, one of the cube's) when the faces can be told apart: the
--     block frame is then absolute and detections with other ids are skipped;
--   - `max_iterations`: bound on the linearisations of one joint fit (default 20);
--   - `sigma`: the corner noise in pixels, for `covariance` and `confidence` (default: the
--     frame's block residuals pooled with `tagpose.uncertainty.DEFAULT_SIGMA`).
-- @treturn {table,...} blocks, nearest first (sorted by `id` when tracking), each
--   `{id =, position = {x, y, z}, rotation = {{...}, {...}, {...}}, quaternion = {w, x, y, z},
--   raw_rotation = {{...}, ...}, error = px, tags = {i, ...}, faces = k, tag_faces = {"+x",
--   ...}, orientation = "faces"|"up"|"track"|"error", covariance = {{...} x 6},
--   confidence = p, alternative = {position, rotation, quaternion, error, covariance,
--   confidence} or nil}`: `covariance[i][j]` in the order (x, y, z, rx, ry, rz) of the block
--   centre and a small rotation vector, both in the camera frame, as for a tag
--   (`tagpose.block.uncertainty`); `confidence` the probability that the block's orientation
--   is the true one of the two a one-face block has (1 with two or more faces; below 0.5 when
--   the better-fitting one is the less likely); the array's field `skipped` lists the
--   detections not used, `{index = i, reason = string}`, `next_id` the id a new block would
--   take, and `noise` the corner noise evidence `{sse =, dof =}` (px², degrees of freedom)
--   carried to the next frame, `up` (`{x =, y =, z =}`) and `floor` the up and floor used
--   (given or found with `"auto"`; nil when none)
-- @return nil, string when no detection gives a tag pose (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
--   (`detections` not a table, the camera, the sizes, the options; a malformed detection
--   inside the array is skipped instead, with its reason)
-- @usage
-- local blocks = tagpose.block.solve({{id = 0, corners = c1}, {id = 0, corners = c2}},
--   camera, 0.024, 0.055, {up = {x = 0, y = -0.9, z = -0.4}})
-- for _, b in ipairs(blocks) do print(b.id, b.position.x, b.position.y, b.position.z) end
function M.solve(detections, camera, tag_size, block_size, options)
  if type(detections) ~= "table" then
    arg_error(1, "array of detections expected, got " .. type(detections))
  end
  if detections[1] == nil and (detections.corners ~= nil or detections.id ~= nil) then
    arg_error(1, "array of detections expected, got one detection (pass {detection})")
  end
  local problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  problem = args.check_sizes(tag_size, "tag_size")
  if problem then arg_error(3, problem) end
  problem = args.check_size(block_size, "block_size")
  if problem then arg_error(4, problem) end
  problem = fits_block(tag_size, block_size)
  if problem then arg_error(4, problem) end
  local settings
  settings, problem = read_options(options)
  if not settings then arg_error(5, problem) end
  local fr = frame.new(settings, detections, camera, tag_size, block_size)
  if #fr.dets == 0 and fr.first_reason then
    return nil, "block: no detection gives a tag pose (" .. fr.first_reason .. ")"
  end
  return results(fr, keep(fr, find(fr)))
end

-- The driver loops over a few tags and blocks branch a lot and call much: on LuaJIT their
-- traces outgrow the machine-code area (512 KB by default), which is then flushed and refilled
-- every hundred frames or so. Left to the interpreter (the kernels they call still compile
-- their own loops) they run about three times faster there. Whether the VM can do that is
-- compat's to know (`compat.interpret`; a no-op on PUC Lua).
compat.interpret(M.solve)
compat.interpret(find)
compat.interpret(best_hypothesis)
compat.interpret(form)
compat.interpret(keep)
compat.interpret(results)

return M
