--- Layout files: Lua data files, apriltag_ros `tags.yaml` and CSV tables, read and written.
--
-- * Lua (`.lua`): a file returning the layout table itself,
--   `return {name = "cube", tags = {[0] = {size =, position = {x =, y =, z =},
--   quaternion = {w =, x =, y =, z =}}, ...}}`, read as data (table constructors, numbers,
--   strings, booleans: never run);
-- * apriltag_ros (`.yaml`, `.yml`): `tag_bundles: [{name: N, layout: [{id: I, size: S, x:,
--   y:, z:, qw:, qx:, qy:, qz:}, ...]}, ...]` (`standalone_tags` ignored). apriltag_ros puts a
--   tag's corners p0..p3 at `(-s/2, -s/2)`, `(s/2, -s/2)`, `(s/2, s/2)`, `(-s/2, s/2)` in its
--   tag frame, y up and z out of the tag: that frame is tagpose's turned half a turn about x,
--   `R_tagpose = R_ros·diag(1, -1, -1)`, so each quaternion is multiplied on the right by
--   `(0, 1, 0, 0)` on reading and on writing (the turn is its own inverse); positions, sizes and
--   the body frame are the same;
-- * CSV (`.csv`): `id,size,x,y,z,qw,qx,qy,qz`, one tag a line (the data sets' form);
-- * WPILib field maps (`.json`, read only): `tagpose.formats.wpilib`.
--
-- Errors are `nil, "path:LINE: reason"`.
-- @module tagpose.formats.layout

local model = require("tagpose.layout.model")
local yaml = require("tagpose.formats.yaml")
local luadata = require("tagpose.formats.luadata")

local format, concat = string.format, table.concat

local M = {}

local CSV_COLUMNS = { "id", "size", "x", "y", "z", "qw", "qx", "qy", "qz" }

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

local function extension(path)
  return (path:match("%.([%w]+)$") or ""):lower()
end

local function read_text(path)
  local f, err = io.open(path, "r")
  if not f then return nil, "layout: " .. tostring(err) end
  local text = f:read("*a")
  f:close()
  return text
end

--- Decode a CSV layout table `id,size,x,y,z,qw,qx,qy,qz`.
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table layout
-- @return nil, string `name:LINE: reason`
function M.decode_csv(text, name)
  local header, tags, n = nil, {}, 0
  for line in (text .. "\n"):gmatch("([^\n]*)\n") do
    n = n + 1
    line = line:gsub("\r$", "")
    if not (line:match("^%s*$") or line:match("^%s*#")) then
      local fields = {}
      for v in (line .. ","):gmatch("([^,]*),") do fields[#fields + 1] = v:match("^%s*(.-)%s*$") end
      local at = name .. ":" .. n .. ": "
      if not header then
        header = {}
        for i, h in ipairs(fields) do header[h] = i end
        for _, c in ipairs(CSV_COLUMNS) do
          if not header[c] then return nil, at .. "header has no column " .. c end
        end
      else
        local row = {}
        for _, c in ipairs(CSV_COLUMNS) do
          local v = tonumber(fields[header[c]])
          if v == nil then return nil, at .. "column " .. c .. " is not a number" end
          row[c] = v
        end
        if not model.is_id(row.id) then return nil, at .. "id is not a whole number" end
        if tags[row.id] then return nil, at .. "tag " .. row.id .. " is listed twice" end
        local entry = { size = row.size, position = { x = row.x, y = row.y, z = row.z },
          quaternion = { w = row.qw, x = row.qx, y = row.qy, z = row.qz } }
        local _, why = model.read_tag(entry, row.id)
        if why then return nil, at .. why end
        tags[row.id] = entry
      end
    end
  end
  if not header then return nil, name .. ":1: no header line" end
  return { tags = tags }
end

-- Check a decoded YAML mapping has a number under key; the line of the entry otherwise.
local function number_field(t, key, where, at, line)
  local v = t[key]
  if type(v) ~= "number" then
    line = where[t] and where[t][key] or line
    return nil, at .. ":" .. line .. ": " .. key .. ": number expected"
  end
  return v
end

--- Decode an apriltag_ros `tags.yaml` into a layout (tag frames converted to tagpose's).
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @tparam[opt] string bundle the bundle to read, by name (needed when there are several)
-- @treturn table layout, with the bundle's `name`
-- @return nil, string `name:LINE: reason`
function M.decode_yaml(text, name, bundle)
  local doc, where = yaml.decode(text, name)
  if doc == nil then return nil, where end
  local bundles = type(doc) == "table" and doc.tag_bundles
  if type(bundles) ~= "table" or bundles[1] == nil then
    local line = type(doc) == "table" and where[doc] and where[doc].tag_bundles or 1
    return nil, name .. ":" .. line .. ": a list tag_bundles of {name, layout} expected"
  end
  local chosen
  if bundle then
    for _, b in ipairs(bundles) do
      if type(b) == "table" and b.name == bundle then chosen = b end
    end
    if not chosen then
      return nil, name .. ":" .. where[doc].tag_bundles .. ": no bundle named " .. bundle
    end
  elseif #bundles > 1 then
    local names = {}
    for i, b in ipairs(bundles) do names[i] = type(b) == "table" and tostring(b.name) or "?" end
    return nil, name .. ":" .. where[doc].tag_bundles .. ": " .. #bundles .. " bundles ("
      .. concat(names, ", ") .. "): name the one to read"
  else
    chosen = bundles[1]
  end
  local list = type(chosen) == "table" and chosen.layout
  if type(list) ~= "table" then
    local line = where[bundles][1] or 1
    return nil, name .. ":" .. line .. ": the bundle has no layout list"
  end
  local tags = {}
  for i, t in ipairs(list) do
    local line = where[list][i]
    local at = name .. ":" .. line .. ": "
    if type(t) ~= "table" then return nil, at .. "{id, size, x, ...} expected" end
    local v = {}
    for _, key in ipairs(CSV_COLUMNS) do
      local x, why = number_field(t, key, where, name, line)
      if not x then return nil, why end
      v[key] = x
    end
    if not model.is_id(v.id) then return nil, at .. "id is not a whole number" end
    if tags[v.id] then return nil, at .. "tag " .. v.id .. " is listed twice" end
    local w, x, y, z = M.flip(v.qw, v.qx, v.qy, v.qz)
    if w < 0 then w, x, y, z = -w, -x, -y, -z end
    local entry = { size = v.size, position = { x = v.x, y = v.y, z = v.z },
      quaternion = { w = w, x = x, y = y, z = z } }
    local _, why = model.read_tag(entry, v.id)
    if why then return nil, at .. why end
    tags[v.id] = entry
  end
  if next(tags) == nil then
    return nil, name .. ":" .. (where[chosen] and where[chosen].layout or 1)
      .. ": the bundle's layout is empty"
  end
  local n = chosen.name
  return { name = type(n) == "string" and n or nil, tags = tags }
end

--- Decode a Lua layout file (read as data, never run).
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table layout
-- @return nil, string `name:LINE: reason`
function M.decode_lua(text, name)
  local value, where, first = luadata.decode(text, name)
  if value == nil then return nil, where end
  if type(value) ~= "table" then
    return nil, name .. ":" .. (first or 1) .. ": the file must return a layout table"
  end
  local tags = value.tags
  if type(tags) ~= "table" then
    local line = where[value] and where[value].tags or first or 1
    return nil, name .. ":" .. line .. ": tags: a table {[id] = tag} expected"
  end
  for key in pairs(value) do
    if key ~= "tags" and key ~= "name" then
      return nil, name .. ":" .. (where[value] and where[value][key] or first or 1)
        .. ": unknown key " .. tostring(key) .. " (a layout has tags and a name)"
    end
  end
  if value.name ~= nil and type(value.name) ~= "string" then
    return nil, name .. ":" .. where[value].name .. ": name: string expected"
  end
  for id, entry in pairs(tags) do
    local line = where[tags] and where[tags][id] or first or 1
    if not model.is_id(id) then
      return nil, name .. ":" .. line .. ": tags: key " .. tostring(id) .. " is not a tag id"
    end
    local _, why = model.read_tag(entry, id)
    if why then return nil, name .. ":" .. line .. ": " .. why end
  end
  return value
end

local function num(v)
  return format("%.17g", v)
end

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

--- Encode a read layout as CSV.
-- @tparam table tags a layout read by `tagpose.layout.model.read`
-- @treturn string
function M.encode_csv(tags)
  local lines = { concat(CSV_COLUMNS, ",") }
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    lines[#lines + 1] = concat({ format("%d", id), num(e.size), num(p.x), num(p.y), num(p.z),
      num(q.w), num(q.x), num(q.y), num(q.z) }, ",")
  end
  return concat(lines, "\n") .. "\n"
end

local function quote_yaml(s)
  return "'" .. s:gsub("'", "''") .. "'"
end

--- Encode a read layout as an apriltag_ros `tags.yaml` of one bundle (tag frames converted).
-- @tparam table tags a read layout
-- @tparam[opt="layout"] string name the bundle's name
-- @treturn string
function M.encode_yaml(tags, name)
  local lines = { "# apriltag_ros tag bundle, written by tagpose (tag frames as apriltag_ros",
    "# defines them: corners p0..p3 at (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2))",
    "standalone_tags:", "  [", "  ]", "tag_bundles:", "  [", "    {",
    "      name: " .. quote_yaml(name or "layout") .. ",", "      layout:", "        [" }
  local items = {}
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    local w, x, y, z = M.flip(q.w, q.x, q.y, q.z)
    if w < 0 then w, x, y, z = -w, -x, -y, -z end
    items[#items + 1] = format("          {id: %d, size: %s, x: %s, y: %s, z: %s, qw: %s, qx: %s,"
      .. " qy: %s, qz: %s}", id, num(e.size), num(p.x), num(p.y), num(p.z), num(w), num(x),
      num(y), num(z))
  end
  lines[#lines + 1] = concat(items, ",\n")
  lines[#lines + 1] = "        ]"
  lines[#lines + 1] = "    }"
  lines[#lines + 1] = "  ]"
  return concat(lines, "\n") .. "\n"
end

--- Encode a read layout as a Lua data file.
-- @tparam table tags a read layout
-- @tparam[opt] string name the layout's name
-- @treturn string
function M.encode_lua(tags, name)
  local lines = {
    "-- a tagpose layout: X_body = R(quaternion) * X_tag + position, tag frames as in",
    "-- tagpose's DESIGN.md (x right, y down, z into the tag; corners c1 = (-s/2, +s/2), ...)",
    "return {" }
  if name then lines[#lines + 1] = format("  name = %q,", name) end
  lines[#lines + 1] = "  tags = {"
  for id, e in each(tags) do
    local p, q = e.position, e.quaternion
    lines[#lines + 1] = format("    [%d] = { size = %s,", id, num(e.size))
    lines[#lines + 1] = format("      position = { x = %s, y = %s, z = %s },", num(p.x), num(p.y),
      num(p.z))
    lines[#lines + 1] = format("      quaternion = { w = %s, x = %s, y = %s, z = %s } },",
      num(q.w), num(q.x), num(q.y), num(q.z))
  end
  lines[#lines + 1] = "  },"
  lines[#lines + 1] = "}"
  return concat(lines, "\n") .. "\n"
end

-- a WPILib field map (loaded when first read): the bundle names nothing there, size is needed
local function decode_wpilib(text, name, bundle, size)
  if bundle ~= nil then return nil, "layout: " .. name .. ": a WPILib field map has no bundles" end
  return require("tagpose.formats.wpilib").decode(text, name, size)
end

local DECODE = { lua = M.decode_lua, yaml = M.decode_yaml, yml = M.decode_yaml,
  csv = M.decode_csv, json = decode_wpilib }
local ENCODE = { lua = M.encode_lua, yaml = M.encode_yaml, yml = M.encode_yaml,
  csv = M.encode_csv }

--- Read a layout file, in the format its extension names.
-- @tparam string path
-- @tparam[opt] string|table options for a `tags.yaml`, the bundle to read; or `{bundle =,
--   size =}`, `size` the tags' side for a WPILib field map (`.json`), which has none
-- @treturn table layout
-- @return nil, string
function M.read(path, options)
  local bundle, size = options, nil
  if type(options) == "table" then bundle, size = options.bundle, options.size end
  local decode = DECODE[extension(path)]
  if not decode then
    return nil, "layout: " .. path .. ": .lua, .yaml, .yml, .csv or .json expected"
  end
  if size ~= nil and decode ~= decode_wpilib then
    return nil, "layout: " .. path .. ": size is for WPILib field maps (.json): this file gives"
      .. " each tag's size"
  end
  local text, err = read_text(path)
  if not text then return nil, err end
  return decode(text, path, bundle, size)
end

--- Write a layout file, in the format its extension names.
-- @tparam string path
-- @tparam table tags a read layout
-- @tparam[opt] string name the layout's name
-- @treturn true
-- @return nil, string
function M.write(path, tags, name)
  local encode = ENCODE[extension(path)]
  if not encode then
    return nil, "layout: " .. path .. ": .lua, .yaml, .yml or .csv expected"
  end
  local f, err = io.open(path, "w")
  if not f then return nil, "layout: " .. tostring(err) end
  local ok, werr = f:write(encode(tags, name))
  local closed, cerr = f:close()
  if not ok or not closed then return nil, "layout: " .. tostring(werr or cerr) end
  return true
end

return M
