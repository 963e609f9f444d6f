--- Layouts as data: reading a layout's tag entries into the flat form the fits use, and writing
-- poses back into entries.
--
-- A layout is `{tags = {[id] = {size =, position = {x =, y =, z =}, quaternion = {w =, x =,
-- y =, z =}}}}`: each tag's frame (docs/conventions.md: origin at the tag's centre, x right,
-- y down, z into the tag) placed in the body frame, `X_body = R(quaternion)·X_tag + position`.
-- Ids are whole numbers of magnitude below 2^53 (every one a double holds exactly, and that
-- every Lua prints and reads back as it was). A quaternion need not be unit (files round
-- them): it is normalised, scaled first so that no square overflows or underflows
-- (`{w = 1e200, x = 1e200}` is a half turn about x, not the identity); one of length 1e-6 or
-- less is refused.
--
-- A read tag is `{id =, size =, half =, r = {9}, x =, y =, z =, points = {12}}`: `r` the flat,
-- row-major tag → body rotation, `(x, y, z)` the tag's centre in the body, and `points` its
-- corners c1..c4 (detection order: `(-h, +h)`, `(+h, +h)`, `(+h, -h)`, `(-h, -h)` in the tag
-- frame, `h` half the side) in the body frame, flat `{x1, y1, z1, ..., z4}`.
-- @module tagpose.rigid.model

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local rotation = require("tagpose.core.rotation")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local floor, huge = math.floor, math.huge

local M = {}

local CX = { -1, 1, 1, -1 }
local CY = { 1, 1, -1, -1 }

--- The corners of a tag placed at `(r, x, y, z)` with half side `half`, in the body frame.
-- @tparam {number,...} r flat tag → body rotation
-- @tparam number x the tag's centre in the body frame
-- @tparam number y
-- @tparam number z
-- @tparam number half half the tag's side
-- @tparam {number,...} out array to fill: 12 numbers from `out[first]`
-- @tparam[opt=1] int first
-- @treturn {number,...} out
function M.corners(r, x, y, z, half, out, first)
  local o = (first or 1) - 1
  for k = 1, 4 do
    local a, b = CX[k] * half, CY[k] * half
    out[o + 1] = r[1] * a + r[2] * b + x
    out[o + 2] = r[4] * a + r[5] * b + y
    out[o + 3] = r[7] * a + r[8] * b + z
    o = o + 3
  end
  return out
end

--- Magnitude every tag id is below: 2^53.
M.MAX_ID = 9007199254740992

--- What a tag id is, for messages.
M.ID = "a whole number of magnitude below 2^53"

--- True for a whole number usable as a tag id: `|id| < 2^53`.
-- @tparam any id
-- @treturn boolean
function M.is_id(id)
  return is_finite(id) and id == floor(id) and id < M.MAX_ID and id > -M.MAX_ID
end

--- A quaternion normalised without overflow or underflow: scaled by its largest component,
-- then divided by its length (`tagpose.core.rotation.unit_quaternion`).
-- @function unit_quaternion
-- @tparam number w finite
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @treturn number|nil w, or nil when the quaternion's length is 1e-6 or less
-- @treturn number x
-- @treturn number y
-- @treturn number z
M.unit_quaternion = rotation.unit_quaternion

--- A tag side larger than this many times a layout's extent contradicts it: a size in another
-- unit than the positions' (millimetres beside metres). The extent is the diagonal of the box
-- around the tags' centres (never less than the distance of the two furthest apart), or what
-- the caller knows of it (a field's length); twice keeps clear of the tags on two adjacent
-- faces of a cube, whose centres are 0.7 side apart.
M.SIZE_EXTENT = 2

--- The tag whose size contradicts a layout's extent (`SIZE_EXTENT`), if any.
-- @tparam table tags the layout's entries by id, `{size =, position = {x =, y =, z =}}`
--   (as the files give them, finite)
-- @tparam[opt] number extent what else is known of the layout's extent (0: nothing)
-- @treturn ?any the id of the largest tag, when its size contradicts the extent
-- @treturn number its size
-- @treturn number the extent
function M.size_contradiction(tags, extent)
  local x0, y0, z0, x1, y1, z1 = huge, huge, huge, -huge, -huge, -huge
  local id, size, n = nil, 0, 0
  for k, t in pairs(tags) do
    local p = t.position
    if p.x < x0 then x0 = p.x end
    if p.x > x1 then x1 = p.x end
    if p.y < y0 then y0 = p.y end
    if p.y > y1 then y1 = p.y end
    if p.z < z0 then z0 = p.z end
    if p.z > z1 then z1 = p.z end
    if t.size > size then id, size = k, t.size end
    n = n + 1
  end
  extent = extent or 0
  if n > 1 then
    local dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    local d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d > extent then extent = d end
  end
  if extent > 0 and size > M.SIZE_EXTENT * extent then return id, size, extent end
  return nil
end

--- Read one tag entry of a layout.
-- @tparam any entry `{size =, position =, quaternion =}`
-- @tparam number id its id (for messages)
-- @tparam[opt] table out the table to fill
-- @treturn table the read tag (see the module's header)
-- @return nil, string what is wrong, naming the field (`tags[3].size: positive number
--   expected, got number -1`)
function M.read_tag(entry, id, out)
  local name = "tags[" .. tostring(id) .. "]"
  if type(entry) ~= "table" then
    return nil, name .. ": table {size =, position =, quaternion =} expected, got " .. type(entry)
  end
  local size, p, q = entry.size, entry.position, entry.quaternion
  if not is_positive(size) then
    return nil, name .. ".size: positive number expected, got " .. describe(size)
  end
  if type(p) ~= "table" or not (is_finite(p.x) and is_finite(p.y) and is_finite(p.z)) then
    return nil, name .. ".position: table of finite numbers {x =, y =, z =} expected"
  end
  if type(q) ~= "table" or not (is_finite(q.w) and is_finite(q.x) and is_finite(q.y)
    and is_finite(q.z)) then
    return nil, name .. ".quaternion: table of finite numbers {w =, x =, y =, z =} expected"
  end
  local w, x, y, z = M.unit_quaternion(q.w, q.x, q.y, q.z)
  if not w then return nil, name .. ".quaternion: zero quaternion (length 1e-6 or less)" end
  for key in pairs(entry) do
    if key ~= "size" and key ~= "position" and key ~= "quaternion" then
      return nil, name .. ": unknown key " .. describe(key)
    end
  end
  out = out or {}
  out.id, out.size, out.half = id, size, 0.5 * size
  out.r = rotation.from_quaternion(w, x, y, z, out.r)
  out.x, out.y, out.z = p.x, p.y, p.z
  out.points = M.corners(out.r, p.x, p.y, p.z, out.half, out.points or {})
  return out
end

--- Read a whole layout: every tag, and the sorted list of ids.
-- @tparam any layout
-- @treturn table `{ids = {id, ...}, [id] = read tag, ...}`
-- @return nil, string what is wrong
function M.read(layout)
  if type(layout) ~= "table" then return nil, "layout table expected, got " .. type(layout) end
  local tags = layout.tags
  if type(tags) ~= "table" then
    return nil, "layout.tags: table {[id] = tag} expected, got " .. type(tags)
  end
  local out, ids = {}, {}
  for id, entry in pairs(tags) do
    if not M.is_id(id) then
      return nil, "layout.tags: key " .. describe(id) .. " is not a tag id (" .. M.ID .. ")"
    end
    local t, why = M.read_tag(entry, id)
    if not t then return nil, "layout." .. why end
    out[id] = t
    ids[#ids + 1] = id
  end
  table.sort(ids)
  out.ids = ids
  return out
end

--- A public tag entry from a pose on the body.
-- @tparam {number,...} r flat tag → body rotation
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @tparam number size the tag's side
-- @treturn table `{size =, position = {x, y, z}, quaternion = {w, x, y, z}}` (`w >= 0`)
function M.entry(r, x, y, z, size)
  local w, qx, qy, qz = rotation.to_quaternion(r)
  return { size = size, position = { x = x, y = y, z = z },
    quaternion = { w = w, x = qx, y = qy, z = qz } }
end

--- A copy of a layout (tags only, plus a string `name` when it has one), every entry read and
-- written again: unit quaternions with `w >= 0`.
-- @tparam table read a layout read by `read`
-- @tparam[opt] string name
-- @treturn table layout
function M.write(read, name)
  local tags = {}
  for _, id in ipairs(read.ids) do
    local t = read[id]
    tags[id] = M.entry(t.r, t.x, t.y, t.z, t.size)
  end
  return { name = name, tags = tags }
end

return M
