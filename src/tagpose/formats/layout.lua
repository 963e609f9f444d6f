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
-- * CSV (`.csv`): `id,size,x,y,z,qw,qx,qy,qz`, one tag a line (the data sets' form). The
--   header names each column once (further columns are ignored), every line has as many
--   fields as the header, numbers are decimal numerals (`compat.decimal`, as a corner log's:
--   no hexadecimal, no `inf`, no quotes, no spaces inside); blank lines and lines starting
--   with `#` are skipped;
-- * WPILib field maps (`.json`, read only): `tagpose.formats.wpilib`.
--
-- Ids are whole numbers of magnitude below 2^53 (`tagpose.rigid.model.is_id`), in every
-- format, read and written. A file larger than `MAX_BYTES` is refused unread. Writing checks
-- and encodes everything first and then writes the file whole (`tagpose.formats.output`: a
-- temporary file renamed onto the target), so a refused layout or a failed write leaves the
-- old file as it was; a target that is not a regular file (a device, a FIFO) is written
-- through, never replaced. A name is written so that the format's reader gives it back: escaped in
-- YAML (double quotes) and Lua (`\ddd`); a YAML name must be UTF-8 text.
--
-- Errors are `nil, "path:LINE: reason"`.
-- @module tagpose.formats.layout

local model = require("tagpose.rigid.model")
local yaml = require("tagpose.formats.yaml")
local luadata = require("tagpose.formats.luadata")
local output = require("tagpose.formats.output")
local compat = require("tagpose.core.compat")

local encode = require("tagpose.formats.layout_encode")

local concat = table.concat
local decimal = compat.decimal

local M = {}

--- The quaternion of a tag frame turned half a turn about its x axis, `q·(0, 1, 0, 0)`: maps
-- apriltag_ros' tag frame to tagpose's and back (`tagpose.formats.layout_encode.flip`).
-- @function flip
M.flip = encode.flip

--- Largest layout file read, in bytes (some 7000 tags in CSV, 4000 in a Lua file).
M.MAX_BYTES = 1048576

local CSV_COLUMNS = encode.CSV_COLUMNS

local function extension(path)
  return (path:match("%.([%w]+)$") or ""):lower()
end

-- "WHAT is not a tag id (...)"
local function not_id(what)
  return what .. " is not a tag id (" .. model.ID .. ")"
end

-- Add a CSV or YAML line's tag: nil, or why not (`at` the line's "name:LINE: ").
local function add_tag(tags, at, id, entry)
  if not model.is_id(id) then return at .. not_id("id " .. tostring(id)) end
  if tags[id] then return at .. "tag " .. encode.id_text(id) .. " is listed twice" end
  local _, why = model.read_tag(entry, id)
  if why then return at .. why end
  tags[id] = entry
end

-- The fields of a CSV line, trimmed.
local function csv_fields(line)
  local fields = {}
  for v in (line .. ","):gmatch("([^,]*),") do fields[#fields + 1] = v:match("^%s*(.-)%s*$") end
  return fields
end

-- The header's columns by name, or nil and why.
local function csv_header(fields)
  local header = {}
  for i, h in ipairs(fields) do
    if h == "" then return nil, "header column " .. i .. " has no name" end
    if header[h] then return nil, "header names column " .. h .. " twice" end
    header[h] = i
  end
  for _, c in ipairs(CSV_COLUMNS) do
    if not header[c] then return nil, "header has no column " .. c end
  end
  return header
end

--- Decode a CSV layout table `id,size,x,y,z,qw,qx,qy,qz` (see the module's header).
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table layout
-- @return nil, string `name:LINE: reason`
function M.decode_csv(text, name)
  local header, width, tags, n = nil, nil, {}, 0
  if text:sub(1, 3) == "\239\187\191" then text = text:sub(4) end
  text = text:gsub("\r\n?", "\n")
  for line in (text .. "\n"):gmatch("([^\n]*)\n") do
    n = n + 1
    if not (line:match("^%s*$") or line:match("^%s*#")) then
      local at = name .. ":" .. n .. ": "
      local fields = csv_fields(line)
      if not header then
        local why
        header, why = csv_header(fields)
        if not header then return nil, at .. why end
        width = #fields
      else
        if #fields ~= width then
          return nil, at .. #fields .. " fields, header has " .. width
        end
        local row = {}
        for _, c in ipairs(CSV_COLUMNS) do
          local v = decimal(fields[header[c]])
          if v == nil then return nil, at .. "column " .. c .. " is not a number" end
          row[c] = v
        end
        local why = add_tag(tags, at, row.id, { size = row.size,
          position = { x = row.x, y = row.y, z = row.z },
          quaternion = { w = row.qw, x = row.qx, y = row.qy, z = row.qz } })
        if why then return nil, why end
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
    local w, x, y, z = M.flip(v.qw, v.qx, v.qy, v.qz)
    if w < 0 then w, x, y, z = -w, -x, -y, -z end
    local why = add_tag(tags, at, v.id, { size = v.size, position = { x = v.x, y = v.y, z = v.z },
      quaternion = { w = w, x = x, y = y, z = z } })
    if why then return nil, why end
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
      return nil, name .. ":" .. line .. ": " .. not_id("tags: key " .. tostring(id))
    end
    local _, why = model.read_tag(entry, id)
    if why then return nil, name .. ":" .. line .. ": " .. why end
  end
  return value
end


--- An id as the files write it (`tagpose.formats.layout_encode.id_text`).
-- @function id_text
M.id_text = encode.id_text
--- A read layout as CSV, apriltag_ros YAML or Lua data (`tagpose.formats.layout_encode`).
-- @function encode_csv
M.encode_csv = encode.csv
--- @function encode_yaml
M.encode_yaml = encode.yaml
--- @function encode_lua
M.encode_lua = encode.lua

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
  local text, err = output.read_text(path, M.MAX_BYTES, "a layout of thousands of tags is"
    .. " smaller")
  if not text then return nil, "layout: " .. err end
  local layout, why = decode(text, path, bundle, size)
  if not layout or decode == decode_wpilib then return layout, why end
  -- a size in another unit than the positions (the WPILib reader checks its own)
  local id, side, extent = model.size_contradiction(layout.tags)
  if id ~= nil then
    return nil, ("layout: %s: tag %s is %.6g wide, more than twice the layout (its tags'"
      .. " centres span %.4g): a size in millimetres beside positions in metres? Sizes and"
      .. " positions take one unit"):format(path, tostring(id), side, extent)
  end
  return layout
end

--- The text of a layout file, in the format the path's extension names: everything `write`
-- checks before it touches a file.
-- @tparam string path
-- @tparam table tags a read layout
-- @tparam[opt] string name the layout's name
-- @treturn string
-- @return nil, string when the extension is not a layout format's or the name cannot be
--   written in it
function M.encode(path, tags, name)
  local ext = extension(path)
  local to_text = ENCODE[ext]
  if not to_text then
    return nil, "layout: " .. path .. ": .lua, .yaml, .yml or .csv expected"
  end
  if name ~= nil and type(name) ~= "string" then
    return nil, "layout: name: string expected, got " .. type(name)
  end
  if name and (ext == "yaml" or ext == "yml") and not encode.is_utf8(name) then
    return nil, "layout: name: not UTF-8 text (a YAML file is)"
  end
  return to_text(tags, name)
end

--- Write a layout file, in the format its extension names, whole or not at all: the text is
-- made first (`encode`), then written to a temporary file renamed onto `path`
-- (`tagpose.formats.output`); on any failure the old file is left as it was. A path that is
-- not a regular file (a device, a FIFO, a pipe) is written through, in place.
-- @tparam string path
-- @tparam table tags a read layout
-- @tparam[opt] string name the layout's name
-- @treturn true
-- @return nil, string
function M.write(path, tags, name)
  local text, err = M.encode(path, tags, name)
  if not text then return nil, err end
  local ok, werr = output.write(path, text)
  if not ok then return nil, "layout: " .. werr end
  return true
end

return M
