--- WPILib field maps (the JSON of `AprilTagFieldLayout`, as FRC's fields ship), read as
-- tagpose layouts:
--
--     {"tags": [{"ID": 1, "pose": {"translation": {"x": 15.08, "y": 0.25, "z": 1.36},
--                 "rotation": {"quaternion": {"W": 0.5, "X": 0, "Y": 0, "Z": 0.866}}}}, ...],
--      "field": {"length": 16.541, "width": 8.211}}
--
-- Each tag's pose places its frame in the field frame (metres; WPILib's field frame: origin at
-- the blue alliance's corner, x along the field, y to the left, z up). WPILib's tag frame has
-- x out of the tag's face (towards whoever looks at it), z up, and so y to the right as seen from
-- the front. tagpose's tag frame has x right, y down and z into the tag, seen from the front:
--
--     x_tagpose = y_wpilib,   y_tagpose = -z_wpilib,   z_tagpose = -x_wpilib
--
-- so the tagpose frame is WPILib's turned by `C = [[0, 0, -1], [1, 0, 0], [0, -1, 0]]` (its
-- columns: tagpose's axes in WPILib's tag frame), the quaternion `(0.5, -0.5, -0.5, 0.5)`, and
-- each tag's rotation is `R_tagpose = R_wpilib·C`. The centre is the same point. The file gives
-- no tag size: the caller does (the 2024 and later FRC fields use 36h11 tags whose black square
-- is 6.5 in, 0.1651 m). `field` is checked (length and width in metres) and not kept: a layout
-- is its tags. A key the format does not have is refused, naming the key meant. Ids are whole
-- numbers >= 0 below 2^53 and quaternions are normalised without overflow, as in every layout
-- format (`tagpose.rigid.model`'s `is_id` and `unit_quaternion`).
-- @module tagpose.formats.wpilib

local compat = require("tagpose.core.compat")
local json = require("tagpose.formats.json")
local failure = require("tagpose.formats.failure")
local model = require("tagpose.rigid.model")

local is_finite = compat.is_finite
local concat = table.concat

local M = {}

--- The rotation from tagpose's tag frame to WPILib's, as a quaternion `w, x, y, z`.
M.TURN = { w = 0.5, x = -0.5, y = -0.5, z = 0.5 }

local function fail(r, at, reason)
  failure.raise("layout: " .. r.name .. ":" .. (at or 1) .. ": " .. reason)
end

local function describe(v)
  if v == json.NULL then return "null" end
  local t = type(v)
  if t == "number" or t == "string" then return t .. " " .. tostring(v) end
  return t
end

-- an object (a table read from `{...}`), or a refusal naming what
local function object(r, v, at, what, keys)
  if type(v) ~= "table" or v == json.NULL or v[1] ~= nil then
    fail(r, at, what .. ": an object {" .. concat(keys, ", ") .. "} expected, got " .. describe(v))
  end
  local lines = r.where[v]
  for k in pairs(v) do
    local known = false
    for _, key in ipairs(keys) do
      if k == key then known = true end
    end
    if not known then
      local hint
      for _, key in ipairs(keys) do
        if key:lower() == tostring(k):lower() then hint = key end
      end
      fail(r, lines[k], what .. ": unknown key '" .. tostring(k) .. "' (" .. (hint and ("did you"
        .. " mean '" .. hint .. "'?") or ("it has " .. concat(keys, ", "))) .. ")")
    end
  end
  for _, key in ipairs(keys) do
    if v[key] == nil then fail(r, at, what .. ": no " .. key) end
  end
  return v, lines
end

-- the finite numbers of an object's keys
local function numbers(r, t, lines, what, keys)
  local out = {}
  for i, key in ipairs(keys) do
    local v = t[key]
    if not is_finite(v) then
      fail(r, lines[key], what .. "." .. key .. ": number expected, got " .. describe(v))
    end
    out[i] = v
  end
  return out
end

-- q·TURN: the tag's rotation with tagpose's tag frame, w >= 0
local function turned(w, x, y, z)
  local t = M.TURN
  local qw = w * t.w - x * t.x - y * t.y - z * t.z
  local qx = w * t.x + x * t.w + y * t.z - z * t.y
  local qy = w * t.y - x * t.z + y * t.w + z * t.x
  local qz = w * t.z + x * t.y - y * t.x + z * t.w
  if qw < 0 then qw, qx, qy, qz = -qw, -qx, -qy, -qz end
  return qw, qx, qy, qz
end

-- one entry of "tags": its id and the layout's entry
local function read_tag(r, t, at, i)
  local what = "tags[" .. i .. "]"
  local _, lines = object(r, t, at, what, { "ID", "pose" })
  local id = t.ID
  if not (model.is_id(id) and id >= 0) then
    fail(r, lines.ID, what .. ".ID: a tag id (a whole number >= 0, below 2^53) expected, got "
      .. describe(id))
  end
  what = "tag " .. id
  local pose, plines = object(r, t.pose, lines.pose, what .. ".pose", { "translation", "rotation" })
  local tr, tlines = object(r, pose.translation, plines.translation, what .. ".pose.translation",
    { "x", "y", "z" })
  local p = numbers(r, tr, tlines, what .. ".pose.translation", { "x", "y", "z" })
  local rot, rlines = object(r, pose.rotation, plines.rotation, what .. ".pose.rotation",
    { "quaternion" })
  local q, qlines = object(r, rot.quaternion, rlines.quaternion, what .. ".pose.rotation"
    .. ".quaternion", { "W", "X", "Y", "Z" })
  local v = numbers(r, q, qlines, what .. ".pose.rotation.quaternion", { "W", "X", "Y", "Z" })
  local w, x, y, z = model.unit_quaternion(v[1], v[2], v[3], v[4])
  if not w then
    fail(r, rlines.quaternion, what .. ".pose.rotation.quaternion: zero quaternion")
  end
  w, x, y, z = turned(w, x, y, z)
  return id, { size = r.size, position = { x = p[1], y = p[2], z = p[3] },
    quaternion = { w = w, x = x, y = y, z = z } }
end

local function read_field(r, doc, lines)
  local f, flines = object(r, doc.field, lines.field, "field", { "length", "width" })
  local v = numbers(r, f, flines, "field", { "length", "width" })
  for i, key in ipairs({ "length", "width" }) do
    if not (v[i] > 0) then
      fail(r, flines[key], "field." .. key .. ": positive number of metres expected, got "
        .. describe(v[i]))
    end
  end
  return v[1], v[2]
end

-- The tags' size against the map's extent (`tagpose.rigid.model.size_contradiction`, the
-- field's length and width included): a refusal when the size cannot be in metres.
local function check_size(r, tags, length, width)
  local id, _, extent = model.size_contradiction(tags, math.max(length or 0, width or 0))
  if id ~= nil then
    failure.raise(("layout: %s: size %.6g is larger than the field map itself (%s%.4g m"
      .. " across): millimetres? A WPILib field map is in metres, and so is the tags' side"
      .. " (0.1651 for the 2024 and later FRC fields)"):format(r.name, r.size,
      length and ("field %.4g m x %.4g m, "):format(length, width) or "", extent))
  end
end

local function parse(r, text)
  local doc, where = json.decode(text, r.name)
  if doc == nil then failure.raise("layout: " .. where) end
  r.where = where
  local keys = doc.field ~= nil and { "tags", "field" } or { "tags" }
  local _, lines = object(r, doc, 1, "the field map", keys)
  local length, width
  if doc.field ~= nil then length, width = read_field(r, doc, lines) end
  local list = doc.tags
  if type(list) ~= "table" or list == json.NULL or (list[1] == nil and next(list) ~= nil) then
    fail(r, lines.tags, "tags: an array of {ID, pose} expected, got " .. describe(list))
  end
  if list[1] == nil then fail(r, lines.tags, "tags: the array is empty") end
  local tags, first = {}, {}
  for i, t in ipairs(list) do
    local at = where[list][i]
    local id, entry = read_tag(r, t, at, i)
    if tags[id] then
      fail(r, at, "tag " .. id .. " is listed twice (first on line " .. first[id] .. ")")
    end
    tags[id], first[id] = entry, at
  end
  check_size(r, tags, length, width)
  return { tags = tags }
end

--- Decode a WPILib field map into a layout (tag frames turned into tagpose's).
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @tparam number size the side of the tags' black squares, metres (the file has none)
-- @treturn table layout `{tags = {[id] = {size =, position =, quaternion =}}}`, metres
-- @return nil, string `"layout: name:LINE: reason"`
function M.decode(text, name, size)
  if not (is_finite(size) and size > 0) then
    return nil, "layout: " .. name .. ": a WPILib field map gives no tag size: read it with"
      .. " {size = S}, the side of the tags' black squares in metres (0.1651 for the 2024 and"
      .. " later FRC fields)"
  end
  return failure.protect(parse, { name = name, size = size }, text)
end

return M
