--- Calibration files: the camera (and the tag sizes) of the files users have.
--
-- `read` takes a file in one of these formats and returns a plain tagpose camera
-- `{fx =, fy =, cx =, cy =, model =, distortion =}`, built by `tagpose.camera.from_matrix`,
-- and what else the file said:
--
-- * a **Lua camera file**, read as data (`tagpose.luadata`: nothing in it runs):
--   `return { fx =, fy =, cx =, cy =, model =, distortion =, width =, height =, name =,
--   tag_size =, block_size =, unit = }`; `distortion` named (`{k1 =, k2 =, p1 =, p2 =, k3 =}`,
--   `k4..k6` for the rational model, `k1..k4` with `model = "fisheye"`) or an array in OpenCV's
--   `distCoeffs` order; `tag_size` a number or `{[id] = size, default = size}`;
-- * **ROS `camera_calibration`** YAML (`ost.yaml`; also what `camera_info_manager` writes):
--   `image_width, image_height, camera_name, camera_matrix {rows, cols, data},
--   distortion_model, distortion_coefficients, rectification_matrix, projection_matrix`;
-- * a **ROS `CameraInfo` message** as `rostopic echo` / `ros2 topic echo` print it (`height,
--   width, distortion_model, D, K, R, P, binning_x, binning_y, roi, header`, or lower case
--   `d, k, r, p`);
-- * **OpenCV FileStorage** YAML (`%YAML:1.0`) with `!!opencv-matrix` entries, under the names
--   OpenCV's calibration samples write (`camera_matrix`, `distortion_coefficients`,
--   `image_width`, `image_height`, `fisheye_model`) or the short `K` / `D` (also `cameraMatrix` /
--   `distCoeffs`).
--
-- A Lua file is told by its name ending in `.lua`, a YAML file by `.yaml` or `.yml`; another
-- name by its text (`return` or `--` first: Lua). Anything not understood is refused with its
-- line: an unknown key (naming the likely intended one), a missing or malformed entry, a
-- distortion model or coefficient count tagpose does not have. In OpenCV files, whose
-- samples store much else (`avg_reprojection_error`, `extrinsic_parameters`, ...), unknown
-- keys are listed in `info.ignored` instead, unless they look like a misspelling of a key that
-- is read.
--
-- The camera is that of the image the calibration was made on (`K`, `D`): corners detected
-- on a rectified image (`image_rect`) belong instead to `info.projection` without distortion.
-- @module tagpose.calibration

local compat = require("tagpose.compat")
local camera_model = require("tagpose.camera")
local yaml = require("tagpose.yaml")
local luadata = require("tagpose.luadata")

local is_finite = compat.is_finite
local floor, min = math.floor, math.min
local concat = table.concat

local M = {}

--- Largest calibration file read, in bytes (a calibration is a few hundred).
M.MAX_BYTES = 1048576

local Failure = {}

local function failure(name, at, reason)
  error(setmetatable({ message = "calibration: " .. name .. (at and (":" .. at) or "") .. ": "
    .. reason }, Failure), 0)
end

-- optimal string alignment distance of two short strings, ignoring case
local function distance(a, b)
  a, b = a:lower(), b:lower()
  if a == b then return 0 end
  local la, lb = #a, #b
  local prev2, prev = {}, {}
  for j = 0, lb do prev[j] = j end
  for i = 1, la do
    local cur = { [0] = i }
    for j = 1, lb do
      local cost = a:byte(i) == b:byte(j) and 0 or 1
      local d = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost)
      if i > 1 and j > 1 and a:byte(i) == b:byte(j - 1) and a:byte(i - 1) == b:byte(j) then
        d = min(d, prev2[j - 2] + 1)
      end
      cur[j] = d
    end
    prev2, prev = prev, cur
  end
  return prev[lb]
end

--- The candidate a mistyped key most likely meant (differing in case only, or by one edit
-- for a key of up to 4 characters, two for a longer one; an edit is an insertion, a deletion,
-- a substitution or a swap of neighbours), or nil.
-- @tparam string key
-- @tparam {string,...} candidates
-- @treturn string|nil
function M.suggest(key, candidates)
  if type(key) ~= "string" or #key > 64 then return nil end
  local best, best_d = nil, 3
  for _, c in ipairs(candidates) do
    local d = distance(key, c)
    if d < best_d and (d == 0 or d <= (#key <= 4 and 1 or 2)) then best, best_d = c, d end
  end
  return best
end

local function describe(v)
  if v == yaml.NULL then return "null" end
  local t = type(v)
  if t == "number" or t == "string" then return t .. " " .. tostring(v) end
  return t
end

local function key_name(k)
  if type(k) == "string" then return "'" .. k .. "'" end
  return "[" .. tostring(k) .. "]"
end

local function sorted_keys(t)
  local keys = {}
  for k in pairs(t) do
    if k ~= yaml.TAG then keys[#keys + 1] = k end
  end
  table.sort(keys, function(a, b)
    if type(a) == type(b) and (type(a) == "string" or type(a) == "number") then return a < b end
    return type(a) < type(b)
  end)
  return keys
end

local function is_integer(v, lo)
  return is_finite(v) and v == floor(v) and v >= lo
end

local BROWN = { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
local FISHEYE = { "k1", "k2", "k3", "k4" }
local COEFFICIENTS = { k1 = true, k2 = true, k3 = true, k4 = true, k5 = true, k6 = true,
  p1 = true, p2 = true }
local MODELS = { pinhole = "pinhole", plumb_bob = "pinhole", rational_polynomial = "pinhole",
  fisheye = "fisheye", equidistant = "fisheye" }

-- the coefficient array D (OpenCV order) for a model kind, from n numbers; 12 and 14
-- coefficients (thin prism, tilt) only when those extra terms are 0
local function opencv_coefficients(d, kind, fail)
  local n = #d
  if n == 0 then return {} end
  if kind == "fisheye" then
    if n ~= 4 then fail("the fisheye (equidistant) model has 4 coefficients k1, k2, k3, k4, got "
      .. n) end
    return d
  end
  if n == 12 or n == 14 then
    for i = 9, n do
      if d[i] ~= 0 then
        fail("coefficient " .. i .. " of " .. n .. " is " .. d[i] .. ": the thin-prism and tilted"
          .. " models (s1..s4, tx, ty) are not supported")
      end
    end
    local out = {}
    for i = 1, 8 do out[i] = d[i] end
    return out
  end
  if n ~= 4 and n ~= 5 and n ~= 8 then
    fail("4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]) expected, got " .. n)
  end
  return d
end

-- the camera from a flat K, coefficients and a model name, through camera.from_matrix
local function build(k, d, model, fail)
  local ok, camera = pcall(camera_model.from_matrix, k, d, model)
  if not ok then
    local reason = tostring(camera):match("^bad argument #%d+ to 'from_matrix' %((.*)%)$")
    fail(reason or tostring(camera))
  end
  return camera
end

local function check_tag_size(v, fail_at, line_of)
  if type(v) == "number" then
    if not (is_finite(v) and v > 0) then
      fail_at(line_of(), "tag_size: positive number expected, got " .. describe(v))
    end
    return v
  end
  if type(v) ~= "table" then
    fail_at(line_of(), "tag_size: a number or a table {[id] = size, default = size} expected,"
      .. " got " .. describe(v))
  end
  local any = false
  for _, k in ipairs(sorted_keys(v)) do
    local size = v[k]
    any = true
    if k ~= "default" and not is_integer(k, 0) then
      local hint = type(k) == "string" and M.suggest(k, { "default" })
      fail_at(line_of(k), "tag_size: unknown key " .. key_name(k) .. (hint and (" (did you mean '"
        .. hint .. "'?)") or " (tag ids are whole numbers >= 0, or 'default')"))
    end
    if not (is_finite(size) and size > 0) then
      fail_at(line_of(k), "tag_size" .. (k == "default" and ".default" or "[" .. k .. "]")
        .. ": positive number expected, got " .. describe(size))
    end
  end
  if not any then fail_at(line_of(), "tag_size: the table is empty") end
  return v
end

-- ----------------------------------------------------------------------------------------------
-- Lua camera files

local LUA_KEYS = { "fx", "fy", "cx", "cy", "model", "distortion", "width", "height", "name",
  "tag_size", "block_size", "unit" }
local LUA_KNOWN = {}
for _, k in ipairs(LUA_KEYS) do LUA_KNOWN[k] = true end

local function lua_camera(text, name)
  local t, where, root_line = luadata.decode(text, name)
  if t == nil and type(where) == "string" then
    error(setmetatable({ message = "calibration: " .. where }, Failure), 0)
  end
  local function fail_at(at, reason) failure(name, at, reason) end
  if type(t) ~= "table" then
    fail_at(root_line, "a camera table expected, got " .. describe(t))
  end
  local lines = where[t]
  for _, k in ipairs(sorted_keys(t)) do
    if not LUA_KNOWN[k] then
      local hint
      if type(k) ~= "string" then
        fail_at(lines[k], "unexpected entry " .. key_name(k) .. " (a camera file has named fields"
          .. " only: " .. concat(LUA_KEYS, ", ") .. ")")
      elseif COEFFICIENTS[k:lower()] then
        hint = "distortion." .. k:lower()
      else
        hint = M.suggest(k, LUA_KEYS)
      end
      fail_at(lines[k], "unknown key " .. key_name(k) .. (hint and (" (did you mean " .. hint
        .. "?)") or (" (a camera file has " .. concat(LUA_KEYS, ", ") .. ")")))
    end
  end
  for _, k in ipairs({ "fx", "fy" }) do
    local v = t[k]
    if v == nil then fail_at(root_line, "no " .. k .. " (the focal length in pixels)") end
    if not (is_finite(v) and v > 0) then
      fail_at(lines[k], k .. ": positive number expected, got " .. describe(v))
    end
  end
  for _, k in ipairs({ "cx", "cy" }) do
    local v = t[k]
    if v == nil then fail_at(root_line, "no " .. k .. " (the principal point in pixels)") end
    if not is_finite(v) then
      fail_at(lines[k], k .. ": finite number expected, got " .. describe(v))
    end
  end
  local model = t.model
  if model ~= nil and not MODELS[model] then
    fail_at(lines.model, "model: 'pinhole' or 'fisheye' expected, got " .. describe(model))
  end
  local kind = MODELS[model or "pinhole"]
  local names = kind == "fisheye" and FISHEYE or BROWN
  local d = {}
  local dist = t.distortion
  if dist ~= nil then
    if type(dist) ~= "table" then
      fail_at(lines.distortion, "distortion: table expected, got " .. describe(dist))
    end
    local dlines = where[dist]
    local n = #dist
    for _, k in ipairs(sorted_keys(dist)) do
      local v = dist[k]
      if type(k) == "number" and n > 0 then
        if not is_integer(k, 1) or k > n then
          fail_at(dlines[k], "distortion: entry " .. key_name(k) .. " of an array of " .. n)
        end
        if not is_finite(v) then
          fail_at(dlines[k], "distortion[" .. k .. "]: finite number expected, got " .. describe(v))
        end
      elseif type(k) == "string" and n == 0 then
        local known = false
        for _, c in ipairs(names) do
          if c == k then known = true end
        end
        if not known then
          local hint = M.suggest(k, names)
          local other = kind == "fisheye" and COEFFICIENTS[k]
          local why = other and ("the fisheye model has " .. concat(FISHEYE, ", "))
            or hint and ("did you mean '" .. hint .. "'?")
            or ("the coefficients are " .. concat(names, ", "))
          fail_at(dlines[k], "distortion: unknown key " .. key_name(k) .. " (" .. why .. ")")
        end
        if not is_finite(v) then
          fail_at(dlines[k], "distortion." .. k .. ": finite number expected, got " .. describe(v))
        end
      else
        fail_at(dlines[k], "distortion: named coefficients (k1 = ...) or an array in OpenCV's"
          .. " order, not both")
      end
    end
    if n > 0 then
      for i = 1, n do d[i] = dist[i] end
      d = opencv_coefficients(d, kind, function(reason)
        fail_at(lines.distortion, "distortion: " .. reason)
      end)
    else
      local last = kind == "fisheye" and 4 or 5
      if kind ~= "fisheye" and (dist.k4 or dist.k5 or dist.k6) then last = 8 end
      for i = 1, last do d[i] = dist[names[i]] or 0 end
    end
  end
  local info = { format = "lua", path = name }
  for _, k in ipairs({ "width", "height" }) do
    local v = t[k]
    if v ~= nil and not is_integer(v, 1) then
      fail_at(lines[k], k .. ": whole number of pixels expected, got " .. describe(v))
    end
    info[k] = v
  end
  for _, k in ipairs({ "name", "unit" }) do
    local v = t[k]
    if v ~= nil and type(v) ~= "string" then
      fail_at(lines[k], k .. ": string expected, got " .. describe(v))
    end
    info[k] = v
  end
  if t.tag_size ~= nil then
    info.tag_size = check_tag_size(t.tag_size, fail_at, function(k)
      if k == nil then return lines.tag_size end
      local tl = where[t.tag_size]
      return tl and tl[k] or lines.tag_size
    end)
  end
  if t.block_size ~= nil then
    local v = t.block_size
    if not (is_finite(v) and v > 0) then
      fail_at(lines.block_size, "block_size: positive number expected, got " .. describe(v))
    end
    info.block_size = v
  end
  local k = { t.fx, 0, t.cx, 0, t.fy, t.cy, 0, 0, 1 }
  local camera = build(k, d, kind, function(reason) fail_at(root_line, reason) end)
  return camera, info
end

-- ----------------------------------------------------------------------------------------------
-- YAML

local NULL, TAG = yaml.NULL, yaml.TAG

local function is_mapping(v)
  return type(v) == "table" and v ~= NULL and v[1] == nil
end

local function is_sequence(v)
  return type(v) == "table" and v ~= NULL and (v[1] ~= nil or next(v) == nil) and v[TAG] == nil
end

local ROS_KEYS = { "image_width", "image_height", "camera_name", "camera_matrix",
  "distortion_model", "distortion_coefficients", "rectification_matrix", "projection_matrix" }
local INFO_KEYS = { "header", "height", "width", "distortion_model", "D", "K", "R", "P",
  "binning_x", "binning_y", "roi" }
local INFO_KEYS_LOWER = { "header", "height", "width", "distortion_model", "d", "k", "r", "p",
  "binning_x", "binning_y", "roi" }
local CV_MATRIX = { "camera_matrix", "cameraMatrix", "K" }
local CV_DISTORTION = { "distortion_coefficients", "distCoeffs", "dist_coeffs", "D" }
local CV_READ = { "camera_matrix", "cameraMatrix", "K", "distortion_coefficients", "distCoeffs",
  "dist_coeffs", "D", "image_width", "image_height", "fisheye_model" }

local function yaml_camera(text, name)
  local doc, where = yaml.decode(text, name)
  if doc == nil then error(setmetatable({ message = "calibration: " .. where }, Failure), 0) end
  local function fail_at(at, reason) failure(name, at, reason) end
  if not is_mapping(doc) or next(doc) == nil then
    fail_at(1, "a mapping of calibration entries expected (camera_matrix, distortion_model, ...)")
  end
  local top = where[doc]
  local function line(container, key)
    local w = where[container]
    return w and w[key]
  end

  -- which format
  local format
  for _, k in ipairs(CV_MATRIX) do
    if type(doc[k]) == "table" and doc[k][TAG] then format = "opencv" end
  end
  if not format then
    if doc.camera_matrix ~= nil then
      format = "ros"
    elseif doc.K ~= nil or doc.k ~= nil then
      format = "camera_info"
    else
      for _, k in ipairs(sorted_keys(doc)) do
        local hint = type(k) == "string" and M.suggest(k, { "camera_matrix", "K" })
        if hint then fail_at(top[k], "unknown key " .. key_name(k) .. " (did you mean " .. hint
          .. "?)") end
      end
      fail_at(1, "no camera matrix: not a ROS camera_calibration file (camera_matrix), a"
        .. " CameraInfo message (K) or an OpenCV FileStorage file (camera_matrix: !!opencv-matrix)")
    end
  end

  local function refuse_unknown(known)
    local set = {}
    for _, k in ipairs(known) do set[k] = true end
    for _, k in ipairs(sorted_keys(doc)) do
      if not set[k] then
        local hint = type(k) == "string" and M.suggest(k, known)
        fail_at(top[k], "unknown key " .. key_name(k) .. (hint and (" (did you mean " .. hint
          .. "?)") or (" (a " .. (format == "ros" and "ROS camera_calibration file" or
          "CameraInfo message") .. " has " .. concat(known, ", ") .. ")")))
      end
    end
  end

  local function numbers(seq, at, what, count)
    if not is_sequence(seq) then
      fail_at(at, what .. ": a sequence of numbers expected, got " .. describe(seq))
    end
    for i = 1, #seq do
      if not is_finite(seq[i]) then
        fail_at(line(seq, i) or at, what .. "[" .. i .. "]: number expected, got "
          .. describe(seq[i]))
      end
    end
    if count and #seq ~= count then
      fail_at(at, what .. ": " .. count .. " numbers expected, got " .. #seq)
    end
    return seq
  end

  -- a {rows, cols, data} matrix (dt too when tagged); returns data, rows, cols
  local function matrix(parent, key, tagged)
    local m = parent[key]
    local at = line(parent, key)
    if tagged then
      if type(m) ~= "table" or m[TAG] ~= "opencv-matrix" then
        fail_at(at, key .. ": an !!opencv-matrix expected, got " .. describe(m))
      end
    elseif not is_mapping(m) then
      fail_at(at, key .. ": a mapping {rows, cols, data} expected, got " .. describe(m))
    end
    local fields = tagged and { "rows", "cols", "dt", "data" } or { "rows", "cols", "data" }
    local set = {}
    for _, f in ipairs(fields) do
      set[f] = true
      if m[f] == nil then fail_at(at, key .. ": no " .. f) end
    end
    for _, f in ipairs(sorted_keys(m)) do
      if not set[f] then
        local hint = type(f) == "string" and M.suggest(f, fields)
        fail_at(line(m, f) or at, key .. ": unknown key " .. key_name(f) .. " (" .. (hint
          and ("did you mean " .. hint .. "?") or ("a matrix has " .. concat(fields, ", "))) .. ")")
      end
    end
    local rows, cols = m.rows, m.cols
    if not is_integer(rows, 0) then
      fail_at(line(m, "rows"), key .. ".rows: whole number expected, got " .. describe(rows))
    end
    if not is_integer(cols, 0) then
      fail_at(line(m, "cols"), key .. ".cols: whole number expected, got " .. describe(cols))
    end
    if tagged and m.dt ~= "d" and m.dt ~= "f" then
      fail_at(line(m, "dt"), key .. ".dt: 'd' or 'f' (one channel of doubles or floats)"
        .. " expected, got " .. describe(m.dt))
    end
    local data = numbers(m.data, line(m, "data"), key .. ".data")
    if #data ~= rows * cols then
      fail_at(line(m, "data"), key .. ": " .. rows .. "x" .. cols .. " = " .. rows * cols
        .. " numbers expected, got " .. #data)
    end
    return data, rows, cols
  end

  local function shape(data, rows, cols, r, c, key)
    if rows ~= r or cols ~= c then
      fail_at(line(doc, key), key .. ": a " .. r .. "x" .. c .. " matrix expected, got " .. rows
        .. "x" .. cols)
    end
    return data
  end

  local function vector(data, rows, cols, key)
    if rows ~= 1 and cols ~= 1 and #data > 0 then
      fail_at(line(doc, key), key .. ": one row or one column expected, got " .. rows .. "x"
        .. cols)
    end
    return data
  end

  local function size(key)
    local v = doc[key]
    if v == nil or v == NULL then return nil end
    if not is_integer(v, 0) then
      fail_at(top[key], key .. ": whole number of pixels expected, got " .. describe(v))
    end
    if v == 0 then return nil end -- CameraInfo's "not set"
    return v
  end

  local function model_of(key)
    local v = doc[key]
    if v == nil or v == NULL then return nil end
    if not MODELS[v] then
      fail_at(top[key], key .. ": 'plumb_bob', 'rational_polynomial' or 'equidistant' expected,"
        .. " got " .. describe(v))
    end
    return v
  end

  local function check_count(model, n, at)
    if n == 0 then return end
    local want = ({ plumb_bob = { 5, 4 }, rational_polynomial = { 8 }, equidistant = { 4 },
      fisheye = { 4 }, pinhole = { 4, 5, 8 } })[model]
    for _, w in ipairs(want) do
      if n == w then return end
    end
    fail_at(at, "distortion_model " .. model .. " has " .. concat(want, " or ")
      .. " coefficients, the file gives " .. n)
  end

  local info = { format = format, path = name }
  local k, d, model
  if format == "ros" then
    refuse_unknown(ROS_KEYS)
    local data, rows, cols = matrix(doc, "camera_matrix")
    k = shape(data, rows, cols, 3, 3, "camera_matrix")
    if doc.distortion_coefficients == nil then
      fail_at(1, "no distortion_coefficients (rows: 1, cols: 0, data: [] for none)")
    end
    data, rows, cols = matrix(doc, "distortion_coefficients")
    d = vector(data, rows, cols, "distortion_coefficients")
    model = model_of("distortion_model")
    if model == nil then
      if #d > 0 then
        fail_at(1, "no distortion_model (plumb_bob, rational_polynomial or equidistant) for the "
          .. #d .. " coefficients")
      end
      model = "plumb_bob"
    end
    check_count(model, #d, line(doc, "distortion_coefficients"))
    info.width, info.height = size("image_width"), size("image_height")
    local cn = doc.camera_name
    if cn ~= nil and cn ~= NULL then
      if type(cn) ~= "string" and type(cn) ~= "number" then
        fail_at(top.camera_name, "camera_name: string expected, got " .. describe(cn))
      end
      info.name = tostring(cn)
    end
    if doc.rectification_matrix ~= nil then
      local r, rr, rc = matrix(doc, "rectification_matrix")
      info.rectification = shape(r, rr, rc, 3, 3, "rectification_matrix")
    end
    if doc.projection_matrix ~= nil then
      local p, pr, pc = matrix(doc, "projection_matrix")
      info.projection = shape(p, pr, pc, 3, 4, "projection_matrix")
    end
  elseif format == "camera_info" then
    local upper = doc.K ~= nil
    local keys = upper and INFO_KEYS or INFO_KEYS_LOWER
    refuse_unknown(keys)
    local K, D, R, P = keys[6], keys[5], keys[7], keys[8]
    k = numbers(doc[K], top[K], K, 9)
    if doc[D] == nil then
      fail_at(1, "no " .. D .. " (the distortion coefficients; [] for none)")
    end
    d = numbers(doc[D], top[D], D)
    model = model_of("distortion_model")
    if model == nil then
      if #d > 0 then fail_at(1, "no distortion_model for the " .. #d .. " coefficients") end
      model = "plumb_bob"
    end
    check_count(model, #d, top[D])
    info.width, info.height = size("width"), size("height")
    for _, b in ipairs({ "binning_x", "binning_y" }) do
      local v = doc[b]
      if v ~= nil and v ~= NULL and v ~= 0 and v ~= 1 then
        fail_at(top[b], b .. " " .. describe(v) .. ": binned images are not supported (the"
          .. " camera matrix is that of the full image)")
      end
    end
    local roi = doc.roi
    if roi ~= nil and roi ~= NULL then
      if not is_mapping(roi) then
        fail_at(top.roi, "roi: mapping expected, got " .. describe(roi))
      end
      for _, o in ipairs({ "x_offset", "y_offset" }) do
        local v = roi[o]
        if v ~= nil and v ~= NULL and v ~= 0 then
          fail_at(line(roi, o), "roi." .. o .. " " .. describe(v) .. ": a region of interest is"
            .. " not supported (the corners would need its offset)")
        end
      end
    end
    if is_mapping(doc.header) and type(doc.header.frame_id) == "string" then
      info.name = doc.header.frame_id
    end
    if doc[R] ~= nil then info.rectification = numbers(doc[R], top[R], R, 9) end
    if doc[P] ~= nil then info.projection = numbers(doc[P], top[P], P, 12) end
  else
    -- OpenCV: which names, then the rest ignored unless it looks like a misspelling
    local function one_of(names, what)
      local found = {}
      for _, n in ipairs(names) do
        if doc[n] ~= nil then found[#found + 1] = n end
      end
      table.sort(found, function(a, b) return top[a] < top[b] end)
      if found[2] then
        fail_at(top[found[2]], "two " .. what .. ": " .. found[1] .. " (line " .. top[found[1]]
          .. ") and " .. found[2])
      end
      return found[1]
    end
    local mk = one_of(CV_MATRIX, "camera matrices")
    local dk = one_of(CV_DISTORTION, "sets of distortion coefficients")
    local read = {}
    for _, n in ipairs(CV_READ) do read[n] = true end
    info.ignored = {}
    for _, key in ipairs(sorted_keys(doc)) do
      if not read[key] then
        local hint = type(key) == "string" and M.suggest(key, CV_READ)
        if hint and #key > 2 then
          fail_at(top[key], "unknown key " .. key_name(key) .. " (did you mean " .. hint .. "?)")
        end
        info.ignored[#info.ignored + 1] = tostring(key)
      end
    end
    local data, rows, cols = matrix(doc, mk, true)
    k = shape(data, rows, cols, 3, 3, mk)
    if not dk then
      fail_at(1, "no distortion_coefficients (or D): write a 5x1 matrix of zeros for none")
    end
    data, rows, cols = matrix(doc, dk, true)
    d = vector(data, rows, cols, dk)
    local fisheye = doc.fisheye_model
    if fisheye ~= nil and fisheye ~= 0 and fisheye ~= 1 and fisheye ~= true
      and fisheye ~= false then
      fail_at(top.fisheye_model, "fisheye_model: 0 or 1 expected, got " .. describe(fisheye))
    end
    model = (fisheye == 1 or fisheye == true) and "equidistant" or "pinhole"
    info.width, info.height = size("image_width"), size("image_height")
    local at = top[dk]
    d = opencv_coefficients(d, MODELS[model], function(reason)
      fail_at(at, dk .. ": " .. reason)
    end)
    if model == "pinhole" then model = #d == 8 and "rational_polynomial" or "plumb_bob" end
  end
  info.distortion_model = model
  local at = top.camera_matrix or top.K or top.k or top.cameraMatrix
  local camera = build(k, d, model, function(reason) fail_at(at, reason) end)
  return camera, info
end

local function is_lua(text, name)
  if name:match("%.[lL][uU][aA]$") then return true end
  if name:match("%.[yY][aA]?[mM][lL]$") then return false end
  local first = text:match("^%s*(%S%S?)") -- "re"turn or "--"
  return first == "--" or (first == "re" and text:match("^%s*return[%s{]") ~= nil)
end

--- Read a calibration from its text.
-- @tparam string text the file's text
-- @tparam string name the file's name: its ending (`.lua`, `.yaml`, `.yml`) tells the format,
--   and it names the file in messages
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info: `format` (`"lua"`, `"ros"`, `"camera_info"` or `"opencv"`), `path`,
--   and what the file gives of `width`, `height` (pixels), `name`, `distortion_model`,
--   `rectification` (flat 3x3), `projection` (flat 3x4), `ignored` (OpenCV keys not read) and,
--   from a Lua file, `tag_size` (a number or `{[id] = size, default = size}`), `block_size`,
--   `unit` (the name of the unit of `tag_size`)
-- @return nil, string `"calibration: NAME:LINE: reason"`
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
function M.decode(text, name)
  if type(text) ~= "string" then
    error("bad argument #1 to 'decode' (string expected, got " .. type(text) .. ")", 2)
  end
  if type(name) ~= "string" then
    error("bad argument #2 to 'decode' (string expected, got " .. type(name) .. ")", 2)
  end
  local ok, camera, info = pcall(is_lua(text, name) and lua_camera or yaml_camera, text, name)
  if ok then return camera, info end
  if getmetatable(camera) == Failure then return nil, camera.message end
  error(camera, 0)
end

--- Read a calibration file (Lua camera file, ROS or OpenCV YAML; see the module's header).
-- @tparam string path
-- @treturn table camera `{fx =, fy =, cx =, cy =, model =, distortion =}`
-- @treturn table info (see `decode`)
-- @return nil, string `"calibration: PATH:LINE: reason"` (or `"calibration: PATH: reason"`
--   when the file cannot be read)
-- @raise `bad argument #1 to 'read' (...)` when `path` is not a string
-- @usage
-- local camera, info = assert(tagpose.calibration.read("ost.yaml"))
-- local pose = tagpose.solve(corners, camera, 0.024)
function M.read(path)
  if type(path) ~= "string" then
    error("bad argument #1 to 'read' (string expected, got " .. type(path) .. ")", 2)
  end
  local f, err = io.open(path, "rb")
  if not f then return nil, "calibration: " .. tostring(err) end
  local text = f:read(M.MAX_BYTES + 1)
  f:close()
  if text == nil then text = "" end
  if #text > M.MAX_BYTES then
    return nil, "calibration: " .. path .. ": larger than " .. M.MAX_BYTES .. " bytes (a"
      .. " calibration is a few lines)"
  end
  return M.decode(text, path)
end

return M
