--- The end of every solve of one tag: from the pipeline's candidates to the pose a caller gets.
--
-- `tagpose.solve` and `tagpose.tracker` both run the pipeline (`tagpose.core.pipeline`) and
-- end with `finish`: the candidates checked finite (the report's method: its error measured),
-- with a prior the tracking filter's choice between them (`tagpose.track`), σ² for the
-- covariance, and the pose table (`tagpose.result.pose`) with its confidence.
--
-- `finish` takes a context: a record of named fields that each caller makes once
-- (`context`) and fills again before every solve, so that ending a solve allocates nothing
-- beyond the pose table. Its fields (false where there is none):
--
-- * `work`: the pipeline's workspace, after `pipeline.refined` or, when `seed` is true,
--   `pipeline.seed` (the corners in `work.px`);
-- * `camera`, the checked camera; `half`, half the tag side;
-- * `sigma2`: σ² of the corner noise (px²) for the covariance; false: with a filter, its
--   running estimate, else the single frame's default (`tagpose.uncertainty`);
-- * `side`: the tag's side in pixels, as the caller measured it; false: measured here;
-- * `time`: the frame's time (s), for the filter's motion model;
-- * `into`: a pose table to fill instead of a new one;
-- * `prior`: the tracking filter's state of the previous frame, which chooses between the
--   candidates. In a chain of solves (`options.prior`), its posterior goes into a state of the
--   pose's own (into's, reused), the pose's `track`, and `chained` says that the prior's state
--   is a solve's own (the chain's cadence is carried: steps that look like milliseconds give
--   the pose a `warning`);
-- * `in_place` (a tracker): `prior` is the state of the tag's track, stepped in place and kept
--   by the caller (the pose has no `track` of it); a track that starts here starts from the
--   noise measured so far on the caller's tracks, `noise` and `noise_dof`
--   (`tagpose.track.noise`), which each frame's pose adds to, and its first confidence is the
--   single frame's.
-- @module tagpose.result

local pipeline = require("tagpose.core.pipeline")
local pose = require("tagpose.result.pose")

local sqrt = math.sqrt
local new, set_confidence = pose.new, pose.set_confidence
local finite, finish_seed = pipeline.finite, pipeline.finish_seed

local M = {}

local track -- tagpose.track, loaded with the first prior

--- A context for `finish`, to fill before each solve (its fields above).
-- @tparam table work the pipeline's workspace the caller solves in
-- @treturn table the context
function M.context(work)
  -- (every field made here, so that filling it never grows the table)
  return { work = work, seed = false, camera = false, half = 0, sigma2 = false, side = false,
    time = false, into = false, prior = false, chained = false, in_place = false, noise = 0,
    noise_dof = 0 }
end

-- The tag's mean side in pixels (the corners px, flat).
-- (Written out: on LuaJIT a loop here starts a side trace that cannot be compiled.)
local function side_of(px)
  local u1, v1, u2, v2, u3, v3, u4, v4 = px[1], px[2], px[3], px[4], px[5], px[6], px[7], px[8]
  local a, b, c, d = u2 - u1, v2 - v1, u3 - u2, v3 - v2
  local e, f, g, h = u4 - u3, v4 - v3, u1 - u4, v1 - v4
  return 0.25 * (sqrt(a * a + b * b) + sqrt(c * c + d * d) + sqrt(e * e + f * f)
    + sqrt(g * g + h * h))
end

-- Steps between the frames of a chain of tracked solves (`options.prior` and `options.time`)
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

local spare_state = setmetatable({}, { __mode = "k" }) -- into -> a state to fill next

-- The state record a chain's solve fills: into's own (the prior's, when into is the prior, is
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

--- The end of a solve: the pose from the pipeline's candidates, as the context says.
-- @tparam table ctx a context (`context`), filled for this solve
-- @treturn table the pose (`tagpose.result.pose`)
-- @return nil, string when the candidates give no finite pose
function M.finish(ctx)
  local w = ctx.work
  if ctx.seed then
    -- the report's method: one candidate, its error measured here. Its pose is not a
    -- least-squares minimum and the method does not look at the other: its covariance is
    -- σ² H⁻¹ at it, its confidence 1
    local err, why = finish_seed(w, ctx.camera, ctx.half)
    if not err then return nil, why end
    return new(ctx, w.first, err, nil, nil, ctx.sigma2 or nil, ctx.side or side_of(w.px))
  end
  local ok, why = finite(w)
  if not ok then return nil, why end
  local a, b = w.first, w.count == 2 and w.second or nil
  local ea, eb = sqrt(a.sse / 4), b and sqrt(b.sse / 4)
  local size = ctx.side or side_of(w.px)
  local prior = ctx.prior
  if not prior then return new(ctx, a, ea, b, eb, ctx.sigma2 or nil, size) end
  -- the tracking filter's choice between a and b
  track = track or require("tagpose.track")
  local time, in_place = ctx.time or nil, ctx.in_place
  local state, started = prior, false
  if in_place then
    started = state.count == 0
    if started then state.sigma2, state.dof = ctx.noise, ctx.noise_dof end
  else
    state = state_into(ctx.into, prior)
  end
  local pick, p = track.step(prior, a, b, size, time, state)
  local warning = nil
  if not in_place then warning = cadence(prior, state, time, ctx.chained) end
  if pick == 2 then a, b, ea, eb = b, a, eb, ea end
  if in_place then ctx.noise, ctx.noise_dof = track.noise(ctx.noise, ctx.noise_dof, a.sse) end
  -- σ² for the covariance: the caller's σ, else what the filter's running estimate with this
  -- frame says of it (the filter keeps its own estimate even when σ is given: its confidence
  -- map was fitted so)
  local r = new(ctx, a, ea, b, eb, ctx.sigma2 or track.noise_mean(state.sigma2, state.dof),
    size)
  if b and not started then set_confidence(r, track.confidence(p)) end
  if not in_place then
    r.track = state
    r.warning = warning
  end
  return r
end

return M
