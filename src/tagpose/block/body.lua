--- Blocks: the rigid body a block is — where its tags sit on the cube — read once a call from
-- the sizes and the options of `tagpose.block.solve`.
--
-- A block is a layout (`tagpose.layout`) of tags on a cube: each tag's frame in the block frame,
-- `X_block = R·X_tag + p`, read by `tagpose.rigid.model` into a **place** `{r = R flat (tag →
-- block), x, y, z = p, key}` (a read tag of the model, with its `half` side and `size` when it
-- is one tag's; `key` is what one tag of a block occupies: its id, or a symmetric block's face
-- name, whatever the turn). The fits put a member's corners where its place says
-- (`tagpose.rigid.model.corners`). There are two kinds of block:
--
-- * **symmetric**: the faces cannot be told apart, by the ids or otherwise — the standard cube
--   of the lab's blocks (the default), or a layout with `symmetric = true`. A tag of any id may
--   be any tag of the layout turned by any of the cube's 24 rotations: the places are the orbit
--   of the layout's tags under the rotations, `places[k]` the one whose rotation is
--   `cube.ROTATIONS[k]` (`places[1]`, the identity, is the block a lone tag's own frame makes).
--   A detection's place is found when it is grouped, and the block's frame is defined up to the
--   rotations. A tag's size is its id's in `tag_size` (the standard cube) or the layout's one.
-- * **identified**: each id is one tag of the layout, at `places[id]`, and the block frame is
--   the layout's — `options.layout`, or `options.faces` as the layout `tagpose.layout.cube`
--   builds from it. Detections of other ids are skipped.
--
-- The record: `symmetric`, `places`, `sizes` (symmetric: `tag_size`, or the layout's one size),
-- `block_size` (given, or twice the median distance of a layout's tags from its centre),
-- `source` (the option a skipped detection's reason names, nil for the standard cube).
-- @module tagpose.block.body

local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")
local model = require("tagpose.rigid.model")

local sqrt, abs, acos, deg, rad = math.sqrt, math.abs, math.acos, math.deg, math.rad
local is_finite, describe, size_of = compat.is_finite, args.describe, args.size_of
local ROTATIONS = cube.ROTATIONS

-- The squared distance of a place p from (x, y, z).
local function distance2(p, x, y, z)
  local dx, dy, dz = p.x - x, p.y - y, p.z - z
  return dx * dx + dy * dy + dz * dz
end

local M = {}

compat.interpret_module()

--- A block more than this many times its tags' size is taken for a mix of units (metres and
-- millimetres), and refused.
M.MAX_RATIO = 100
--- A layout's tag lies on a face of the cube when its z axis is within this angle (radians) of
-- the face's inward normal...
M.FACE_ANGLE = rad(20)
--- ... and its centre within this distance (× block_size) of the face's plane (1.1 mm on a
-- 55 mm cube: a glued tag lies on its face).
M.FACE_DISTANCE = 0.02
--- A symmetric layout's tags are turned by the cube's rotations to within this angle
-- (radians), and the places they give agree to within this distance (× block_size).
M.SYMMETRY_TOLERANCE = 1e-3
--- `tag_size` agrees with a layout's size to within this relative difference.
M.SIZE_TOLERANCE = 1e-6

-- Every size of `sizes` (a size, or sizes by id) must fit on a face of the block, and be in the
-- block size's unit; or what is wrong. `name` names them in the message.
local function fits_block(sizes, block_size, name)
  for key, size in pairs(type(sizes) == "table" and sizes or { sizes }) do
    local what = type(sizes) == "table" and name .. "[" .. tostring(key) .. "]" or name
    if not (block_size > size) then
      return ("block_size must exceed %s, got %g <= %g"):format(what, block_size, size)
    end
    if block_size > M.MAX_RATIO * size then
      return ("block_size %g is %.0f times %s %g: both must be in one unit (a tag covers a "
        .. "fair part of its face)"):format(block_size, block_size / size, what, size)
    end
  end
end

-- The places of a symmetric block: the orbit of a read layout's tags under the cube's
-- rotations, by rotation index, each `{r = ROTATIONS[k], x, y, z}`; or nil and what is wrong.
local function orbit(tags, block_size)
  local places, size = {}, nil
  local tolerance = M.SYMMETRY_TOLERANCE * block_size
  for _, id in ipairs(tags.ids) do
    local t = tags[id]
    local e, off = cube.nearest(t.r)
    if off > M.SYMMETRY_TOLERANCE then
      return nil, ("options.layout.tags[%s]: a symmetric layout's tags are turned by the "
        .. "cube's rotations, this one is %.3g° from the nearest"):format(tostring(id), deg(off))
    end
    size = size or t.size
    if abs(t.size - size) > M.SIZE_TOLERANCE * size then
      return nil, ("options.layout.tags[%s].size: a symmetric layout's tags are of one size, "
        .. "got %g and %g"):format(tostring(id), size, t.size)
    end
    for j = 1, 24 do
      local g = ROTATIONS[j]
      local k = cube.nearest(rotation.multiply(g, ROTATIONS[e], {}))
      local x = g[1] * t.x + g[2] * t.y + g[3] * t.z
      local y = g[4] * t.x + g[5] * t.y + g[6] * t.z
      local z = g[7] * t.x + g[8] * t.y + g[9] * t.z
      local p = places[k]
      if not p then
        places[k] = { r = ROTATIONS[k], x = x, y = y, z = z, key = cube.face_of(ROTATIONS[k]),
          id = id }
      elseif distance2(p, x, y, z) > tolerance * tolerance then
        return nil, ("options.layout: not symmetric: the cube's rotations put tags[%s] and "
          .. "tags[%s] in one place %g apart (leave out symmetric = true when the ids tell the "
          .. "tags apart)"):format(tostring(p.id), tostring(id), sqrt(distance2(p, x, y, z)))
      end
    end
  end
  return places, size
end

-- the standard cube's places, kept for the last block size (the default: every call)
local standard_size, standard_places

-- The places of the standard cube of side `block_size`: the orbit of the tags
-- `tagpose.layout.cube` places on it, whose size (`size`, any that fits) does not matter: a
-- symmetric block's tags take their detections' sizes.
local function standard(block_size, size)
  if block_size ~= standard_size then
    standard_places = orbit(model.read(cube.layout(size, block_size)), block_size)
    standard_size = block_size
  end
  return standard_places
end

-- A symmetric layout's orbit, kept by its layout table (weakly: forgotten with the table), as
-- `{tags = the read tags, block_size =, places =, size =}`: reused only while the table's tags
-- read back the same (a layout changed between calls gets its orbit again).
local orbits = setmetatable({}, { __mode = "k" })

-- True when two read layouts have the same ids and each tag the same size, rotation and centre.
local function same_tags(a, b)
  local ia, ib = a.ids, b.ids
  if #ia ~= #ib then return false end
  for k = 1, #ia do
    local id = ia[k]
    if ib[k] ~= id then return false end
    local s, t = a[id], b[id]
    if s.size ~= t.size or s.x ~= t.x or s.y ~= t.y or s.z ~= t.z then return false end
    local rs, rt = s.r, t.r
    for i = 1, 9 do
      if rs[i] ~= rt[i] then return false end
    end
  end
  return true
end

-- `orbit(tags, block_size)` for the layout table `given`, from the cache when its tags and the
-- block size are those of the last call that gave it.
local function orbit_of(given, tags, block_size)
  local kept = orbits[given]
  if kept and kept.block_size == block_size and same_tags(kept.tags, tags) then
    return kept.places, kept.size
  end
  local places, size = orbit(tags, block_size)
  if places then
    orbits[given] = { tags = tags, block_size = block_size, places = places, size = size }
  end
  return places, size
end

-- The face a read tag lies on: the face's name, the tag centre's distance from the block's
-- centre along the face's normal, its distance from that line, and the angle between the tag's
-- z axis and the face's inward normal.
local function face_of(t)
  local nx, ny, nz = -t.r[3], -t.r[6], -t.r[9]
  local name = cube.face_name(nx, ny, nz)
  local n = cube.NORMALS[name]
  local c = nx * n[1] + ny * n[2] + nz * n[3]
  local d = t.x * n[1] + t.y * n[2] + t.z * n[3]
  local off = sqrt(math.max(t.x * t.x + t.y * t.y + t.z * t.z - d * d, 0))
  return name, d, off, acos(c < 1 and c or 1)
end

-- The block size a read layout's tags make (twice their median distance from the centre
-- along their faces' normals), or the one given, checked: every tag on a face of the cube. Returns
-- it, or nil, the argument to blame and what is wrong.
local function cube_size(tags, block_size)
  local distances = {}
  for _, id in ipairs(tags.ids) do
    local name, d, _, angle = face_of(tags[id])
    if angle > M.FACE_ANGLE then
      return nil, 5, ("options.layout.tags[%s]: a block's tags lie on the cube's faces, this "
        .. "one's z axis is %.1f° from the inward normal of the nearest (%s)")
        :format(tostring(id), deg(angle), name)
    end
    distances[#distances + 1] = d
  end
  local given = block_size ~= nil
  if given then
    local problem = args.check_size(block_size, "block_size")
    if problem then return nil, 4, problem end
  else
    -- twice the median distance (one tag placed wrong is then the one blamed)
    table.sort(distances)
    local n = #distances
    block_size = distances[math.floor((n + 1) / 2)] + distances[math.floor(n / 2) + 1]
    if not (block_size > 0) then
      return nil, 5, "options.layout: not a cube (its tags face away from its centre)"
    end
  end
  for _, id in ipairs(tags.ids) do
    local name, d, off = face_of(tags[id])
    if abs(d - 0.5 * block_size) > M.FACE_DISTANCE * block_size or off > 0.5 * block_size then
      local where = ("tags[%s] is %g from the centre along %s and %g from that axis"):format(
        tostring(id), d, name, off)
      if given then
        return nil, 4, ("block_size %g contradicts options.layout: %s, where a face's centre "
          .. "is at block_size/2 = %g"):format(block_size, where, 0.5 * block_size)
      end
      return nil, 5, ("options.layout: not a cube: %s, where the tags make a cube of side %g")
        :format(where, block_size)
    end
  end
  return block_size
end

-- tag_size[key] (key nil: tag_size) is `got`, the layout says `want` (of tag `id`, or of all
-- its tags): the misuse, or nil when they agree.
local function contradicts(got, want, key, id)
  if got ~= nil and abs(got - want) <= M.SIZE_TOLERANCE * want then return nil end
  return ("%s is %s, but %s (with a layout, tag_size may be nil: the layout gives each tag's "
    .. "size)"):format(key ~= nil and "tag_size[" .. tostring(key) .. "]" or "tag_size",
    got == nil and "no size" or ("%g"):format(got), id == nil
    and ("the tags of options.layout are of size %g"):format(want)
    or ("options.layout.tags[%s].size is %g"):format(tostring(id), want))
end

-- With a layout, tag_size is nil or gives each tag the layout's size (a symmetric layout's
-- one size, `one`, whatever the id); or the misuse.
local function check_tag_size(tag_size, tags, one)
  if tag_size == nil then return nil end
  local problem = args.check_sizes(tag_size, "tag_size")
  if problem then return problem end
  local by_id = type(tag_size) == "table"
  if one then
    for key, size in pairs(by_id and tag_size or { tag_size }) do
      problem = contradicts(size, one, by_id and key or nil)
      if problem then return problem end
    end
    return nil
  end
  for _, id in ipairs(tags.ids) do
    problem = contradicts(size_of(tag_size, id), tags[id].size, by_id and id or nil, id)
    if problem then return problem end
  end
end

-- The block of a layout (options.layout, or options.faces through tagpose.layout.cube); or nil,
-- the argument to blame and what is wrong.
local function of_layout(given, tag_size, block_size, source)
  local tags, why = model.read(given)
  if not tags then return nil, 5, "options." .. why end
  if #tags.ids == 0 then return nil, 5, "options.layout.tags: no tag (a layout of one cube)" end
  local symmetric = given.symmetric
  if symmetric ~= nil and type(symmetric) ~= "boolean" then
    return nil, 5, "options.layout.symmetric: boolean expected, got " .. describe(symmetric)
  end
  local size, n, problem = cube_size(tags, block_size)
  if not size then return nil, n, problem end
  local body = { symmetric = symmetric or false, block_size = size, source = source }
  if symmetric then
    body.places, body.sizes = orbit_of(given, tags, size)
    if not body.places then return nil, 5, body.sizes end
  else
    body.places = tags
    for _, id in ipairs(tags.ids) do tags[id].key = id end
  end
  problem = check_tag_size(tag_size, tags, symmetric and body.sizes or nil)
  if problem then return nil, 3, problem end
  for _, id in ipairs(tags.ids) do
    problem = fits_block(tags[id].size, size, "options.layout.tags[" .. tostring(id) .. "].size")
    if problem then return nil, block_size and 4 or 5, problem end
  end
  return body
end

--- The block a call of `tagpose.block.solve` solves for.
-- @tparam any tag_size the call's `tag_size`
-- @tparam any block_size the call's `block_size`
-- @tparam[opt] table settings the options read (`tagpose.block.options.read`; nil when they
--   are wrong: the standard cube, so that the sizes are checked first)
-- @treturn table the block (see the module's header)
-- @return nil, the number of the argument to blame, and what is wrong
function M.new(tag_size, block_size, settings)
  local given = settings and settings.layout
  if not given then
    local problem = args.check_sizes(tag_size, "tag_size")
    if problem then return nil, 3, problem end
    problem = args.check_size(block_size, "block_size")
      or fits_block(tag_size, block_size, "tag_size")
    if problem then return nil, 4, problem end
  end
  local faces = settings and settings.faces
  if faces then
    for id in pairs(faces) do
      if size_of(tag_size, id) == nil then
        return nil, 3, "tag_size has no size for tag id " .. tostring(id)
          .. " of options.faces and no default"
      end
    end
    return of_layout(cube.layout(tag_size, block_size, faces), nil, block_size, "options.faces")
  elseif given then
    return of_layout(given, tag_size, block_size, "options.layout")
  end
  local any = tag_size
  if type(any) == "table" then any = select(2, next(any)) end
  return { symmetric = true, places = standard(block_size, any), sizes = tag_size,
    block_size = block_size }
end

--- Where a detection's tag is on the block, and its half side.
-- @tparam table body
-- @tparam any id the detection's id
-- @treturn table its place (symmetric: `places[1]`, to be found when grouped)
-- @treturn number half its tag's side
-- @return nil, string why the detection is not a tag of the block
function M.place(body, id)
  if body.symmetric then
    local size = size_of(body.sizes, id)
    if size == nil then
      return nil, "block: tag_size has no size for tag id " .. tostring(id) .. " and no default"
    end
    return body.places[1], 0.5 * size
  end
  local place = is_finite(id) and body.places[id]
  if not place then
    return nil, "block: tag id " .. tostring(id) .. (body.source == "options.faces"
      and " is on no face of options.faces" or " is not in options.layout")
  end
  return place, place.half
end

return M
