--- Blocks: the options of `tagpose.block.solve`, read once into a settings record that nothing
-- writes afterwards.
--
-- The record: `layout` (the caller's layout, or nil), `faces` (tag id → face name or nested
-- cube rotation, checked; or nil), `up` (a unit vector
-- `{x, y, z}` as an array, or nil), `auto_up`, `up_tolerance` (radians), `floor` (or nil),
-- `auto_floor`, `floor_tolerance` (or nil for the default), `max_iterations`, `previous` (the
-- previous frame's blocks as records `{x, y, z, r, id, decided}`, or nil), `next_id`, and the
-- noise evidence carried from the previous frame, `noise_sse` and `noise_dof` (or nil), and
-- `opencv` (the corners in OpenCV's order, `options.order`).
-- @module tagpose.block.options

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local rotation = require("tagpose.core.rotation")
local cube = require("tagpose.rigid.cube")
local model = require("tagpose.rigid.model")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local sqrt, rad = math.sqrt, math.rad
local NORMALS = cube.NORMALS

local M = {}

compat.interpret_module()

--- Default standard deviation (radians) of a block's tilt from `options.up`.
M.UP_TOLERANCE = rad(2)
--- Default bound on the linearisations of one joint fit.
M.MAX_ITERATIONS = 20

-- A direction {x, y, z} or {1, 2, 3}, made unit; or nil and the misuse.
local function read_direction(v, name)
  if type(v) ~= "table" then
    return nil, name .. ": table {x =, y =, z =} expected, got " .. type(v)
  end
  local x, y, z = v.x, v.y, v.z
  if x == nil then x, y, z = v[1], v[2], v[3] end
  if not (is_finite(x) and is_finite(y) and is_finite(z)) then
    return nil, name .. ": three finite numbers expected"
  end
  local n = sqrt(x * x + y * y + z * z)
  if not (n > 0) then return nil, name .. ": non-zero vector expected" end
  return { x / n, y / n, z / n }
end

-- options.faces: id → face name or nested cube rotation, checked and copied (for
-- `tagpose.layout.cube`); or nil and the misuse.
local function read_faces(faces)
  if type(faces) ~= "table" then
    return nil, "options.faces: table (tag id -> face) expected, got " .. type(faces)
  end
  local out = {}
  for id, f in pairs(faces) do
    if type(f) == "string" then
      if not NORMALS[f] then
        return nil, "options.faces[" .. tostring(id) .. "]: face '+x', '-x', '+y', '-y', '+z' "
          .. "or '-z' expected, got string " .. f
      end
    elseif not cube.of_nested(f) then
      return nil, "options.faces[" .. tostring(id) .. "]: face name or 3x3 rotation of the "
        .. "cube (the tag frame in the block frame) expected"
    end
    if not model.is_id(id) then
      return nil, "options.faces: key " .. describe(id) .. " is not a tag id (whole number)"
    end
    out[id] = f
  end
  if next(out) == nil then return nil, "options.faces: no tag id (tag id -> face) given" end
  return out
end

-- The previous frame's blocks: an array of {position, rotation or quaternion, id, ...}.
local function read_previous(previous)
  if type(previous) ~= "table" then
    return nil, "options.previous: array of blocks expected, got " .. type(previous)
  end
  local out = {}
  for i = 1, #previous do
    local b = previous[i]
    local p = type(b) == "table" and b.position
    if type(p) ~= "table" or not (is_finite(p.x) and is_finite(p.y) and is_finite(p.z)) then
      return nil, "options.previous[" .. i .. "]: block with a finite position expected"
    end
    local r = rotation.of_pose(b)
    if not r then
      return nil, "options.previous[" .. i .. "]: block with a finite rotation expected"
    end
    out[i] = { x = p.x, y = p.y, z = p.z, r = r, id = b.id,
      decided = b.orientation ~= nil and b.orientation ~= "error" }
  end
  return out, previous.next_id
end

-- the options block.solve takes
local OPTIONS = { "up", "up_tolerance", "floor", "floor_tolerance", "previous", "faces",
  "layout", "max_iterations", "sigma", "order" }

-- the scalar options: name, check, what the check expects
-- (an angle in radians: one above π/2 is degrees passed for radians, a prior that holds nothing)
local function is_tolerance(v)
  return is_positive(v) and v <= 0.5 * math.pi
end

local SCALAR_OPTIONS = {
  "up_tolerance", is_tolerance, "angle in radians, above 0 and at most π/2 (math.rad(2) is 2°)",
  "floor", is_finite, "finite number",
  "floor_tolerance", is_positive, "positive number",
  "max_iterations", args.is_count, "positive integer",
  "sigma", is_positive, "positive number",
}

-- options.previous and the noise it carries, into the settings s; or nil and the misuse.
local function read_tracking(s, previous)
  local problem
  s.previous, problem = read_previous(previous)
  if not s.previous then return nil, problem end
  s.next_id = problem
  local noise = previous.noise
  if noise ~= nil then
    if type(noise) ~= "table" or not (is_finite(noise.sse) and noise.sse >= 0
      and is_finite(noise.dof) and noise.dof >= 0) then
      return nil, "options.previous.noise: {sse =, dof =} (finite, >= 0) expected"
    end
    s.noise_sse, s.noise_dof = noise.sse, noise.dof
  end
  return s
end

--- Read the options of `tagpose.block.solve`.
-- @tparam any options the caller's options (or nil)
-- @treturn table the settings record (see the module's header)
-- @return nil, string describing the misuse
function M.read(options)
  local s = { up_tolerance = M.UP_TOLERANCE, max_iterations = M.MAX_ITERATIONS,
    auto_up = false, auto_floor = false, opencv = false }
  if options == nil then return s end
  if type(options) ~= "table" then return nil, "options table expected, got " .. type(options) end
  local problem = args.unknown_keys(options, OPTIONS, "options")
  if problem then return nil, problem end
  s.opencv, problem = args.read_order(options.order)
  if s.opencv == nil then return nil, problem end
  if options.up == "auto" then
    s.auto_up = true
  elseif options.up ~= nil then
    s.up, problem = read_direction(options.up, "options.up")
    if not s.up then return nil, problem .. " (or 'auto')" end
  end
  if options.faces ~= nil and options.layout ~= nil then
    return nil, "options.faces and options.layout: give one (faces names the layout "
      .. "tagpose.layout.cube(tag_size, block_size, faces))"
  elseif options.faces ~= nil then
    s.faces, problem = read_faces(options.faces)
    if not s.faces then return nil, problem end
  elseif options.layout ~= nil then
    if type(options.layout) ~= "table" then
      return nil, "options.layout: layout {tags = {[id] = {size =, position =, quaternion =}}} "
        .. "expected, got " .. type(options.layout)
    end
    s.layout = options.layout
  end
  if options.previous ~= nil then
    local ok
    ok, problem = read_tracking(s, options.previous)
    if not ok then return nil, problem end
  end
  for i = 1, #SCALAR_OPTIONS, 3 do
    local name, ok, what = SCALAR_OPTIONS[i], SCALAR_OPTIONS[i + 1], SCALAR_OPTIONS[i + 2]
    local v = options[name]
    if name == "floor" and v == "auto" then
      s.auto_floor, v = true, nil
    elseif name == "floor" and v ~= nil then
      what = what .. " (or 'auto')"
    end
    if v ~= nil then
      if not ok(v) then
        return nil, "options." .. name .. ": " .. what .. " expected, got " .. describe(v)
      end
      s[name] = v
    end
  end
  if s.floor and not s.up then return nil, "options.floor: needs options.up (a vector)" end
  if s.auto_floor and not (s.up or s.auto_up) then
    return nil, "options.floor: 'auto' needs options.up (a vector or 'auto')"
  end
  return s
end

return M
