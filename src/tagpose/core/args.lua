--- Argument checks shared by the public entry points.
--
-- Misuse of a public function raises with Lua's own wording, at the caller's level:
-- `bad argument #3 to 'solve' (positive number expected for tag_size, got number -1)`.
-- The helpers here build the pieces of such messages; the entry points raise them.
-- @module tagpose.core.args

local compat = require("tagpose.core.compat")

local is_finite = compat.is_finite

local M = {}

-- a key that is not a string, for a message
local function describe_key(k)
  if type(k) == "number" then return "[" .. tostring(k) .. "]" end
  return "(" .. type(k) .. ")"
end

--- A short description of a value for an error message: `number -2`, `string abc`, `nil`.
-- @tparam any v
-- @treturn string
function M.describe(v)
  local t = type(v)
  if t == "number" or t == "string" then return t .. " " .. tostring(v) end
  return t
end

--- True for a finite number greater than zero.
-- @tparam any v
-- @treturn boolean
function M.is_positive(v)
  return is_finite(v) and v > 0
end

--- True for a whole number of at least 1 (a count, such as an iteration bound).
-- @tparam any v
-- @treturn boolean
function M.is_count(v)
  return is_finite(v) and v >= 1 and v == math.floor(v)
end

--- Sizes (tag sides, block sides) below this are not a length in any unit...
M.MIN_SIZE = 1e-12
--- ... nor above this.
M.MAX_SIZE = 1e12

--- Check a size argument (`tag_size`, `block_size`): a positive number within
-- `MIN_SIZE..MAX_SIZE`.
-- @tparam any v
-- @tparam string name the argument's name for the message
-- @treturn string|nil what is wrong, or nil
function M.check_size(v, name)
  if not M.is_positive(v) then
    return "positive number expected for " .. name .. ", got " .. M.describe(v)
  end
  if not (v >= M.MIN_SIZE and v <= M.MAX_SIZE) then
    return ("%s between %g and %g expected (in the unit the poses come out in), got %s")
      :format(name, M.MIN_SIZE, M.MAX_SIZE, M.describe(v))
  end
end

--- Check a size argument that may also be a table of sizes by tag id, `{[id] = size, default =
-- size}`: every value a size (`check_size`).
-- @tparam any v
-- @tparam string name the argument's name for the message
-- @treturn string|nil what is wrong, or nil
function M.check_sizes(v, name)
  if type(v) ~= "table" then return M.check_size(v, name) end
  local any = false
  for key, size in pairs(v) do
    any = true
    local problem = M.check_size(size, name .. "[" .. (type(key) == "string"
      and ("%q"):format(key) or tostring(key)) .. "]")
    if problem then return problem end
  end
  if not any then return name .. ": a size or a table of sizes by tag id expected, got {}" end
end

--- The size of tag `id` in a size argument (`check_sizes`: a size, or sizes by tag id with an
-- optional `default`).
-- @tparam number|table sizes
-- @tparam any id
-- @treturn number|nil its size, or nil when the table has none for it and no default
function M.size_of(sizes, id)
  if type(sizes) ~= "table" then return sizes end
  local size = sizes[id]
  if size == nil then size = sizes.default end
  return size
end

--- Read four corners (`{u, v}` or `{x = u, y = v}` each) into the flat array `out`
-- (`{u1, v1, ..., u4, v4}`, in the detection order c1..c4).
-- @tparam any corners
-- @tparam {number,...} out array to fill
-- @tparam[opt] boolean opencv the corners are in OpenCV's and ArUco's order (top-left, top-right,
--   bottom-right, bottom-left of the printed tag: c4, c3, c2, c1)
-- @treturn true|int `true`, or the index of the first corner that is not finite (in the order
--   given)
-- @return false, string when `corners` is not four corners (the misuse, for an error message)
function M.read_corners(corners, out, opencv)
  if type(corners) ~= "table" then
    return false, "table of four corners expected, got " .. type(corners)
  end
  -- counted by indexing, not `#`: a table's own `__len` may say anything (and no loop on the
  -- way of four corners: LuaJIT cannot compile an inner loop into its caller's trace)
  if corners[4] == nil or corners[5] ~= nil or corners[3] == nil or corners[2] == nil
    or corners[1] == nil then
    local n = 0
    while n < 1000 and corners[n + 1] ~= nil do n = n + 1 end
    return false, "four corners expected, got " .. (n == 1000 and "1000 or more" or tostring(n))
  end
  local first_nonfinite
  for i = 1, 4 do
    local c = corners[i]
    if type(c) ~= "table" then
      return false, "corner " .. i .. ": table expected, got " .. type(c)
    end
    local u, v = c[1], c[2]
    if u == nil then u = c.x end
    if v == nil then v = c.y end
    if type(u) ~= "number" or type(v) ~= "number" then
      return false, "corner " .. i .. ": numbers {u, v} or {x =, y =} expected, got "
        .. M.describe(u) .. " and " .. M.describe(v)
    end
    -- finite exactly when u - u is 0 (NaN and ±inf give NaN)
    if not first_nonfinite and not (u - u == 0 and v - v == 0) then first_nonfinite = i end
    -- as floats: integer pixels near math.mininteger would wrap around in u - cx (Lua 5.3+)
    local k = opencv and 5 - i or i
    out[2 * k - 1], out[2 * k] = u + 0.0, v + 0.0
  end
  return first_nonfinite or true
end

--- The corner orders an `options.order` takes: the detection order c1..c4 (the default) and
-- OpenCV's and ArUco's (`read_corners`).
M.ORDERS = { "apriltag", "opencv" }

--- Read an `options.order`: true for OpenCV's order, false for the detection order (the
-- default, `nil`).
-- @tparam any order
-- @treturn boolean|nil whether the corners are in OpenCV's order, or nil
-- @treturn string what is wrong, when nil (for `bad argument`)
function M.read_order(order)
  if order == nil or order == "apriltag" then return false end
  if order == "opencv" then return true end
  return nil, "options.order: 'apriltag' or 'opencv' expected, got " .. M.describe(order)
end

--- The words of the corner-order hint in a failure message ("the corners wind the wrong way
-- round"): what `tagpose.solve` takes.
M.ORDER_HINT = "options.order = 'opencv'"

--- A failure message with its corner-order hint naming the option of another call than
-- `tagpose.solve`: `options.order = 'opencv'` becomes `{order = 'opencv'} in call` (or
-- `option` itself, such as a command's `--order opencv`, when `call` is nil).
-- @tparam ?string message a failure message (nil passes through)
-- @tparam ?string call the call the user made, `tagpose.layout.solve(..., options)`
-- @tparam[opt] string option the whole replacement instead
-- @treturn ?string
function M.name_order(message, call, option)
  if type(message) ~= "string" then return message end
  local i, j = message:find(M.ORDER_HINT, 1, true)
  if not i then return message end
  local text = option or ("{order = 'opencv'} in " .. call)
  return message:sub(1, i - 1) .. text .. message:sub(j + 1)
end

--- The misuse of passing one detection where an array of them belongs: the message, in the
-- words of every entry point.
M.ONE_DETECTION = "array of detections expected, got one detection {id =, corners =} "
  .. "(pass {detection})"

--- Is `t` one detection `{id =, corners =}` rather than an array of them?
-- @tparam table t
-- @treturn boolean
function M.is_detection(t)
  return t[1] == nil and (t.corners ~= nil or t.id ~= nil)
end

-- Levenshtein distance of two short strings, with an early exit above `cap`.
local function distance(a, b, cap)
  local la, lb = #a, #b
  if math.abs(la - lb) > cap then return cap + 1 end
  local prev, cur = {}, {}
  for j = 0, lb do prev[j] = j end
  for i = 1, la do
    cur[0] = i
    local ca = a:byte(i)
    for j = 1, lb do
      local cost = ca == b:byte(j) and 0 or 1
      local v = prev[j - 1] + cost
      if prev[j] + 1 < v then v = prev[j] + 1 end
      if cur[j - 1] + 1 < v then v = cur[j - 1] + 1 end
      cur[j] = v
    end
    prev, cur = cur, prev
  end
  return prev[lb]
end

--- The name among `names` that `name` most likely means: the same in another case, one at most
-- two edits away, or one with something added or cut off (`prior_pose`, `max_iter`; three
-- characters or more each). What every "did you mean" of tagpose's says.
-- @tparam string name
-- @tparam {string,...} names
-- @treturn string|nil the nearest, nil when none is that near
function M.nearest(name, names)
  local best, best_d = nil, 3
  for _, a in ipairs(names) do
    local d = a:lower() == name:lower() and 0 or distance(a, name, 2)
    if d > 2 and #name >= 3 and #a >= 3 and (name:sub(1, #a) == a or a:sub(1, #name) == name)
    then
      d = 2
    end
    if d < best_d then best, best_d = a, d end
  end
  return best
end

--- The message for a key that a table does not take, with the likely intended key: the same
-- key in another case, or one at most two edits away.
-- @tparam any key the unknown key
-- @tparam {string,...} allowed the keys the table takes
-- @tparam string where the table's name in messages (`options`, `camera.distortion`)
-- @tparam[opt] table misplaced key -> where such a key belongs
-- @treturn string
function M.unknown_key_message(key, allowed, where, misplaced)
  local name = type(key) == "string" and key or describe_key(key)
  local head = where .. "." .. name .. ": unknown key"
  if type(key) ~= "string" then
    return where .. ": unknown key " .. name .. " (keys are " .. table.concat(allowed, ", ") .. ")"
  end
  if misplaced and misplaced[key] then
    return head .. " (did you mean " .. misplaced[key] .. "?)"
  end
  local best = M.nearest(key, allowed)
  if best then return head .. " (did you mean '" .. best .. "'?)" end
  return head .. " (known keys: " .. table.concat(allowed, ", ") .. ")"
end

--- The first key of a table that is not among the allowed ones, as a message; nil when every
-- key is allowed.
-- @tparam table t
-- @tparam {string,...} allowed
-- @tparam string where the table's name in messages
-- @tparam[opt] table misplaced key -> where such a key belongs
-- @treturn string|nil
function M.unknown_keys(t, allowed, where, misplaced)
  for k in pairs(t) do
    local known = false
    for i = 1, #allowed do
      if k == allowed[i] then known = true end
    end
    if not known then return M.unknown_key_message(k, allowed, where, misplaced) end
  end
  return nil
end

--- Raise `bad argument #n to 'fname' (message)`.
-- @tparam int n argument position
-- @tparam string fname the public function's name
-- @tparam string message what was expected and what came
-- @tparam int level the stack level to blame, as for `error` (counted from the caller of this
--   function)
function M.raise(n, fname, message, level)
  error("bad argument #" .. n .. " to '" .. fname .. "' (" .. message .. ")", level + 1)
end

return M
