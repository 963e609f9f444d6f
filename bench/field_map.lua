-- A WPILib field map (the JSON of WPILib's AprilTagFieldLayout) for the field benchmark, until
-- tagpose.layout.read reads such files itself:
--
--   {"tags": [{"ID": n, "pose": {"translation": {"x", "y", "z"},
--              "rotation": {"quaternion": {"W", "X", "Y", "Z"}}}}, ...],
--    "field": {"length", "width"}}
--
-- metres, the field frame's z up. WPILib's tag frame has x out of the tag's face (towards whoever
-- looks at it), y to the viewer's right and z up; tagpose's has x right, y down and z into the
-- tag, seen from the front. So tagpose's axes are, in WPILib's tag frame, x = +y, y = -z,
-- z = -x: the tag → field rotation of tagpose's layout is R_wpilib · C, C's columns those three.
--
--   local map = dofile("bench/field_map.lua")
--   local field = map.read("bench/field/2024-crescendo.json")   -- {tags = {...}, length, width}
--   local layout = map.layout(field, 0.1651)                    -- tagpose's layout
--   local corners = map.corners(field.tags[1], 0.1651)          -- c1..c4 in the field, from
--                                                               -- WPILib's frame directly
--   local q = map.quaternion(map.matrix(w, x, y, z))            -- {w, x, y, z}, w >= 0
--
-- Self-contained (no tagpose): the benchmark's generator uses it too.

local sqrt = math.sqrt

local M = {}

---------------------------------------------------------------------------------------------
-- A small JSON reader (objects, arrays, strings without escapes, numbers, true, false,
-- null): enough for field maps, with the line of an error.

local function reader(text, path)
  local pos = 1
  local function fail(what)
    local line = select(2, text:sub(1, pos):gsub("\n", "")) + 1
    error(("%s:%d: %s"):format(path, line, what), 0)
  end
  local function skip()
    pos = text:find("[^ \t\r\n]", pos) or #text + 1
  end
  local value
  local function string_value()
    local s, e = text:find('^"[^"\\]*"', pos)
    if not s then fail("string without escapes expected") end
    pos = e + 1
    return text:sub(s + 1, e - 1)
  end
  function value()
    skip()
    local c = text:sub(pos, pos)
    if c == "{" then
      local t = {}
      pos = pos + 1
      skip()
      if text:sub(pos, pos) == "}" then pos = pos + 1 return t end
      while true do
        skip()
        if text:sub(pos, pos) ~= '"' then fail("key expected") end
        local k = string_value()
        skip()
        if text:sub(pos, pos) ~= ":" then fail("':' expected") end
        pos = pos + 1
        t[k] = value()
        skip()
        c = text:sub(pos, pos)
        pos = pos + 1
        if c == "}" then return t end
        if c ~= "," then fail("',' or '}' expected") end
      end
    elseif c == "[" then
      local t = {}
      pos = pos + 1
      skip()
      if text:sub(pos, pos) == "]" then pos = pos + 1 return t end
      while true do
        t[#t + 1] = value()
        skip()
        c = text:sub(pos, pos)
        pos = pos + 1
        if c == "]" then return t end
        if c ~= "," then fail("',' or ']' expected") end
      end
    elseif c == '"' then
      return string_value()
    end
    for word, v in pairs({ ["true"] = true, ["false"] = false, null = M.NULL }) do
      if text:sub(pos, pos + #word - 1) == word then
        pos = pos + #word
        return v
      end
    end
    local s, e = text:find("^-?%d+%.?%d*[eE]?[-+]?%d*", pos)
    if not s then fail("value expected") end
    pos = e + 1
    return tonumber(text:sub(s, e)) or fail("bad number")
  end
  return function()
    local v = value()
    skip()
    if pos <= #text then fail("text after the value") end
    return v
  end
end

M.NULL = setmetatable({}, { __tostring = function() return "null" end })

local function number(v, what, path)
  if type(v) ~= "number" then error(path .. ": " .. what .. ": number expected", 0) end
  return v
end

--- Read a field map: `{tags = {[id] = {id, x, y, z, qw, qx, qy, qz}}, ids = {...}, length, width}`
-- (the quaternion normalised). Raises "path:line: reason" on a malformed file.
function M.read(path)
  local f = assert(io.open(path, "r"))
  local text = f:read("*a")
  f:close()
  local doc = reader(text, path)()
  if type(doc) ~= "table" or type(doc.tags) ~= "table" then
    error(path .. ": {\"tags\": [...]} expected", 0)
  end
  local out = { tags = {}, ids = {} }
  for k, t in ipairs(doc.tags) do
    local what = "tags[" .. k .. "]"
    local p = t.pose or {}
    local tr, q = p.translation or {}, (p.rotation or {}).quaternion or {}
    local tag = { id = number(t.ID, what .. ".ID", path),
      x = number(tr.x, what .. ".pose.translation.x", path),
      y = number(tr.y, what .. ".pose.translation.y", path),
      z = number(tr.z, what .. ".pose.translation.z", path),
      qw = number(q.W, what .. ".quaternion.W", path), qx = number(q.X, what .. ".X", path),
      qy = number(q.Y, what .. ".Y", path), qz = number(q.Z, what .. ".Z", path) }
    local n = sqrt(tag.qw ^ 2 + tag.qx ^ 2 + tag.qy ^ 2 + tag.qz ^ 2)
    tag.qw, tag.qx, tag.qy, tag.qz = tag.qw / n, tag.qx / n, tag.qy / n, tag.qz / n
    out.tags[tag.id] = tag
    out.ids[#out.ids + 1] = tag.id
  end
  table.sort(out.ids)
  local field = doc.field or {}
  out.length, out.width = field.length, field.width
  return out
end

--- The rotation of a unit quaternion, flat row-major.
function M.matrix(w, x, y, z)
  return { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
end

-- tagpose's tag axes in WPILib's tag frame, as the columns of C: x = +y, y = -z, z = -x
local C = { 0, 0, -1, 1, 0, 0, 0, -1, 0 }

local function mul(a, b)
  local c = {}
  for i = 0, 6, 3 do
    for j = 1, 3 do
      c[i + j] = a[i + 1] * b[j] + a[i + 2] * b[3 + j] + a[i + 3] * b[6 + j]
    end
  end
  return c
end

--- The unit quaternion (w >= 0) of a rotation, flat row-major: `{w, x, y, z}` (Shepperd's
-- branches: the largest of the trace and the diagonal picks one).
function M.quaternion(m)
  local t = m[1] + m[5] + m[9]
  local w, x, y, z
  if t >= m[1] and t >= m[5] and t >= m[9] then
    w = sqrt(1 + t) / 2
    x, y, z = (m[8] - m[6]) / (4 * w), (m[3] - m[7]) / (4 * w), (m[4] - m[2]) / (4 * w)
  elseif m[1] >= m[5] and m[1] >= m[9] then
    x = sqrt(1 + m[1] - m[5] - m[9]) / 2
    w, y, z = (m[8] - m[6]) / (4 * x), (m[2] + m[4]) / (4 * x), (m[3] + m[7]) / (4 * x)
  elseif m[5] >= m[9] then
    y = sqrt(1 - m[1] + m[5] - m[9]) / 2
    w, x, z = (m[3] - m[7]) / (4 * y), (m[2] + m[4]) / (4 * y), (m[6] + m[8]) / (4 * y)
  else
    z = sqrt(1 - m[1] - m[5] + m[9]) / 2
    w, x, y = (m[4] - m[2]) / (4 * z), (m[3] + m[7]) / (4 * z), (m[6] + m[8]) / (4 * z)
  end
  if w < 0 then w, x, y, z = -w, -x, -y, -z end
  return { w = w, x = x, y = y, z = z }
end

--- tagpose's layout of a field map, every tag of side `size` (tagpose's tag frame: see the
-- header); the body frame is the field's.
function M.layout(field, size)
  local tags = {}
  for _, id in ipairs(field.ids) do
    local t = field.tags[id]
    tags[id] = { size = size, position = { x = t.x, y = t.y, z = t.z },
      quaternion = M.quaternion(mul(M.matrix(t.qw, t.qx, t.qy, t.qz), C)) }
  end
  return { tags = tags }
end

--- The four corners of a tag of side `size` in the field, in detection order (c1 bottom-left,
-- c2 bottom-right, c3 top-right, c4 top-left, as seen from the front), straight from WPILib's
-- tag frame: (0, ∓s/2, ∓s/2), y to the viewer's right, z up.
function M.corners(t, size)
  local h = size / 2
  local r = M.matrix(t.qw, t.qx, t.qy, t.qz)
  local out = {}
  for k, c in ipairs({ { -h, -h }, { h, -h }, { h, h }, { -h, h } }) do
    local y, z = c[1], c[2]
    out[k] = { t.x + r[2] * y + r[3] * z, t.y + r[5] * y + r[6] * z, t.z + r[8] * y + r[9] * z }
  end
  return out
end

--- The outward normal of a tag (WPILib's x) in the field.
function M.normal(t)
  local r = M.matrix(t.qw, t.qx, t.qy, t.qz)
  return r[1], r[4], r[7]
end

return M
