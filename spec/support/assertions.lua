-- Domain assertions for the specs: nearness of vectors, rotations, quaternions and poses.
-- Each failure prints both values and the measured distance.

local assert = require("luassert")
local say = require("say")

local sqrt, asin, deg = math.sqrt, math.asin, math.deg

local function vec(v)
  if v.x ~= nil then return v.x, v.y, v.z end
  return v[1], v[2], v[3]
end

local function flat(r)
  if type(r[1]) == "table" then
    return { r[1][1], r[1][2], r[1][3], r[2][1], r[2][2], r[2][3], r[3][1], r[3][2], r[3][3] }
  end
  return r
end

local function fmt_vec(v)
  local x, y, z = vec(v)
  return ("(%.17g, %.17g, %.17g)"):format(x, y, z)
end

-- geodesic angle between two rotation matrices, in degrees (chord formula: exact near 0)
local function rotation_angle(a, b)
  a, b = flat(a), flat(b)
  local s = 0
  for i = 1, 9 do
    s = s + (a[i] - b[i]) ^ 2
  end
  local h = sqrt(s / 8)
  if h > 1 then h = 1 end
  return deg(2 * asin(h))
end

-- The result `ok`, with the failure message (callers make it only when the assertion fails:
-- `state.mod` is false for a negated one; formatting the values costs more than the check).
local function set(state, arguments, ok, message, ...)
  local text = message:format(...)
  if arguments[4] then text = arguments[4] .. ": " .. text end
  state.failure_message = text
  return ok
end

-- assert.vector_near(expected, actual, tolerance [, message]): Euclidean distance
local function vector_near(state, arguments)
  local e, a, tol = arguments[1], arguments[2], arguments[3]
  local ex, ey, ez = vec(e)
  local ax, ay, az = vec(a)
  local d = sqrt((ex - ax) ^ 2 + (ey - ay) ^ 2 + (ez - az) ^ 2)
  if (d <= tol) ~= state.mod then
    return set(state, arguments, d <= tol, "expected %s, got %s: distance %.3g > %.3g",
      fmt_vec(e), fmt_vec(a), d, tol)
  end
  return d <= tol
end

-- assert.rotation_near(expected, actual, tolerance_degrees [, message])
local function rotation_near(state, arguments)
  local e, a, tol = arguments[1], arguments[2], arguments[3]
  local d = rotation_angle(e, a)
  if (d <= tol) ~= state.mod then
    return set(state, arguments, d <= tol,
      "rotations differ by %.3g deg > %.3g deg\nexpected {%s}\n     got {%s}", d, tol,
      table.concat(flat(e), ", "), table.concat(flat(a), ", "))
  end
  return d <= tol
end

-- assert.quaternion_near(expected, actual, tolerance [, message]): q and -q are the same
local function quaternion_near(state, arguments)
  local e, a, tol = arguments[1], arguments[2], arguments[3]
  local dp = sqrt((e.w - a.w) ^ 2 + (e.x - a.x) ^ 2 + (e.y - a.y) ^ 2 + (e.z - a.z) ^ 2)
  local dm = sqrt((e.w + a.w) ^ 2 + (e.x + a.x) ^ 2 + (e.y + a.y) ^ 2 + (e.z + a.z) ^ 2)
  local d = dp < dm and dp or dm
  if (d <= tol) ~= state.mod then
    return set(state, arguments, d <= tol, "expected (%.17g, %.17g, %.17g, %.17g), got (%.17g, "
      .. "%.17g, %.17g, %.17g): distance %.3g > %.3g", e.w, e.x, e.y, e.z, a.w, a.x, a.y, a.z,
      d, tol)
  end
  return d <= tol
end

for name, fn in pairs({ vector_near = vector_near, rotation_near = rotation_near,
  quaternion_near = quaternion_near }) do
  say:set("assertion." .. name .. ".positive", name .. " failed")
  say:set("assertion." .. name .. ".negative", "not " .. name .. " failed")
  assert:register("assertion", name, fn, "assertion." .. name .. ".positive",
    "assertion." .. name .. ".negative")
end

-- The message of the error f raises, which must point at the spec file `name` (the caller's
-- line, as misuse errors do).
local function raised(f, name)
  local ok, err = pcall(f)
  assert.is_false(ok)
  local where, message = tostring(err):match("^(.-" .. name:gsub("%p", "%%%0") .. ":%d+): (.*)$")
  assert.is_string(where, "error does not point at the caller: " .. tostring(err))
  return message
end

return { rotation_angle = rotation_angle, flat = flat, raised = raised }
