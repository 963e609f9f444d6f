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
local solvequad = require("tagpose.solvequad")
local rotation = require("tagpose.rotation")
local track = require("tagpose.track")
local pose = require("tagpose.pose")
local pipeline = require("tagpose.pipeline")
local uncertainty = require("tagpose.uncertainty")
local refine = require("tagpose.refine")

local is_positive, describe = args.is_positive, args.describe
local sqrt, exp = math.sqrt, math.exp
local to_quaternion = rotation.to_quaternion
local _ = compat

local M = {
  _VERSION = "tagpose 0.1.0",
  camera = camera_model,
}

--- solveQuad's threshold when it only starts the refined method, unless `options.tolerance`
-- says otherwise (`tagpose.pipeline.REFINED_TOLERANCE`).
M.REFINED_TOLERANCE = pipeline.REFINED_TOLERANCE

local work = pipeline.new() -- the pipeline's workspace, reused by every solve
local state = {} -- tracking state of this frame, when the result has none to fill
local qa, qb = {}, {} -- the candidates' quaternions, as the tracker takes them
local spare = setmetatable({}, { __mode = "k" }) -- into -> an alternative table to reuse

-- the options solve takes
local OPTIONS = { "method", "prior", "into", "tolerance", "max_iterations", "sigma" }

-- Read the options; or nil and a description of the misuse.
local function read_options(options)
  if options == nil then
    return "refined", M.REFINED_TOLERANCE, solvequad.MAX_ITERATIONS
  end
  if type(options) ~= "table" then return nil, "options table expected, got " .. type(options) end
  local unknown = args.unknown_keys(options, OPTIONS, "options")
  if unknown then return nil, unknown end
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
  local prior, into = options.prior, options.into
  if prior ~= nil then
    if type(prior) ~= "table" then
      return nil, "options.prior: pose table expected, got " .. type(prior)
    end
    prior = track.from_prior(prior)
    if not prior then
      return nil, "options.prior: pose with a finite quaternion or rotation expected"
    end
  end
  if into ~= nil and type(into) ~= "table" then
    return nil, "options.into: table expected, got " .. type(into)
  end
  local sigma = options.sigma
  if sigma ~= nil and not is_positive(sigma) then
    return nil, "options.sigma: positive number expected, got " .. describe(sigma)
  end
  return method, tol, max_it, prior, into, sigma
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

-- Which candidate of an ordered workspace is the pose: the first (the smaller error), or the
-- tracker's choice given the prior's state; the track state of this frame goes into `out`.
-- Returns the pose's candidate and the other (nil when there is no second minimum).
local function choose(w, prior, out)
  local a, b = w.first, w.second
  local has2 = w.count == 2
  qa[1], qa[2], qa[3], qa[4] = a.qw, a.qx, a.qy, a.qz
  qb[1], qb[2], qb[3], qb[4] = b.qw, b.qx, b.qy, b.qz
  if prior then
    if track.choose(prior, qa, a.sse, has2 and qb or nil, b.sse, out) == 2 and has2 then
      a, b = b, a
    end
  else
    track.start(out, qa, a.sse, has2 and qb or nil, b.sse)
  end
  return a, has2 and b or nil
end

-- The branch confidence of a result and its alternative (their candidates a and b), and their
-- covariances, made when first read (`tagpose.uncertainty`). σ²: options.sigma, else the
-- tracker's running estimate, else the default pooled with the frame's residuals. With a
-- tracking state the confidence is the tracker's posterior.
local function uncertain(result, alt, a, b, sigma, track_state)
  local sigma2 = sigma and sigma * sigma or (track_state and track_state[10])
    or uncertainty.noise(a.sse)
  local conf, _, ka, kb, d1, d2, d3, d4, d5, d6 = uncertainty.assess(a, alt and b, sigma2)
  if alt and track_state then conf = 1 / (1 + exp(-track_state[9])) end
  result.confidence = conf
  uncertainty.resolve(result, a, sigma2, ka, d1, d2, d3, d4, d5, d6)
  if alt then
    alt.confidence = 1 - conf
    uncertainty.resolve(alt, b, sigma2, kb, -d1, -d2, -d3, -d4, -d5, -d6)
  end
  return result
end

-- The public result of the refined method from an ordered workspace.
local function refined_result(w, prior, into, sigma)
  local out_state = into and type(into.track) == "table" and into.track or state
  local a, b = choose(w, prior, out_state)
  local ea = sqrt(a.sse / 4)
  if not pose.is_finite(a, ea) then
    return nil, "tagpose: no finite pose for these corners"
  end
  local alt = nil
  if b then
    local eb = sqrt(b.sse / 4)
    if pose.is_finite(b, eb) then
      alt = pose.result(b, eb, w.iterations, b.linearisations, into and (into.alternative
        or spare[into]))
      alt.alternative, alt.track = nil, nil
    end
  end
  local result = pose.result(a, ea, w.iterations, w.linearisations, into)
  if into and result.alternative and not alt then spare[into] = result.alternative end
  result.alternative = alt
  local st = result.track
  if type(st) ~= "table" then
    result.track = { out_state[1], out_state[2], out_state[3], out_state[4], out_state[5],
      out_state[6], out_state[7], out_state[8], out_state[9], out_state[10] }
  elseif st ~= out_state then
    for i = 1, 10 do st[i] = out_state[i] end
  end
  return uncertain(result, alt, a, b, sigma, prior and out_state)
end

-- The public result of the report's method (one candidate, its error measured here). The
-- report's pose is not a least-squares minimum and its method does not look at the other: its
-- covariance is σ² H⁻¹ at it, its confidence 1.
local function seed_result(w, camera, half, into, sigma)
  local a = w.first
  a.qw, a.qx, a.qy, a.qz = to_quaternion(a.r)
  local err = pose.reprojection_error(w.C, a.r, a.tx, a.ty, a.tz, half, w.px)
  if not pose.is_finite(a, err) then
    return nil, "tagpose: no finite pose for these corners"
  end
  local result = pose.result(a, err, w.iterations, nil, into)
  if into then into.alternative, into.track = nil, nil end
  a.sse = refine.normal(camera, w.px, half, a.r, a.tx, a.ty, a.tz, a.normal)
  result.confidence = 1
  uncertainty.resolve(result, a, sigma and sigma * sigma or uncertainty.noise(a.sse), 0, 0, 0,
    0, 0, 0, 0)
  return result
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
--   - `prior`: the pose this tag had in the previous frame, for tracking (`tagpose.track`);
--   - `into`: a pose table from an earlier call to fill instead of allocating a new one;
--   - `sigma`: the standard deviation of the corner noise in pixels, for `covariance` and
--     `confidence` (default: with `prior`, the tracker's running estimate; else
--     `tagpose.uncertainty.DEFAULT_SIGMA` pooled with this frame's residuals);
--   - `tolerance`: solveQuad's threshold (default 1e-10 for `"seed"`, `REFINED_TOLERANCE`
--     for `"refined"`), `max_iterations`: its bound (default 100).
-- @treturn table pose `{position = {x, y, z}, rotation = {{...}, {...}, {...}},
--   quaternion = {w, x, y, z}, error = px, iterations = n, refine_iterations = n,
--   confidence = p, covariance = {{...} x 6}, alternative = pose or nil, track = state}`:
--   `covariance[i][j]` in the order (x, y, z, rx, ry, rz), position in tag-size units and a
--   small rotation vector `r` in the camera frame, `R_true = exp([r]×) R`; `confidence` the
--   probability that the pose is on the true branch of the planar ambiguity (1 where there is
--   one minimum; with `prior`, the tracker's posterior), the alternative's its complement
-- @return nil, string when the corners cannot be a tag's (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
-- @usage
-- local pose = tagpose.solve({{280, 280}, {360, 280}, {360, 200}, {280, 200}},
--   {fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5}, 0.024)
function M.solve(corners, camera, tag_size, options)
  local w = work
  local bad, problem = args.read_corners(corners, w.px)
  if not bad then arg_error(1, problem) end
  problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  problem = args.check_size(tag_size, "tag_size")
  if problem then arg_error(3, problem) end
  local method, tol, max_it, prior, into, sigma = read_options(options)
  if not method then arg_error(4, tol) end
  if bad ~= true then return nil, "tagpose: corner " .. bad .. " is not finite" end
  local ok, why = pipeline.prepare(w, camera)
  if not ok then return nil, why end
  local half = 0.5 * tag_size
  if method == "refined" then
    ok, why = pipeline.refined(w, half, tol, max_it)
    if not ok then return nil, why end
    return refined_result(w, prior, into, sigma)
  end
  ok, why = pipeline.seed(w, half, tol, max_it)
  if not ok then return nil, why end
  return seed_result(w, camera, half, into, sigma)
end

--- Blocks: cubes carrying a tag on each face (`tagpose.block`).
M.block = require("tagpose.block")

--- Layouts: rigid sets of tags of any shape (`tagpose.layout`).
M.layout = require("tagpose.layout")

--- Calibration files: a camera from a ROS, OpenCV or Lua camera file (`tagpose.calibration`).
M.calibration = require("tagpose.calibration")

return M
