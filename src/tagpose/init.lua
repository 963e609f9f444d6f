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
local refine = require("tagpose.refine")
local rotation = require("tagpose.rotation")
local track = require("tagpose.track")
local pose = require("tagpose.pose")
local ippe = require("tagpose.ippe")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local sqrt, huge = math.sqrt, math.huge
local to_quaternion = rotation.to_quaternion

local M = {
  _VERSION = "tagpose 0.1.0",
  camera = camera_model,
}

--- solveQuad's threshold when it only starts the refined method (unless `options.tolerance`
-- says otherwise): the refinement converges to the same pose from any start this close, so
-- solving the quadratics to the report's 1e-10 would be work thrown away. (The refined method
-- starts from `tagpose.ippe`'s poses; the report's method is its fallback start.)
M.REFINED_TOLERANCE = 1e-7

-- scratch, written in place on every solve and never handed out
local px = {} -- pixel corners, flat
local m = {} -- normalised, undistorted corners, flat
local q = {} -- the two quadratics' coefficients
local depth = {} -- the proximate solution's corner depths
local r1, r2 = {}, {} -- rotations of the two candidates
local qa, qb = {}, {} -- their quaternions {w, x, y, z}
local ta, tb = {}, {} -- and positions {x, y, z}
local frame = {} -- the frame as the tracking filter reads it
local state = {} -- tracking state of this frame
local prior_state = {} -- tracking state made from a prior without one
local spare = setmetatable({}, { __mode = "k" }) -- into -> an alternative table to reuse

-- The quaternion {w, x, y, z} of a pose table (quaternion or rotation field), or nil.
local function pose_quaternion(p, out)
  if type(p) ~= "table" then return nil end
  local qt = p.quaternion
  if type(qt) == "table" and is_finite(qt.w) and is_finite(qt.x) and is_finite(qt.y)
    and is_finite(qt.z) then
    local n = sqrt(qt.w * qt.w + qt.x * qt.x + qt.y * qt.y + qt.z * qt.z)
    if n > 0 then
      out[1], out[2], out[3], out[4] = qt.w / n, qt.x / n, qt.y / n, qt.z / n
      return out
    end
  end
  local rt = p.rotation
  if type(rt) == "table" and type(rt[1]) == "table" and type(rt[2]) == "table"
    and type(rt[3]) == "table" then
    local flat = rotation.from_nested(rt, r2)
    for i = 1, 9 do
      if not is_finite(flat[i]) then return nil end
    end
    out[1], out[2], out[3], out[4] = to_quaternion(flat)
    return out
  end
  return nil
end

-- The position {x, y, z} of a pose table, or nil.
local function pose_position(p, out)
  local pt = type(p) == "table" and p.position
  if type(pt) == "table" and is_finite(pt.x) and is_finite(pt.y) and is_finite(pt.z) and pt.z > 0
  then
    out[1], out[2], out[3] = pt.x, pt.y, pt.z
    return out
  end
  return nil
end

-- The tracking state a prior carries, or one made from its pose (and alternative's).
local function read_prior(prior)
  local t = prior.track
  if track.is_state(t) then return t end
  if not pose_quaternion(prior, qa) then return nil end
  local alt = pose_quaternion(prior.alternative, qb)
  return track.from_pose(prior_state, qa, pose_position(prior, ta), alt,
    alt and pose_position(prior.alternative, tb))
end

-- Read the options; or nil and a description of the misuse.
local function read_options(options)
  if options == nil then
    return "refined", M.REFINED_TOLERANCE, solvequad.MAX_ITERATIONS
  end
  if type(options) ~= "table" then return nil, "options table expected, got " .. type(options) end
  local method = options.method
  if method == nil then
    method = "refined"
  elseif method ~= "refined" and method ~= "seed" then
    return nil, "options.method: 'refined' or 'seed' expected, got " .. describe(method)
  end
  local tol = options.tolerance
  if tol == nil then
    tol = method == "seed" and solvequad.TOLERANCE or M.REFINED_TOLERANCE
  elseif not is_positive(tol) then
    return nil, "options.tolerance: positive number expected, got " .. describe(tol)
  end
  local max_it = options.max_iterations
  if max_it == nil then
    max_it = solvequad.MAX_ITERATIONS
  elseif not args.is_count(max_it) then
    return nil, "options.max_iterations: positive integer expected, got " .. describe(max_it)
  end
  local time = options.time
  if time ~= nil and not is_finite(time) then
    return nil, "options.time: finite number expected, got "
      .. (time ~= time and "NaN" or describe(time))
  end
  local prior, into = options.prior, options.into
  if prior ~= nil then
    if type(prior) ~= "table" then
      return nil, "options.prior: pose table expected, got " .. type(prior)
    end
    prior = read_prior(prior)
    if not prior then
      return nil, "options.prior: pose with a finite quaternion or rotation expected"
    end
  end
  if into ~= nil and type(into) ~= "table" then
    return nil, "options.into: table expected, got " .. type(into)
  end
  return method, tol, max_it, prior, into, time
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

local function finite_pose(r, tx, ty, tz, err)
  local s = tx + ty + tz + err
  for i = 1, 9 do s = s + r[i] end
  return s == s and s < huge and s > -huge
end

-- Normalise and undistort the corners (px into m) and check their shape: true, or nil and why.
-- The proximate depths go into `depth`.
local function prepare(camera)
  if camera.distortion == nil then
    local fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
    m[1], m[2], m[3], m[4] = (px[1] - cx) / fx, (px[2] - cy) / fy, (px[3] - cx) / fx,
      (px[4] - cy) / fy
    m[5], m[6], m[7], m[8] = (px[5] - cx) / fx, (px[6] - cy) / fy, (px[7] - cx) / fx,
      (px[8] - cy) / fy
  else
    for i = 1, 4 do
      local x, y = camera_model.normalise(camera, px[2 * i - 1], px[2 * i])
      if not x then return nil, y .. " (corner " .. i .. ")" end
      m[2 * i - 1], m[2 * i] = x, y
    end
  end
  local l1, l2, l3, l4 = square.shape(m)
  if not l1 then return nil, l2 end
  depth[1], depth[2], depth[3], depth[4] = l1, l2, l3, l4
  return true
end

-- The report's method on the prepared corners: the pose into r1 and tx, ty, tz, iterations; or
-- nil, why, iterations.
local function seed(half, tol, max_it)
  local X0, Y0 = square.proximate(depth[1], depth[2], depth[3], depth[4])
  square.quadratics(m, q)
  local X, Y, iterations = solvequad.solve(q, X0, Y0, tol, max_it)
  if not X then return nil, Y, iterations end
  local tx, ty, tz = square.pose(m, X, Y, half, r1)
  if not tx then return nil, ty, iterations end
  return tx, ty, tz, iterations
end

-- The proximate pose into r1, for a start where the report's method gives none.
local function proximate(half)
  return square.proximate_pose(m, depth[1], depth[2], depth[3], depth[4], half, r1)
end

-- The two local minima of the planar ambiguity from one start in r1: the start refined over
-- all four corners, and the mirror of that minimum refined. Returns both (translations, sums
-- of squared residuals, linearisations); a sum is math.huge where its start put a corner
-- behind the camera.
local function minima(camera, half, tx, ty, tz)
  local c1, k1, c2, k2, ux, uy, uz
  tx, ty, tz, c1, k1 = refine.refine(camera, px, half, r1, tx, ty, tz)
  refine.mirror(r1, tx, ty, tz, r2)
  ux, uy, uz, c2, k2 = refine.refine(camera, px, half, r2, tx, ty, tz)
  return tx, ty, tz, c1, k1, ux, uy, uz, c2, k2
end

-- The tag's mean side in pixels (the corners in px).
local function side()
  local s = 0
  for i = 1, 4 do
    local j = i % 4 + 1
    local du, dv = px[2 * j - 1] - px[2 * i - 1], px[2 * j] - px[2 * i]
    s = s + sqrt(du * du + dv * dv)
  end
  return 0.25 * s
end

-- The second half of `choose`: the tracking filter's choice between the two candidates (the
-- first, r1, in qa and ta; the second, r2, in qb and tb; c1, c2 their sums of squares), and
-- the result.
local function decide(c1, c2, has2, k1, k2, iterations, prior, into)
  local out_state = into and type(into.track) == "table" and into.track or state
  -- the filter's frame: the candidates by error, the tag's size
  local first = c2 < c1 and 2 or 1
  local q1, q2, t1, t2 = qa, qb, ta, tb
  if first == 2 then q1, q2, t1, t2, c1, c2 = qb, qa, tb, ta, c2, c1 end
  frame.q1, frame.t1, frame.sse1 = q1, t1, c1
  frame.q2, frame.t2, frame.sse2 = has2 and q2 or nil, t2, c2
  frame.size = side()
  local pick, p = track.choose(prior, frame, out_state)
  local confidence = has2 and track.confidence(p) or 1
  -- the pose: the first candidate by error unless the filter says otherwise
  local qp, tp, qo, to, cp, co = q1, t1, q2, t2, c1, c2
  local chosen = first
  if pick == 2 then
    qp, tp, qo, to, cp, co = q2, t2, q1, t1, c2, c1
    chosen = 3 - first
  end
  local ra, rb, ka, kb = r1, r2, k1, k2
  if chosen == 2 then ra, rb, ka, kb = r2, r1, k2, k1 end
  local ea, eb = sqrt(cp / 4), sqrt(co / 4)
  if not finite_pose(ra, tp[1], tp[2], tp[3], ea) then
    return nil, "tagpose: no finite pose for these corners"
  end
  local alt = nil
  if has2 and finite_pose(rb, to[1], to[2], to[3], eb) then
    local reuse = into and (into.alternative or spare[into])
    alt = pose.result(rb, to[1], to[2], to[3], eb, iterations, kb, reuse, qo[1], qo[2], qo[3],
      qo[4])
    alt.alternative, alt.track = nil, nil
    alt.confidence = 1 - confidence
  end
  local result = pose.result(ra, tp[1], tp[2], tp[3], ea, iterations, ka + kb, into, qp[1],
    qp[2], qp[3], qp[4])
  if into and result.alternative and not alt then spare[into] = result.alternative end
  result.alternative = alt
  result.confidence = confidence
  local st = result.track
  if type(st) ~= "table" then
    st = {}
    result.track = st
  end
  if st ~= out_state then
    local n = #out_state
    for i = 1, n do st[i] = out_state[i] end
    for i = n + 1, #st do st[i] = nil end
  end
  return result
end

-- The result of the refined method from the two minima (the first in r1, the second in r2;
-- a sum of squares math.huge where that start led nowhere): the better by error, or the
-- tracker's choice, as the pose, the other as its alternative.
local function choose(tx, ty, tz, c1, k1, ux, uy, uz, c2, k2, iterations, prior, into)
  if not (c1 < huge) then
    if not (c2 < huge) then
      return nil, "refine: no pose puts every corner in front of the camera"
    end
    -- only the second start led to a pose: it is the one
    for i = 1, 9 do r1[i] = r2[i] end
    tx, ty, tz, c1, c2 = ux, uy, uz, c2, huge
  end
  local w1, x1, y1, z1 = to_quaternion(r1)
  local w2, x2, y2, z2 = w1, x1, y1, z1
  local has2 = false
  if c2 < huge then
    w2, x2, y2, z2 = to_quaternion(r2)
    -- two minima, unless both starts reached the same one (the quaternions' chord, q ~ -q, below
    -- 5e-7: an angle below 1e-6 rad)
    local dw, dx, dy, dz = w1 - w2, x1 - x2, y1 - y2, z1 - z2
    local ow, ox, oy, oz = w1 + w2, x1 + x2, y1 + y2, z1 + z2
    local dp, dm = dw * dw + dx * dx + dy * dy + dz * dz, ow * ow + ox * ox + oy * oy + oz * oz
    has2 = (dp < dm and dp or dm) > 2.5e-13
  end
  -- the candidates in the scratch tables, so that few values are live across the filter (a
  -- tail call)
  qa[1], qa[2], qa[3], qa[4], qb[1], qb[2], qb[3], qb[4] = w1, x1, y1, z1, w2, x2, y2, z2
  ta[1], ta[2], ta[3], tb[1], tb[2], tb[3] = tx, ty, tz, ux, uy, uz
  return decide(c1, c2, has2, k1, k2, iterations, prior, into)
end

-- The refined method when the local starts put a corner behind the camera (at round-off, on
-- tiny or extreme tags): the report's pose and its mirror, else the proximate pose and its
-- mirror. `spent`: the linearisations already used.
local function fallback(camera, half, tol, max_it, prior, into, spent)
  local sx, sy, sz, iterations = seed(half, tol, max_it)
  local why
  if not sx then
    why, iterations = sy, sz
    sx, sy, sz = proximate(half)
    if not sx then return nil, sy end
  end
  local tx, ty, tz, c1, k1, ux, uy, uz, c2, k2 = minima(camera, half, sx, sy, sz)
  if not (c1 < huge or c2 < huge) and why == nil then
    spent = spent + k1 + k2
    sx, sy, sz = proximate(half)
    if sx then tx, ty, tz, c1, k1, ux, uy, uz, c2, k2 = minima(camera, half, sx, sy, sz) end
  end
  return choose(tx, ty, tz, c1, k1 + spent, ux, uy, uz, c2, k2, iterations, prior, into)
end

-- The refined method: both local minima of the planar ambiguity, refined over all four corners
-- from the local (IPPE) poses of the square, then chosen between. (The stages are tail calls
-- so that few values are live where they branch: LuaJIT cannot compile side exits that carry
-- many.)
local function refined(camera, half, tol, max_it, prior, into)
  local spent = 0
  local sx, sy, sz = ippe.poses(m, depth[1], depth[2], depth[3], depth[4], half, r1, r2)
  if sx then
    local tx, ty, tz, c1, k1 = refine.refine(camera, px, half, r1, sx, sy, sz)
    local ux, uy, uz, c2, k2 = refine.refine(camera, px, half, r2, sx, sy, sz)
    if c1 < huge or c2 < huge then
      return choose(tx, ty, tz, c1, k1, ux, uy, uz, c2, k2, 0, prior, into)
    end
    spent = k1 + k2
  end
  return fallback(camera, half, tol, max_it, prior, into, spent)
end

--- Solve the pose of one tag.
-- @tparam {{number,number},...} corners the four corners in detection order, each `{u, v}` or
--   `{x = u, y = v}`, in pixels
-- @tparam table camera `{fx =, fy =, cx =, cy =}` in pixels, optionally `distortion` and
--   `model` (see `tagpose.camera`)
-- @tparam number tag_size side of the tag's black square (> 0); lengths come out in its unit
-- @tparam[opt] table options
--
--   - `method`: `"refined"` (default) or `"seed"` (the report's method exactly);
--   - `prior`: the pose this tag had in the previous frame, for tracking (`tagpose.track`;
--     `tagpose.tracker` does this for many tags);
--   - `time`: this frame's time in seconds, for the tracking filter's motion model (default:
--     `tagpose.track.FRAME` after the prior's frame);
--   - `into`: a pose table from an earlier call to fill instead of allocating a new one;
--   - `tolerance`: solveQuad's threshold (default 1e-10 for `"seed"`, `REFINED_TOLERANCE`
--     for `"refined"`), `max_iterations`: its bound (default 100).
-- @treturn table pose `{position = {x, y, z}, rotation = {{...}, {...}, {...}},
--   quaternion = {w, x, y, z}, error = px, iterations = n, refine_iterations = n,
--   confidence = probability of the right branch (with a prior: the tracking filter's
--   posterior), alternative = pose or nil, track = state}`
-- @return nil, string when the corners cannot be a tag's (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
-- @usage
-- local pose = tagpose.solve({{280, 280}, {360, 280}, {360, 200}, {280, 200}},
--   {fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5}, 0.024)
function M.solve(corners, camera, tag_size, options)
  local bad, problem = args.read_corners(corners, px)
  if not bad then arg_error(1, problem) end
  problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  if not is_positive(tag_size) then
    arg_error(3, "positive number expected for tag_size, got " .. describe(tag_size))
  end
  local method, tol, max_it, prior, into, time = read_options(options)
  if not method then arg_error(4, tol) end
  frame.time = time
  if bad ~= true then return nil, "tagpose: corner " .. bad .. " is not finite" end
  local ok, why = prepare(camera)
  if not ok then return nil, why end
  local half = 0.5 * tag_size
  if method == "refined" then return refined(camera, half, tol, max_it, prior, into) end
  local tx, ty, tz, iterations = seed(half, tol, max_it)
  if not tx then return nil, ty end
  local err = pose.reprojection_error(camera, r1, tx, ty, tz, half, px)
  if not finite_pose(r1, tx, ty, tz, err) then
    return nil, "tagpose: no finite pose for these corners"
  end
  local result = pose.result(r1, tx, ty, tz, err, iterations, nil, into)
  if into then into.alternative, into.track = nil, nil end
  return result
end

--- Blocks: cubes carrying a tag on each face (`tagpose.block`; it uses `solve` above).
M.block = require("tagpose.block")

--- Many tags tracked frame by frame (`tagpose.tracker`; it uses `solve` above).
M.tracker = require("tagpose.tracker")

return M
