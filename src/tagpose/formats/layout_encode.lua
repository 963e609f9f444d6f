--- Layout files written: a read layout (`tagpose.rigid.model.read`) as the text of a CSV, an
-- apriltag_ros `tags.yaml` or a Lua data file, each read back by `tagpose.formats.layout` to
-- the last bit (numbers as `%.17g`, ids as whole numbers, names escaped so that the format's
-- reader gives them back).
-- @module tagpose.formats.layout_encode

local model = require("tagpose.rigid.model")

local format, concat, byte = string.format, table.concat, string.byte

local M = {}

--- The columns of a CSV layout, in the order written (also the keys of an apriltag_ros entry).
M.CSV_COLUMNS = { "id", "size", "x", "y", "z", "qw", "qx", "qy", "qz" }

local CSV_COLUMNS = M.CSV_COLUMNS

--- The quaternion of a tag frame turned half a turn about its x axis: `q·(0, 1, 0, 0)`. Maps
-- apriltag_ros' tag frame to tagpose's and back.
-- @tparam number w
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @treturn number w
-- @treturn number x
-- @treturn number y
-- @treturn number z
function M.flip(w, x, y, z)
  return -x, w, z, -y
end

local function num(v)
  return format("%.17g", v)
end

--- An id as the files write it (a whole number, no exponent, no `-0`).
-- @tparam number id a tag id (`tagpose.rigid.model.is_id`)
-- @treturn string
function M.id_text(id)
  if id == 0 then return "0" end
  return format("%.0f", id)
end

local id_text = M.id_text

-- the read layout's entries, by id
local function each(tags)
  local i = 0
  return function()
    i = i + 1
    local id = tags.ids[i]
    if id == nil then return nil end
    local t = tags[id]
    local e = model.entry(t.r, t.x, t.y, t.z, t.size)
    return id, e
  end
end

--- Encode a read layout as CSV (a CSV layout has no name).
-- @tparam table tags a layout read by `tagpose.rigid.model.read`
-- @treturn string
function M.csv(tags)
  local lines = { concat(CSV_COLUMNS, ",") }
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    lines[#lines + 1] = concat({ id_text(id), num(e.size), num(p.x), num(p.y), num(p.z),
      num(q.w), num(q.x), num(q.y), num(q.z) }, ",")
  end
  return concat(lines, "\n") .. "\n"
end

--- True when s is UTF-8 text (no byte out of place, no overlong or surrogate form).
-- @tparam string s
-- @treturn boolean
function M.is_utf8(s)
  local i, n = 1, #s
  while i <= n do
    local c = byte(s, i)
    local len, lo = 1, 0
    if c >= 0xF0 and c <= 0xF4 then
      len, lo = 4, (c == 0xF0 and 0x90 or 0x80)
    elseif c >= 0xE0 and c <= 0xEF then
      len, lo = 3, (c == 0xE0 and 0xA0 or 0x80)
    elseif c >= 0xC2 and c <= 0xDF then
      len, lo = 2, 0x80
    elseif c >= 0x80 then
      return false
    end
    for k = 1, len - 1 do
      local b = byte(s, i + k)
      local hi = (k == 1 and (c == 0xED and 0x9F or c == 0xF4 and 0x8F)) or 0xBF
      if not b or b < (k == 1 and lo or 0x80) or b > hi then return false end
    end
    i = i + len
  end
  return true
end

-- A YAML double-quoted scalar of s (UTF-8 text): `"` and `\` escaped, control characters as
-- `\xNN` (their code points).
local function quote_yaml(s)
  return '"' .. s:gsub('[%c"\\\127]', function(c)
    if c == '"' or c == "\\" then return "\\" .. c end
    return format("\\x%02X", byte(c))
  end) .. '"'
end

-- A Lua string literal of s that tagpose.luadata reads back: `"` and `\` escaped, control
-- characters as `\ddd` (three digits).
local function quote_lua(s)
  return '"' .. s:gsub('[%c"\\\127]', function(c)
    if c == '"' or c == "\\" then return "\\" .. c end
    return format("\\%03d", byte(c))
  end) .. '"'
end

--- Encode a read layout as an apriltag_ros `tags.yaml` of one bundle (tag frames converted).
-- @tparam table tags a read layout
-- @tparam[opt="layout"] string name the bundle's name (UTF-8 text)
-- @treturn string
function M.yaml(tags, name)
  local lines = { "# apriltag_ros tag bundle, written by tagpose (tag frames as apriltag_ros",
    "# defines them: corners p0..p3 at (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2))",
    "standalone_tags:", "  [", "  ]", "tag_bundles:", "  [", "    {",
    "      name: " .. quote_yaml(name or "layout") .. ",", "      layout:", "        [" }
  local items = {}
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    local w, x, y, z = M.flip(q.w, q.x, q.y, q.z)
    if w < 0 then w, x, y, z = -w, -x, -y, -z end
    items[#items + 1] = format("          {id: %s, size: %s, x: %s, y: %s, z: %s, qw: %s, qx: %s,"
      .. " qy: %s, qz: %s}", id_text(id), num(e.size), num(p.x), num(p.y), num(p.z), num(w),
      num(x), num(y), num(z))
  end
  lines[#lines + 1] = concat(items, ",\n")
  lines[#lines + 1] = "        ]\n    }\n  ]"
  return concat(lines, "\n") .. "\n"
end

--- Encode a read layout as a Lua data file.
-- @tparam table tags a read layout
-- @tparam[opt] string name the layout's name
-- @treturn string
function M.lua(tags, name)
  local lines = {
    "-- a tagpose layout: X_body = R(quaternion) * X_tag + position, tag frames as tagpose's",
    "-- (x right, y down, z into the tag; corners c1 = (-s/2, +s/2), c2 = (+s/2, +s/2), ...)",
    "return {" }
  if name then lines[#lines + 1] = "  name = " .. quote_lua(name) .. "," end
  lines[#lines + 1] = "  tags = {"
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    lines[#lines + 1] = format("    [%s] = { size = %s,", id_text(id), num(e.size))
    lines[#lines + 1] = format("      position = { x = %s, y = %s, z = %s },", num(p.x), num(p.y),
      num(p.z))
    lines[#lines + 1] = format("      quaternion = { w = %s, x = %s, y = %s, z = %s } },",
      num(q.w), num(q.x), num(q.y), num(q.z))
  end
  lines[#lines + 1] = "  },\n}"
  return concat(lines, "\n") .. "\n"
end

return M
