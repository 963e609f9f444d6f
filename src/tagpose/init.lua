--- tagpose: the 3D pose of an AprilTag from its four image corners, in pure Lua.
--
-- Frames and units (those of AprilTag 3's `estimate_tag_pose` and OpenCV's
-- `SOLVEPNP_IPPE_SQUARE`): camera x right, y down, z forward; tag origin at its centre, x right,
-- y down, z into the tag; corners in detection order `c1 = (-s/2, +s/2, 0)`,
-- `c2 = (+s/2, +s/2, 0)`, `c3 = (+s/2, -s/2, 0)`, `c4 = (-s/2, -s/2, 0)`; the pose maps tag to
-- camera, `X_cam = R X_tag + t`; lengths in the unit of the tag size, angles in radians,
-- image coordinates in pixels.
-- @module tagpose

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local solvequad = require("tagpose.core.solvequad")
local rotation = require("tagpose.core.rotation")
local pipeline = require("tagpose.core.pipeline")
local result = require("tagpose.result")

local is_positive, describe, is_finite = args.is_positive, args.describe, compat.is_finite

local M = {
  _VERSION = "tagpose 0.3.0",
  camera = camera_model,
  rotation = rotation,
}

--- solveQuad's threshold when it only starts the refined method, unless `options.tolerance`
-- says otherwise (`tagpose.core.pipeline.REFINED_TOLERANCE`).
M.REFINED_TOLERANCE = pipeline.REFINED_TOLERANCE

-- The fields loaded when first used: a robot that only solves never loads them.
local ON_DEMAND = {
  block = "tagpose.block",
  layout = "tagpose.layout",
  tracker = "tagpose.tracker",
  calibration = "tagpose.formats.calibration",
  transform = "tagpose.transform",
  localizer = "tagpose.localizer",
}

--- The robot's pose on a map from one camera frame (`tagpose.localizer.localize`, loaded when
-- first called): the floor, gravity and optionally the gyro's heading as priors, tags that
-- disagree left out, the covariance, the confidence and the other minimum.
-- @function localize
-- @tparam {table,...} detections `{id =, corners =}` each
-- @tparam table camera a calibration with its `mount` (camera → robot)
-- @tparam table map a layout in the field's frame
-- @tparam[opt] table options
-- @treturn table|nil the robot's pose
M.localize = function(detections, camera, map, options)
  return require("tagpose.localizer").localize(detections, camera, map, options)
end

setmetatable(M, {
  __index = function(t, key)
    local name = ON_DEMAND[key]
    if not name then return nil end
    local module = require(name)
    rawset(t, key, module)
    return module
  end,
})

local work = pipeline.new() -- the pipeline's workspace, reused by every solve
local ending = result.context(work) -- what the end of every solve is told (tagpose.result)
local finish = result.finish
local defaults = true -- whether ending holds the defaults of what the options set
local track -- tagpose.track, loaded with the first prior

-- the options solve takes
local OPTIONS = { "method", "prior", "into", "tolerance", "max_iterations", "sigma", "time",
  "order" }

-- Read the options: the method, solveQuad's tolerance and bound, and what the end of the solve
-- takes into the context ctx (`tagpose.result`); or nil and a description of the misuse.
local function read_options(options, ctx)
  if options == nil then
    if not defaults then
      ctx.prior, ctx.chained, ctx.into, ctx.sigma2, ctx.time = false, false, false, false, false
      defaults = true
    end
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
  local chained = false
  if prior ~= nil then
    if type(prior) ~= "table" then
      return nil, "options.prior: pose table expected, got " .. type(prior)
    end
    track = track or require("tagpose.track")
    local pose = prior
    prior = track.from_prior(pose)
    if not prior then
      return nil, "options.prior: pose with a finite quaternion or rotation expected"
    end
    -- (a state of a solve's own, not one made from the caller's pose)
    chained = prior == rawget(pose, "track")
  end
  if into ~= nil and type(into) ~= "table" then
    return nil, "options.into: table expected, got " .. type(into)
  end
  local sigma = options.sigma
  if sigma ~= nil and not is_positive(sigma) then
    return nil, "options.sigma: positive number expected, got " .. describe(sigma)
  end
  local time = options.time
  if time ~= nil and not is_finite(time) then
    return nil, "options.time: finite number expected, got "
      .. (time ~= time and "NaN" or describe(time))
  end
  local opencv, why = args.read_order(options.order)
  if opencv == nil then return nil, why end
  ctx.prior, ctx.chained, ctx.into = prior or false, chained, into or false
  ctx.sigma2, ctx.time = sigma and sigma * sigma or false, time or false
  defaults = false
  return method, tol, max_it
end

-- Whether the options put the corners in OpenCV's order (read before the corners are).
local function opencv_order(options)
  return type(options) == "table" and options.order == "opencv"
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
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
--     `tagpose.track.FRAME` after the prior's frame); a chain of solves whose times step by 5
--     or more at a steady cadence (milliseconds) has a `warning` on its poses, and says so
--     once on standard error;
--   - `into`: a pose table from an earlier call to fill instead of allocating a new one;
--   - `sigma`: the standard deviation of the corner noise in pixels, for `covariance` and
--     `confidence` (default: with `prior`, the tracker's running estimate; else
--     `tagpose.uncertainty.DEFAULT_SIGMA` pooled with this frame's residuals);
--   - `order`: `"apriltag"` (the default: the detection order c1..c4 above) or `"opencv"`
--     (OpenCV's and ArUco's detectors: top-left, top-right, bottom-right, bottom-left of the
--     printed tag, that is c4, c3, c2, c1);
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
  local read, problem = args.read_corners(corners, w.px, opencv_order(options))
  if not read then arg_error(1, problem) end
  problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  problem = args.check_size(tag_size, "tag_size")
  if problem then arg_error(3, problem) end
  local ctx = ending
  local method, tol, max_it = read_options(options, ctx)
  if not method then arg_error(4, tol) end
  if read ~= true then return nil, "tagpose: corner " .. read .. " is not finite" end
  local ok, why = pipeline.prepare(w, camera)
  if not ok then return nil, why end
  local half = 0.5 * tag_size
  local seed = method == "seed"
  if seed then
    ok, why = pipeline.seed(w, half, tol, max_it)
  else
    ok, why = pipeline.refined(w, half, tol, max_it)
  end
  if not ok then return nil, why end
  ctx.camera, ctx.half, ctx.seed = camera, half, seed
  return finish(ctx)
end

return M
