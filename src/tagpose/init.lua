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
local result = require("tagpose.core.result")

local is_positive, describe, is_finite = args.is_positive, args.describe, compat.is_finite
local sqrt = math.sqrt

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
local track -- tagpose.track, loaded with the first prior

-- the options solve takes
local OPTIONS = { "method", "prior", "into", "tolerance", "max_iterations", "sigma", "time",
  "order" }

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
  return method, tol, max_it, prior, into, sigma, time, chained
end

-- Whether the options put the corners in OpenCV's order (read before the corners are).
local function opencv_order(options)
  return type(options) == "table" and options.order == "opencv"
end

--- Steps between the frames of a chain of tracked solves (`options.prior` and `options.time`)
-- of at least this many seconds, three in a row at a steady cadence (each within 1.5 times the
-- one before), are times in milliseconds: the pose's `warning` says so (and standard error,
-- once per chain). The tracking filter models steps up to `tagpose.track.MAX_STEP`.
local STEADY_STEP = 5

-- The cadence of a chain of tracked solves carried from the prior's state to the new one:
-- the step, how many steps in a row were steady and long, whether the chain was warned. The
-- warning, or nil.
local function cadence(prior, state, time, chained)
  local step, steady, warned = nil, 0, nil
  if chained then
    warned = prior.warned
    if time ~= nil then
      step = time - prior.time
      local last = prior.step
      if step >= STEADY_STEP and last and last >= STEADY_STEP and step < 1.5 * last
        and last < 1.5 * step then
        steady = (prior.steady or 0) + 1
      end
    end
  end
  state.step, state.steady, state.warned = step, steady, warned
  if steady < 2 then return nil end
  local text = ("options.time steps by %.4g between frames, steadily: the tracking filter takes"
    .. " seconds, and these times look like milliseconds (pass seconds)"):format(step)
  if not warned then
    state.warned = true
    io.stderr:write("tagpose: warning: ", text, "\n")
  end
  return "tagpose: " .. text
end

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

-- The tag's mean side in pixels (the corners px, flat).
-- (Written out: on LuaJIT a loop here starts a side trace that cannot be compiled.)
local function side(px)
  local u1, v1, u2, v2, u3, v3, u4, v4 = px[1], px[2], px[3], px[4], px[5], px[6], px[7], px[8]
  local a, b, c, d = u2 - u1, v2 - v1, u3 - u2, v3 - v2
  local e, f, g, h = u4 - u3, v4 - v3, u1 - u4, v1 - v4
  return 0.25 * (sqrt(a * a + b * b) + sqrt(c * c + d * d) + sqrt(e * e + f * f)
    + sqrt(g * g + h * h))
end

local spare_state = setmetatable({}, { __mode = "k" }) -- into -> a state to fill next

-- The state record a tracked solve fills: into's own (the prior's, when into is the prior, is
-- kept for the next frame while a spare is filled), or a new one.
local function state_into(into, prior)
  if not into then return track.new_state() end
  local current = rawget(into, "track")
  if track.is_state(current) and current ~= prior then return current end
  local state = spare_state[into]
  if not state or state == prior then state = track.new_state() end
  if track.is_state(current) then spare_state[into] = current end
  return state
end

-- The result of the refined method from an ordered workspace: the better fit, or with a prior
-- the tracking filter's choice (`tagpose.track`), whose state goes into the result's `track`.
local function refined_result(w, camera, half, prior, into, sigma, time, chained)
  local ok, why = pipeline.finite(w)
  if not ok then return nil, why end
  local a, b = w.first, w.count == 2 and w.second or nil
  local ea, eb = sqrt(a.sse / 4), b and sqrt(b.sse / 4)
  local size = side(w.px)
  local sigma2 = sigma and sigma * sigma or nil
  if not prior then
    return result.new(a, ea, b, eb, w.iterations, w.linearisations, b and b.linearisations,
      camera, half, sigma2, size, time, into)
  end
  local state = state_into(into, prior)
  local pick, p = track.step(prior, a, b, size, time, state)
  local warning = cadence(prior, state, time, chained)
  if pick == 2 then a, b, ea, eb = b, a, eb, ea end
  -- (the filter keeps its own running estimate of σ² even when options.sigma is given: its
  -- confidence map was fitted so; σ, or the mean of σ² that estimate implies, sets the
  -- covariance, as in tagpose.tracker)
  local r = result.new(a, ea, b, eb, w.iterations, w.linearisations, b and b.linearisations,
    camera, half, sigma2 or track.noise_mean(state.sigma2, state.dof), size, time, into)
  if b then result.set_confidence(r, track.confidence(p)) end
  r.track = state
  r.warning = warning
  return r
end

-- The result of the report's method (one candidate, its error measured here). The report's
-- pose is not a least-squares minimum and its method does not look at the other: its
-- covariance is σ² H⁻¹ at it, its confidence 1.
local function seed_result(w, camera, half, into, sigma, time)
  local err, why = pipeline.finish_seed(w, camera, half)
  if not err then return nil, why end
  return result.new(w.first, err, nil, nil, w.iterations, nil, nil, camera, half,
    sigma and sigma * sigma or nil, side(w.px), time, into)
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
  local method, tol, max_it, prior, into, sigma, time, chained = read_options(options)
  if not method then arg_error(4, tol) end
  if read ~= true then return nil, "tagpose: corner " .. read .. " is not finite" end
  local ok, why = pipeline.prepare(w, camera)
  if not ok then return nil, why end
  local half = 0.5 * tag_size
  if method == "refined" then
    ok, why = pipeline.refined(w, half, tol, max_it)
    if not ok then return nil, why end
    return refined_result(w, camera, half, prior, into, sigma, time, chained)
  end
  ok, why = pipeline.seed(w, half, tol, max_it)
  if not ok then return nil, why end
  return seed_result(w, camera, half, into, sigma, time)
end

return M
