--- Lua camera files, read as data (`tagpose.formats.luadata`: nothing in them runs).
--
--     return { fx =, fy =, cx =, cy =, model =, distortion =, width =, height =, name =,
--       tag_size =, block_size =, unit = }
--
-- `distortion` named (`{k1 =, k2 =, p1 =, p2 =, k3 =}`, `k4..k6` for the rational model,
-- `k1..k4` with `model = "fisheye"`) or an array in OpenCV's `distCoeffs` order; `tag_size` a
-- number or `{[id] = size, default = size}`. An unknown key, a missing or malformed entry is
-- refused with its line. Functions raise the `Failure` of `tagpose.calibration.common`.
-- @module tagpose.formats.calibration.lua_file

local compat = require("tagpose.core.compat")
local luadata = require("tagpose.formats.luadata")
local camera_model = require("tagpose.core.camera")
local common = require("tagpose.formats.calibration.common")

local is_finite = compat.is_finite
local MIN_FOCAL, MAX_FOCAL = camera_model.MIN_FOCAL, camera_model.MAX_FOCAL
local MAX_CENTRE = camera_model.MAX_CENTRE
local concat = table.concat
local describe, key_name, sorted_keys = common.describe, common.key_name, common.sorted_keys
local is_integer, suggest = common.is_integer, common.suggest
local BROWN, FISHEYE, COEFFICIENTS, MODELS = common.BROWN, common.FISHEYE, common.COEFFICIENTS,
  common.MODELS

local M = {}

local KEYS = { "fx", "fy", "cx", "cy", "model", "distortion", "width", "height", "name",
  "tag_size", "block_size", "unit" }
local KNOWN = {}
for _, k in ipairs(KEYS) do KNOWN[k] = true end

-- the file being read: its name, its table, the lines of the table's keys and of every table
local function reading(name, t, where)
  return { name = name, t = t, where = where, lines = where[t] }
end

local function fail(r, at, reason)
  common.fail(r.name, at, reason)
end

local function refuse_unknown_keys(r)
  local t, lines = r.t, r.lines
  for _, k in ipairs(sorted_keys(t)) do
    if not KNOWN[k] then
      local hint
      if type(k) ~= "string" then
        fail(r, lines[k], "unexpected entry " .. key_name(k) .. " (a camera file has named"
          .. " fields only: " .. concat(KEYS, ", ") .. ")")
      elseif COEFFICIENTS[k:lower()] then
        hint = "distortion." .. k:lower()
      else
        hint = suggest(k, KEYS)
      end
      fail(r, lines[k], "unknown key " .. key_name(k) .. (hint and (" (did you mean " .. hint
        .. "?)") or (" (a camera file has " .. concat(KEYS, ", ") .. ")")))
    end
  end
end

local function check_intrinsics(r, root_line)
  local t, lines = r.t, r.lines
  for _, k in ipairs({ "fx", "fy" }) do
    local v = t[k]
    if v == nil then fail(r, root_line, "no " .. k .. " (the focal length in pixels)") end
    if not (is_finite(v) and v > 0) then
      fail(r, lines[k], k .. ": positive number expected, got " .. describe(v))
    end
    if not (v >= MIN_FOCAL and v <= MAX_FOCAL) then
      fail(r, lines[k], ("%s: a focal length in pixels between %g and %g expected, got %s")
        :format(k, MIN_FOCAL, MAX_FOCAL, describe(v)))
    end
  end
  for _, k in ipairs({ "cx", "cy" }) do
    local v = t[k]
    if v == nil then fail(r, root_line, "no " .. k .. " (the principal point in pixels)") end
    if not is_finite(v) then
      fail(r, lines[k], k .. ": finite number expected, got " .. describe(v))
    end
    if not (v >= -MAX_CENTRE and v <= MAX_CENTRE) then
      fail(r, lines[k], ("%s: a principal point coordinate in pixels within %g expected, got %s")
        :format(k, MAX_CENTRE, describe(v)))
    end
  end
end

-- check one entry k = v of the distortion table (an array of n, or named when n is 0)
local function check_coefficient(r, dlines, k, v, n, kind, names)
  if type(k) == "number" and n > 0 then
    if not is_integer(k, 1) or k > n then
      fail(r, dlines[k], "distortion: entry " .. key_name(k) .. " of an array of " .. n)
    end
    if not is_finite(v) then
      fail(r, dlines[k], "distortion[" .. k .. "]: finite number expected, got " .. describe(v))
    end
  elseif type(k) == "string" and n == 0 then
    local known = false
    for _, c in ipairs(names) do
      if c == k then known = true end
    end
    if not known then
      local hint = suggest(k, names)
      local other = kind == "fisheye" and COEFFICIENTS[k]
      local why = other and ("the fisheye model has " .. concat(FISHEYE, ", "))
        or hint and ("did you mean '" .. hint .. "'?")
        or ("the coefficients are " .. concat(names, ", "))
      fail(r, dlines[k], "distortion: unknown key " .. key_name(k) .. " (" .. why .. ")")
    end
    if not is_finite(v) then
      fail(r, dlines[k], "distortion." .. k .. ": finite number expected, got " .. describe(v))
    end
  else
    fail(r, dlines[k], "distortion: named coefficients (k1 = ...) or an array in OpenCV's"
      .. " order, not both")
  end
end

-- the coefficients in OpenCV's order, from the distortion entry (none: {})
local function coefficients(r, kind)
  local dist = r.t.distortion
  local d = {}
  if dist == nil then return d end
  if type(dist) ~= "table" then
    fail(r, r.lines.distortion, "distortion: table expected, got " .. describe(dist))
  end
  local names = kind == "fisheye" and FISHEYE or BROWN
  local dlines = r.where[dist]
  local n = #dist
  for _, k in ipairs(sorted_keys(dist)) do
    check_coefficient(r, dlines, k, dist[k], n, kind, names)
  end
  if n > 0 then
    for i = 1, n do d[i] = dist[i] end
    return common.opencv_coefficients(d, kind, function(reason)
      fail(r, r.lines.distortion, "distortion: " .. reason)
    end)
  end
  local last = kind == "fisheye" and 4 or 5
  if kind ~= "fisheye" and (dist.k4 or dist.k5 or dist.k6) then last = 8 end
  for i = 1, last do d[i] = dist[names[i]] or 0 end
  return d
end

-- the line of tag_size's key k (or of tag_size itself)
local function tag_size_line(r, k)
  local lines = r.lines
  if k == nil then return lines.tag_size end
  local tl = r.where[r.t.tag_size]
  return tl and tl[k] or lines.tag_size
end

local function check_tag_size(r, v)
  if type(v) == "number" then
    if not (is_finite(v) and v > 0) then
      fail(r, tag_size_line(r), "tag_size: positive number expected, got " .. describe(v))
    end
    return v
  end
  if type(v) ~= "table" then
    fail(r, tag_size_line(r), "tag_size: a number or a table {[id] = size, default = size}"
      .. " expected, got " .. describe(v))
  end
  local any = false
  for _, k in ipairs(sorted_keys(v)) do
    local size = v[k]
    any = true
    if k ~= "default" and not is_integer(k, 0) then
      local hint = type(k) == "string" and suggest(k, { "default" })
      fail(r, tag_size_line(r, k), "tag_size: unknown key " .. key_name(k) .. (hint
        and (" (did you mean '" .. hint .. "'?)")
        or " (tag ids are whole numbers >= 0, or 'default')"))
    end
    if not (is_finite(size) and size > 0) then
      fail(r, tag_size_line(r, k), "tag_size" .. (k == "default" and ".default" or "[" .. k
        .. "]") .. ": positive number expected, got " .. describe(size))
    end
  end
  if not any then fail(r, tag_size_line(r), "tag_size: the table is empty") end
  return v
end

-- what else the file says: width, height, name, unit, tag_size, block_size
local function read_info(r)
  local t, lines = r.t, r.lines
  local info = { format = "lua", path = r.name }
  for _, k in ipairs({ "width", "height" }) do
    local v = t[k]
    if v ~= nil and not is_integer(v, 1) then
      fail(r, lines[k], k .. ": whole number of pixels expected, got " .. describe(v))
    end
    info[k] = v
  end
  for _, k in ipairs({ "name", "unit" }) do
    local v = t[k]
    if v ~= nil and type(v) ~= "string" then
      fail(r, lines[k], k .. ": string expected, got " .. describe(v))
    end
    info[k] = v
  end
  if t.tag_size ~= nil then info.tag_size = check_tag_size(r, t.tag_size) end
  if t.block_size ~= nil then
    local v = t.block_size
    if not (is_finite(v) and v > 0) then
      fail(r, lines.block_size, "block_size: positive number expected, got " .. describe(v))
    end
    info.block_size = v
  end
  return info
end

--- Read a Lua camera file's text.
-- @tparam string text
-- @tparam string name the file's name, for messages
-- @treturn table the camera
-- @treturn table info `{format = "lua", path =, width =, height =, name =, unit =, tag_size =,
--   block_size =}` (what the file gives of them)
-- @raise a `Failure` of `tagpose.calibration.common` when the file is refused
function M.read(text, name)
  local t, where, root_line = luadata.decode(text, name)
  if t == nil and type(where) == "string" then common.refuse("calibration: " .. where) end
  if type(t) ~= "table" then
    common.fail(name, root_line, "a camera table expected, got " .. describe(t))
  end
  local r = reading(name, t, where)
  refuse_unknown_keys(r)
  check_intrinsics(r, root_line)
  local model = t.model
  if model ~= nil and not MODELS[model] then
    fail(r, r.lines.model, "model: 'pinhole' or 'fisheye' expected, got " .. describe(model))
  end
  local kind = MODELS[model or "pinhole"]
  local d = coefficients(r, kind)
  local info = read_info(r)
  local k = { t.fx, 0, t.cx, 0, t.fy, t.cy, 0, 0, 1 }
  local camera = common.build(k, d, kind, function(reason) fail(r, root_line, reason) end)
  return camera, info
end

return M
