--- OpenCV FileStorage in XML and JSON, read into the record that the YAML files give
-- (`tagpose.formats.calibration.entries`), so that one reader (`tagpose.calibration.opencv`)
-- reads the three.
--
-- XML (`<?xml version="1.0"?><opencv_storage>...</opencv_storage>`, OpenCV's meaning): an
-- element of named elements is a mapping; an element of values (numbers and strings separated by
-- white space, a string with spaces in `"..."`) or of `<_>` items is a sequence, one value alone
-- a scalar; the attribute `type_id="opencv-matrix"` tags a mapping, and its `data` is always a
-- sequence. JSON: an object with a `"type_id"` is tagged by it. The tag is kept under
-- `tagpose.formats.yaml.TAG`, `null` is `yaml.NULL`, and every key and value keeps its line.
-- Functions raise the `Failure` of `tagpose.calibration.common`.
-- @module tagpose.formats.calibration.storage

local compat = require("tagpose.core.compat")
local yaml = require("tagpose.formats.yaml")
local xml = require("tagpose.formats.xml")
local json = require("tagpose.formats.json")
local common = require("tagpose.formats.calibration.common")

local byte, sub, find = string.byte, string.sub, string.find
local decimal = compat.decimal

local NULL, TAG = yaml.NULL, yaml.TAG

local M = {}

-- the value of one token as written (a quoted string, or a number, or a plain string)
local function token_value(r, raw, quoted, line)
  local s, why = xml.unescape(raw)
  if not s then common.fail(r.name, line, why) end
  if quoted then return s end
  local v = decimal(s)
  if v == nil and (find(s, "^[-+]?%.[iI][nN][fF]$") or find(s, "^%.[nN][aA][nN]$")) then
    common.fail(r.name, line, "'" .. s .. "' (not a number or infinite) is refused")
  end
  if v ~= nil and not compat.is_finite(v) then
    common.fail(r.name, line, "number " .. s .. " is beyond the range of doubles")
  end
  return v == nil and s or v
end

-- the values of a text starting on line, appended to seq (their lines to lines); the line
-- ends are counted once each as the reading moves forward (`nl`: the next one not counted),
-- so that a text of one long line is read in time linear in its length
local function tokens(r, s, line, seq, lines)
  local i = 1
  local nl = find(s, "\n", 1, true)
  while true do
    local a = find(s, "[^ \t\r\n]", i)
    if not a then return end
    while nl and nl < a do
      line = line + 1
      nl = find(s, "\n", nl + 1, true)
    end
    local e, v
    if byte(s, a) == 34 then -- "
      e = find(s, '"', a + 1, true)
      if not e then common.fail(r.name, line, "a string is not closed ('\"' expected)") end
      v = token_value(r, sub(s, a + 1, e - 1), true, line)
    else
      e = (find(s, "[ \t\r\n]", a) or #s + 1) - 1
      v = token_value(r, sub(s, a, e), false, line)
    end
    seq[#seq + 1], lines[#lines + 1] = v, line
    i = e + 1
  end
end

-- the value of an element, OpenCV's way; `as_sequence` for a matrix's data
local function xml_value(r, el, as_sequence)
  for k in pairs(el.attributes) do
    if k ~= "type_id" then
      common.fail(r.name, el.line, "<" .. el.name .. ">: attribute '" .. k .. "' (OpenCV writes"
        .. " only type_id)")
    end
  end
  local type_id = el.attributes.type_id
  local map, map_lines, seq, seq_lines, items = nil, {}, {}, {}, false
  for i = 1, #el do
    local c, line = el[i], el.lines[i]
    if type(c) == "string" then
      tokens(r, c, line, seq, seq_lines)
    elseif c.name == "_" then
      items = true
      seq[#seq + 1], seq_lines[#seq_lines + 1] = xml_value(r, c), line
    else
      map = map or {}
      if map[c.name] ~= nil then
        common.fail(r.name, line, "<" .. c.name .. "> given twice in <" .. el.name .. "> (first on"
          .. " line " .. map_lines[c.name] .. ")")
      end
      map[c.name] = xml_value(r, c, type_id ~= nil and c.name == "data")
      map_lines[c.name] = line
    end
  end
  if map and #seq > 0 then
    common.fail(r.name, seq_lines[1], "<" .. el.name .. "> (line " .. el.line .. ") holds both"
      .. " named elements and values")
  end
  if type_id then
    if #seq > 0 then
      common.fail(r.name, el.line, "<" .. el.name .. ">: type_id on values, not on named elements")
    end
    map = map or {}
    map[TAG] = type_id
  end
  if map then
    r.where[map] = map_lines
    return map
  end
  if #seq == 1 and not items and not as_sequence then return seq[1] end
  r.where[seq] = seq_lines
  return seq
end

--- Read an OpenCV FileStorage XML text.
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table the document's record `{name =, doc =, where =, top =, format = "opencv"}`
function M.xml(text, name)
  local root, err = xml.decode(text, name)
  if not root then common.refuse("calibration: " .. err) end
  if root.name ~= "opencv_storage" then
    common.fail(name, root.line, "the root element is <" .. root.name .. ">, not"
      .. " <opencv_storage>: not an OpenCV FileStorage file")
  end
  local r = { name = name, where = {} }
  local doc = xml_value(r, root)
  if root.attributes.type_id or type(doc) ~= "table" or doc[1] ~= nil then
    common.fail(name, root.line, "<opencv_storage> must hold named elements (camera_matrix, ...)")
  end
  r.where[doc] = r.where[doc] or {}
  return { name = name, doc = doc, where = r.where, top = r.where[doc], format = "opencv" }
end

-- move every object's "type_id" under TAG
local function retag(t, where)
  if type(t.type_id) == "string" then
    t[TAG], t.type_id = t.type_id, nil
  end
  for _, v in pairs(t) do
    if type(v) == "table" and v ~= NULL and where[v] then retag(v, where) end
  end
end

--- Read an OpenCV FileStorage JSON text.
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table the document's record `{name =, doc =, where =, top =, format = "opencv"}`
function M.json(text, name)
  local doc, where = json.decode(text, name, NULL)
  if doc == nil then common.refuse("calibration: " .. where) end
  if type(doc) ~= "table" or doc == NULL or doc[1] ~= nil then
    common.fail(name, 1, "an object of calibration entries expected ({\"camera_matrix\": ...})")
  end
  retag(doc, where)
  return { name = name, doc = doc, where = where, top = where[doc], format = "opencv" }
end

return M
