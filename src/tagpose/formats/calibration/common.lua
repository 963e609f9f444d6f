--- What every calibration format reads with: refusals with the file's line, the likely
-- intended key of a mistyped one, descriptions of values for messages, the distortion models
-- and the camera built from a matrix and coefficients.
--
-- A refusal is raised as a `Failure` table `{message = "calibration: NAME:LINE: reason"}` and
-- caught by `tagpose.calibration.decode`.
-- @module tagpose.formats.calibration.common

local compat = require("tagpose.core.compat")
local camera_model = require("tagpose.core.camera")
local yaml = require("tagpose.formats.yaml")
local failure = require("tagpose.formats.failure")

local is_finite = compat.is_finite
local floor = math.floor

local M = {}

--- The metatable of the refusals raised while reading (`tagpose.formats.failure.Failure`).
M.Failure = failure.Failure

--- Refuse the file with a message as it is (`"calibration: ..."`).
-- @function refuse
-- @tparam string message
M.refuse = failure.raise

--- Refuse the file: `"calibration: NAME:LINE: reason"` (`"calibration: NAME: reason"`
-- without a line).
-- @tparam string name the file's name
-- @tparam[opt] int at the line
-- @tparam string reason
function M.fail(name, at, reason)
  M.refuse("calibration: " .. name .. (at and (":" .. at) or "") .. ": " .. reason)
end

-- The optimal string alignment distance of two lowercased strings given as byte arrays, when it
-- is at most `limit`; `limit + 1` otherwise. Only the band |i - j| <= limit of the table is
-- filled, and the scan stops at the first row whose every entry exceeds the limit, so a key far
-- from the candidate costs a few rows of 2·limit + 1 entries. `rows` holds three scratch rows.
local function bounded_distance(a, la, b, lb, limit, rows)
  local over = limit + 1
  if la - lb > limit or lb - la > limit then return over end
  local prev2, prev, cur = rows[1], rows[2], rows[3]
  for j = 0, lb do prev[j] = j <= limit and j or over end
  for i = 1, la do
    local lo, hi = i - limit, i + limit
    if lo < 1 then lo = 1 end
    if hi > lb then hi = lb end
    cur[lo - 1] = (lo == 1 and i <= limit) and i or over
    local row_min = cur[lo - 1]
    local ai, ai1 = a[i], a[i - 1]
    for j = lo, hi do
      local bj = b[j]
      local d = prev[j] + 1
      local ins = cur[j - 1] + 1
      if ins < d then d = ins end
      local sub = prev[j - 1] + (ai == bj and 0 or 1)
      if sub < d then d = sub end
      if i > 1 and j > 1 and ai == b[j - 1] and ai1 == bj then
        local swap = prev2[j - 2] + 1
        if swap < d then d = swap end
      end
      if d > over then d = over end
      cur[j] = d
      if d < row_min then row_min = d end
    end
    if hi < lb then cur[hi + 1] = over end
    if row_min > limit then return over end
    prev2, prev, cur = prev, cur, prev2
  end
  return prev[lb] <= limit and prev[lb] or over
end

local function lower_bytes(s, out)
  s = s:lower()
  for i = 1, #s do out[i] = s:byte(i) end
  return out, #s
end

--- A suggester for one set of candidates, made once (per file) and asked for each key: the
-- candidate a mistyped key most likely meant (differing in case only, or by one edit for a key
-- of up to 4 characters, two for a longer one; an edit is an insertion, a deletion, a
-- substitution or a swap of neighbours), or nil. Each question costs time linear in the key's
-- length per candidate of a near length, so a file of many unknown keys is read in time linear
-- in its size.
-- @tparam {string,...} candidates
-- @treturn function `suggest(key)` → the candidate or nil
function M.suggester(candidates)
  local bytes, lengths = {}, {}
  for i, c in ipairs(candidates) do
    bytes[i], lengths[i] = lower_bytes(c, {})
  end
  local rows = { {}, {}, {} }
  local key_bytes = {}
  return function(key)
    if type(key) ~= "string" or #key > 64 then return nil end
    local k, lk = lower_bytes(key, key_bytes)
    local limit = #key <= 4 and 1 or 2
    local best, best_d = nil, limit + 1
    for i = 1, #candidates do
      local d = bounded_distance(k, lk, bytes[i], lengths[i], limit, rows)
      if d < best_d then best, best_d = candidates[i], d end
    end
    return best
  end
end

--- The candidate a mistyped key most likely meant (see `suggester`), or nil.
-- @tparam string key
-- @tparam {string,...} candidates
-- @treturn string|nil
function M.suggest(key, candidates)
  return M.suggester(candidates)(key)
end

--- A value as a message names it: `null`, `number 3`, `string abc`, `table`.
-- @param v
-- @treturn string
function M.describe(v)
  if v == yaml.NULL then return "null" end
  local t = type(v)
  if t == "number" or t == "string" then return t .. " " .. tostring(v) end
  return t
end

--- A key as a message names it: `'name'` or `[3]`.
-- @param k
-- @treturn string
function M.key_name(k)
  if type(k) == "string" then return "'" .. k .. "'" end
  return "[" .. tostring(k) .. "]"
end

--- The keys of a table (but `yaml.TAG`) in a fixed order: numbers, then strings, each sorted.
-- @tparam table t
-- @treturn table
function M.sorted_keys(t)
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

--- True for a finite whole number of at least `lo`.
-- @param v
-- @tparam number lo
-- @treturn boolean
function M.is_integer(v, lo)
  return is_finite(v) and v == floor(v) and v >= lo
end

--- The names of the coefficients, in OpenCV's `distCoeffs` order, of the Brown-Conrady model.
M.BROWN = { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
--- ... and of the fisheye (equidistant) model.
M.FISHEYE = { "k1", "k2", "k3", "k4" }
--- Every coefficient name (a set).
M.COEFFICIENTS = { k1 = true, k2 = true, k3 = true, k4 = true, k5 = true, k6 = true,
  p1 = true, p2 = true }
--- The model names of the files, and the kind of lens each is (`"pinhole"` or `"fisheye"`).
M.MODELS = { pinhole = "pinhole", plumb_bob = "pinhole", rational_polynomial = "pinhole",
  fisheye = "fisheye", equidistant = "fisheye" }

--- The coefficient array D (OpenCV order) for a kind of lens, from n numbers; 12 and 14
-- coefficients (thin prism, tilt) only when those extra terms are 0.
-- @tparam {number,...} d
-- @tparam string kind `"pinhole"` or `"fisheye"`
-- @tparam function fail called with the reason when the count does not fit
-- @treturn {number,...}
function M.opencv_coefficients(d, kind, fail)
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

--- The camera from a flat K, coefficients and a model name, through `camera.from_matrix`,
-- checked as `tagpose.solve` checks it.
-- @tparam {number,...} k flat 3x3, row-major
-- @tparam {number,...} d the coefficients, OpenCV order
-- @tparam string model
-- @tparam function fail called with the reason `from_matrix` gives
-- @treturn table the camera
function M.build(k, d, model, fail)
  local ok, camera = pcall(camera_model.from_matrix, k, d, model)
  if not ok then
    local reason = tostring(camera):match("^bad argument #%d+ to 'from_matrix' %((.*)%)$")
    fail(reason or tostring(camera))
  end
  -- what every later call would refuse is refused now, while the file's line is known
  local problem = camera_model.check(camera)
  if problem then fail(problem) end
  return camera
end

return M
