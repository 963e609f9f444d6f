--- tagpose: the 3D pose of an AprilTag from its four image corners, in pure Lua.
--
-- Frames and units (those of AprilTag 3's `estimate_tag_pose` and OpenCV's
-- `SOLVEPNP_IPPE_SQUARE`): camera x right, y down, z forward; tag origin at its centre, x right,
-- y down, z into the tag; corners in detection order `c1 = (-s/2, +s/2, 0)`,
-- `c2 = (+s/2, +s/2, 0)`, `c3 = (+s/2, -s/2, 0)`, `c4 = (-s/2, -s/2, 0)`; the pose maps tag to
-- camera, `X_cam = R X_tag + t`; lengths in the unit of the tag size, angles in radians,
-- image coordinates in pixels.
-- @module tagpose

local compat = require("tagpose.compat")
local args = require("tagpose.args")
local camera_model = require("tagpose.camera")
local square = require("tagpose.square")
local solvequad = require("tagpose.solvequad")
local pose = require("tagpose.pose")
local refine = require("tagpose.refine")
local rotation = require("tagpose.rotation")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local floor = math.floor

local M = {
  _VERSION = "tagpose 0.1.0",
}

-- scratch, written in place on every solve and never handed out
local m = {} -- normalised corners, flat
local px = {} -- pixel corners, flat
local q = {} -- the two quadratics' coefficients
local r = {} -- rotation, flat
local r2 = {} -- the other pose's rotation

-- Read the corners into px. Returns true (or the index of the first non-finite corner), or
-- false and a description of the misuse.
local function read_corners(corners)
  if type(corners) ~= "table" then
    return false, "table of four corners expected, got " .. type(corners)
  end
  if #corners ~= 4 then return false, "four corners expected, got " .. #corners end
  local bad = true
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
        .. describe(u) .. " and " .. describe(v)
    end
    if bad == true and not (is_finite(u) and is_finite(v)) then bad = i end
    px[2 * i - 1], px[2 * i] = u, v
  end
  return bad
end

-- Read the options: method, tolerance, max_iterations; or nil and a description of the misuse.
local function read_options(options)
  if options == nil then return "refined", solvequad.TOLERANCE, solvequad.MAX_ITERATIONS end
  if type(options) ~= "table" then return nil, "options table expected, got " .. type(options) end
  local method = options.method
  if method == nil then
    method = "refined"
  elseif method ~= "refined" and method ~= "seed" then
    return nil, "options.method: 'refined' or 'seed' expected, got " .. describe(method)
  end
  local tol = options.tolerance
  if tol == nil then
    tol = solvequad.TOLERANCE
  elseif not is_positive(tol) then
    return nil, "options.tolerance: positive number expected, got " .. describe(tol)
  end
  local max_it = options.max_iterations
  if max_it == nil then
    max_it = solvequad.MAX_ITERATIONS
  elseif not (is_finite(max_it) and max_it >= 1 and floor(max_it) == max_it) then
    return nil, "options.max_iterations: positive integer expected, got " .. describe(max_it)
  end
  return method, tol, max_it
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

--- Solve the pose of one tag.
-- @tparam {{number,number},...} corners the four corners in detection order, each `{u, v}` or
--   `{x = u, y = v}`, in pixels
-- @tparam table camera `{fx =, fy =, cx =, cy =}` in pixels
-- @tparam number tag_size side of the tag's black square (> 0); lengths come out in its unit
-- @tparam[opt] table options `method` (`"seed"`), `tolerance` (solveQuad's threshold,
--   default 1e-10), `max_iterations` (default 100)
-- @treturn table pose `{position = {x, y, z}, rotation = {{...}, {...}, {...}},
--   quaternion = {w, x, y, z}, error = px, iterations = n}`
-- @return nil, string when the corners cannot be a tag's (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
-- @usage
-- local pose = tagpose.solve({{280, 280}, {360, 280}, {360, 200}, {280, 200}},
--   {fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5}, 0.024)
function M.solve(corners, camera, tag_size, options)
  local bad, problem = read_corners(corners)
  if not bad then arg_error(1, problem) end
  problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  if not is_positive(tag_size) then
    arg_error(3, "positive number expected for tag_size, got " .. describe(tag_size))
  end
  local method, tol, max_it = read_options(options)
  if not method then arg_error(4, tol) end
  if bad ~= true then return nil, "tagpose: corner " .. bad .. " is not finite" end

  for i = 1, 4 do
    m[2 * i - 1], m[2 * i] = camera_model.normalise(camera, px[2 * i - 1], px[2 * i])
  end
  local l1, l2, l3, l4 = square.shape(m)
  if not l1 then return nil, l2 end
  local half = 0.5 * tag_size
  -- the report's method
  local X0, Y0 = square.proximate(l1, l2, l3, l4)
  square.quadratics(m, q)
  local X, Y, iterations = solvequad.solve(q, X0, Y0, tol, max_it)
  local tx, ty, tz
  problem = nil
  if X then
    tx, ty, tz = square.pose(m, X, Y, half, r)
    if not tx then problem = ty end
  else
    problem = Y
  end
  if method == "seed" then
    if problem then return nil, problem end
    local err = pose.reprojection_error(camera, r, tx, ty, tz, half, px)
    return pose.result(r, tx, ty, tz, err, iterations)
  end
  -- refined: from the report's pose (or the proximate one where it has none), all four corners
  if problem then
    tx, ty, tz = square.proximate_pose(m, l1, l2, l3, l4, half, r)
    if not tx then return nil, ty end
  end
  local c1, c2, k1, k2
  tx, ty, tz, c1, k1 = refine.refine(camera, px, half, r, tx, ty, tz)
  -- and the other local minimum of the planar ambiguity
  refine.mirror(r, tx, ty, tz, r2)
  local ux, uy, uz
  ux, uy, uz, c2, k2 = refine.refine(camera, px, half, r2, tx, ty, tz)
  if not (c1 < math.huge) and not (c2 < math.huge) then
    return nil, "refine: no pose puts every corner in front of the camera"
  end
  local same = rotation.angle(r, r2) < 1e-6
  local main = pose.result(r, tx, ty, tz, math.sqrt(c1 / 4), iterations)
  local other
  if not same and c2 < math.huge then
    other = pose.result(r2, ux, uy, uz, math.sqrt(c2 / 4), iterations)
    other.refine_iterations = k2
  end
  main.refine_iterations = k1 + k2
  if other and c2 < c1 then
    main, other = other, main
    main.refine_iterations, other.refine_iterations = other.refine_iterations, k1
  end
  main.alternative = other
  return main
end

return M
