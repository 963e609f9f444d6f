--- Tracking: choosing between the two poses of the planar ambiguity with the help of the
-- earlier frames, by a multi-hypothesis filter with a motion model. Loaded on demand: by
-- `tagpose.solve` given `options.prior`, and by `tagpose.tracker`.
--
-- A square seen from afar or nearly face-on has two poses that reproject almost alike: the
-- second has the tag's normal mirrored about the line of sight. Noise decides which one has
-- the smaller error, so choosing by the error alone flips between them from frame to frame.
--
-- **The tilt vector.** What tells the two poses apart is where the tag's normal `n` points
-- relative to the line of sight `l` to its centre: `τ = (n·e₁, n·e₂)`, with `e₁, e₂` the
-- camera's x and y axes turned by the smallest rotation that takes the camera's z axis onto
-- `l` (`|τ|` is the sine of the tilt; `τ = 0` is face-on). The mirrored pose has `-τ`. When a
-- tag passes face-on, the true `τ` goes *through* zero with its rate while the wrong
-- continuation turns back; which is which cannot be seen in one frame, but can in the motion.
--
-- **The filter** keeps up to `HYPOTHESES` hypotheses about the *true* tilt path, each a
-- constant-rate Kalman filter on `τ` (white angular acceleration of density `PROCESS`,
-- rad²/s³, so missed frames and uneven spacing are handled by the time between frames), with
-- a log-weight. Every frame each hypothesis branches on which candidate is the true pose:
-- its weight gains the frame's likelihood under the hypothesis, its share of it that falls on
-- that candidate's side, and the frame's evidence for the candidate (below). A new path may
-- also start at either candidate with a small weight (`BIRTH`), so a hypothesis set that lost
-- the truth recovers. Children that coincide are merged, the best `HYPOTHESES` kept. The
-- probability that a candidate is the true pose is the weight of the hypotheses that chose it.
-- (`tagpose.track.filter` does one frame: predict, branch, merge, emit.)
--
-- **The likelihood.** What the corners fix of the tilt, to first order, is its square: the
-- foreshortening's direction and amount, not its sign (the two candidates' `τ` are nearly
-- opposite). As a complex number, `q = τ²` is measured with noise that is unbiased, isotropic
-- and of one size whatever the tilt, about `2.6·σ/w` per part (σ the corner noise, w the tag's
-- side, in pixels; measured on synthetic sequences), while `τ` itself near face-on is biased
-- away from zero (about `√(σ/w)` in size) and poor in direction. So a hypothesis predicting
-- `τ̂` with per-axis variance `P` gives the frame the likelihood of a candidate's `q` under a
-- Gaussian about `τ̂²` of per-part variance `4(|τ̂|² + P)·P + ρ²`, `ρ = SQUARE_NOISE·σ/w` (the
-- measured 2.6, with an allowance); its children share it in proportion to how near each
-- candidate lies to the prediction. That is what carries a far tag through face-on: a
-- hypothesis that keeps its rate through a crossing is not penalised for a `τ` that the noise
-- inflated.
--
-- **The update.** Each child's Kalman update takes its candidate's `g·τ` with variance `r²`
-- (per axis), where with `x = |τ| / √(σ/w)`: `g = SHRINK` for `x ≤ SHRINK_FROM`, rising
-- linearly to 1 at `SHRINK_TO`, and `r = min(SPREAD, SPREAD_TAIL / x)·√(σ/w)` (measured: the
-- true branch's `τ` against the candidate's, by x).
--
-- **The evidence** of one frame is a log-likelihood ratio between the two candidates,
-- `log P(corners | first) − log P(corners | second)`: `M.evidence`, the Student-t form
-- `κ(x)·(ν + 2)/2·log((ν·s² + SSE₂)/(ν·s² + SSE₁))` of the known-noise
-- `κ(x)·(SSE₂ − SSE₁)/(2σ²)` for σ² known only as an estimate `s²` of ν degrees of freedom,
-- where the weight `κ` rises from 0 at `x = EVIDENCE_FROM` to `EVIDENCE_MAX` at `EVIDENCE_TO`
-- (near face-on the error difference says nothing about the branch), unless the caller
-- supplies its own.
--
-- **The noise** is estimated on the way (`M.noise`): the residuals of the candidate chosen
-- (`SSE/2` for its two degrees of freedom), pooled with the estimate before it whose weight
-- decays by `NOISE_MEMORY` a frame; a track starts from `NOISE_DOF` degrees of freedom at
-- `NOISE_SIGMA` (the single-frame default of `tagpose.uncertainty`), or from a state that
-- carries an estimate (`tagpose.tracker` starts its tracks from the noise its other tracks
-- measured). A frame's evidence and measurement take the estimate from before it.
--
-- **The confidence** returned is the filter's posterior probability of the chosen candidate,
-- calibrated by an increasing map of its log-odds (`CONFIDENCE`), fitted on synthetic
-- sequences with the evidence above (`bench/fit_confidence.lua`; a different evidence function
-- needs its own): up to log-odds 6 the posterior is a little overconfident (by a tenth), and
-- beyond 99.99 % a wrong branch is rare but not rarer.
--
-- **The state** of a track is a record (`new_state`; `pose.track` of a tracked solve): `time`
-- (s) of its frame, `sigma2` and `dof` (px² and degrees of freedom: the running noise
-- estimate, 0 and 0 while there is none), `first` (the posterior probability of that frame's
-- first candidate), `back_first` and `back_second` (for smoothing, see `step`), `count`
-- (hypotheses) and `hypotheses`, the filter's own flat array (`tagpose.track.filter` reads and
-- writes it; nothing else does).
--
-- A candidate, as the filter takes it, is a record with the rotation's unit quaternion
-- `qw, qx, qy, qz` (tag → camera), the tag centre `tx, ty, tz` (camera frame) and `sse`, the
-- sum of squared pixel residuals of its corners: `tagpose.core.pipeline`'s candidates are.
-- @module tagpose.track

local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")

local sqrt, exp, log = math.sqrt, math.exp, math.log
local is_finite = compat.is_finite

local M = {}

--- Nominal time between frames (s), when no time is given.
M.FRAME = 1 / 30
--- Most hypotheses kept.
M.HYPOTHESES = 12
--- Density of the white angular acceleration of the tilt vector, rad²/s³.
M.PROCESS = 0.1
--- Variance of a new path's tilt rate, (rad/s)².
M.RATE = 0.25
--- Weight of a new path starting at a candidate, relative to the hypotheses' total.
M.BIRTH = 3e-4
--- Places kept for the best hypotheses of each candidate, however unlikely (so that the
-- path of the branch not chosen is never lost, and a track started on the wrong branch
-- leaves it as soon as the frames say so).
M.RESERVE = 2
--- Children closer than this many standard deviations (and choosing the same candidate) are
-- merged.
M.MERGE = 0.5
--- Measurement model of a candidate's tilt vector (see above).
M.SHRINK = 0.35
M.SHRINK_FROM = 2
M.SHRINK_TO = 3
M.SPREAD = 0.7
M.SPREAD_TAIL = 1.3
--- Standard deviation of each part of a candidate's tilt vector squared (as a complex number),
-- over σ/w (σ the corner noise, w the tag's side, both in pixels; see the module's header):
-- measured 2.6, taken a little wider for what the constant-rate model does not foresee.
M.SQUARE_NOISE = 3.0
--- Weight of the reprojection evidence (see above).
M.EVIDENCE_FROM = 1
M.EVIDENCE_TO = 3
M.EVIDENCE_MAX = 0.9
--- The running estimate of the corner noise: the weight of the estimate so far lost at each
-- frame, its degrees of freedom and σ (px) before any frame (`tagpose.uncertainty`'s single-frame
-- default, `DEFAULT_DOF` and `DEFAULT_SIGMA`), its floor (px²).
M.NOISE_MEMORY = 0.1
M.NOISE_DOF = 8
M.NOISE_SIGMA = 0.5
M.NOISE_FLOOR = 1e-4
-- The calibration of the confidence (`M.CONFIDENCE`): pairs (posterior log-odds, confidence
-- log-odds) of a piecewise-linear increasing map, fitted to the reliability of the posterior
-- on synthetic sequences (see the module's header): `bench/fit_confidence.lua` on
-- `bench/make_sequences.lua` seeds 2101-2116 (the dev set's seven kinds).
M.CONFIDENCE = { 0, 0, 6, 5.4, 11, 8.42, 14, 9, 40, 9 }
--- Slope of the confidence's calibration beyond its last pair.
M.CONFIDENCE_TAIL = 0.05
--- Bounds on the time between frames (s).
M.MIN_STEP = 1e-3
M.MAX_STEP = 60
--- Numbers per hypothesis in a state's `hypotheses` (τx, τy, their rates, the position
-- variance, the position-rate covariance, the rate variance, the log-weight, the candidate
-- it chose).
M.STRIDE = 9

local STATE = { __name = "tagpose.track state" } -- the metatable that marks a state
M.STATE = STATE

--- A new, empty state record (no hypotheses: the next `step` starts the track).
-- @treturn table
function M.new_state()
  return setmetatable({ time = 0, sigma2 = 0, dof = 0, first = 1, back_first = 0.5,
    back_second = 0.5, count = 0, hypotheses = {} }, STATE)
end

--- Tilt vector of a pose: the tag normal's components across the line of sight.
-- @tparam number w quaternion of the rotation (tag → camera)
-- @tparam number x
-- @tparam number y
-- @tparam number z
-- @tparam number tx the tag centre in the camera frame (tz > 0)
-- @tparam number ty
-- @tparam number tz
-- @treturn number τx
-- @treturn number τy
function M.tilt(w, x, y, z, tx, ty, tz)
  -- third column of the rotation: the tag's normal in the camera frame
  local nx, ny, nz = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
  local d = sqrt(tx * tx + ty * ty + tz * tz)
  if not (d > 0) then return nx, ny end
  local lx, ly, lz = tx / d, ty / d, tz / d
  if lz < -0.999 then lz = -0.999 end
  local k = 1 / (1 + lz)
  return nx * (1 - lx * lx * k) - ny * lx * ly * k - nz * lx,
    -nx * lx * ly * k + ny * (1 - ly * ly * k) - nz * ly
end

--- The measurement model: the shrink factor g and the per-axis variance r² of a candidate's
-- tilt vector of magnitude m, for a tag of side `size` px and corner noise variance s2; and
-- the normalised tilt x (see the module's header).
-- @tparam number m |τ|
-- @tparam number size the tag's side in pixels
-- @tparam number s2 σ² (px²)
-- @treturn number g
-- @treturn number r²
-- @treturn number x
function M.measurement(m, size, s2)
  local scale = sqrt(sqrt(s2) / size)
  local x = m / scale
  local g
  if x <= M.SHRINK_FROM then
    g = M.SHRINK
  elseif x >= M.SHRINK_TO then
    g = 1
  else
    g = M.SHRINK + (1 - M.SHRINK) * (x - M.SHRINK_FROM) / (M.SHRINK_TO - M.SHRINK_FROM)
  end
  local r = M.SPREAD_TAIL / x
  if not (r < M.SPREAD) then r = M.SPREAD end
  r = r * scale
  return g, r * r, x
end

--- The default evidence of one frame for its first candidate against its second, with the
-- corner noise known only as an estimate `s2` of `dof` degrees of freedom (σ² integrated out:
-- the frame's residuals, two degrees of freedom each, against a scaled inverse-χ² belief):
-- `κ(x)·(dof + 2)/2·log((dof·s2 + sse2)/(dof·s2 + sse1))`, which tends to
-- `κ(x)·(sse2 − sse1)/(2·s2)` as dof grows (the form taken without dof: σ² known).
-- @tparam number sse1 first candidate's sum of squared residuals (px²)
-- @tparam number sse2 second candidate's
-- @tparam number s2 corner noise variance (px²), > 0
-- @tparam number x the first candidate's tilt over `√(σ/w)` (see the module's header)
-- @tparam[opt] number dof the degrees of freedom of s2, > 0 (nil: s2 is σ² itself)
-- @treturn number log-likelihood ratio
function M.evidence(sse1, sse2, s2, x, dof)
  local k
  if x <= M.EVIDENCE_FROM then
    return 0
  elseif x >= M.EVIDENCE_TO then
    k = M.EVIDENCE_MAX
  else
    k = M.EVIDENCE_MAX * (x - M.EVIDENCE_FROM) / (M.EVIDENCE_TO - M.EVIDENCE_FROM)
  end
  if not dof then return k * (sse2 - sse1) / (2 * s2) end
  local scale = dof * s2
  return k * 0.5 * (dof + 2) * log((scale + sse2) / (scale + sse1))
end

--- The running noise estimate after a frame: the chosen candidate's residuals (two degrees of
-- freedom) pooled with the estimate before it (`s2` of `dof` degrees of freedom, their weight
-- decayed by `NOISE_MEMORY`), or with `NOISE_DOF` degrees of freedom at `NOISE_SIGMA` when there
-- is none (dof 0: then σ² is `tagpose.uncertainty`'s single-frame default).
-- @tparam number s2 the estimate (px²)
-- @tparam number dof its degrees of freedom (0: none)
-- @tparam number sse the chosen candidate's sum of squared residuals (px²)
-- @treturn number σ² (px²)
-- @treturn number its degrees of freedom
function M.noise(s2, dof, sse)
  local sum, d
  if dof > 0 and s2 > 0 then
    local keep = 1 - M.NOISE_MEMORY
    d = keep * dof
    sum, d = d * s2 + sse, d + 2
  else
    local sigma = M.NOISE_SIGMA
    sum, d = M.NOISE_DOF * sigma * sigma + sse, M.NOISE_DOF + 2
  end
  local v = sum / d
  if not (v >= M.NOISE_FLOOR) then v = M.NOISE_FLOOR end
  return v, d
end

--- The mean of σ² given a running estimate `s2` of `dof` degrees of freedom (a scaled
-- inverse-χ² belief): `s2·dof/(dof − 2)`, the σ² whose covariance `σ² H⁻¹` is the pose's own
-- when σ is not known (the estimate itself is the belief's scale, a little smaller).
-- @tparam number s2 the estimate (px²)
-- @tparam number dof its degrees of freedom (> 2)
-- @treturn number σ² (px²)
function M.noise_mean(s2, dof)
  return s2 * dof / (dof - 2)
end

local function logistic(l)
  return 1 / (1 + exp(-l))
end

--- Calibrated confidence of a posterior probability.
-- @tparam number p posterior probability of the chosen candidate (>= 0.5)
-- @treturn number confidence in [0.5, 1]
function M.confidence(p)
  if not (p > 0.5) then return 0.5 end
  local l = p < 1 and log(p / (1 - p)) or 745
  local k = M.CONFIDENCE
  for i = 3, #k, 2 do
    if l <= k[i] then
      return logistic(k[i - 1] + (k[i + 1] - k[i - 1]) * (l - k[i - 2]) / (k[i] - k[i - 2]))
    end
  end
  return logistic(k[#k] + M.CONFIDENCE_TAIL * (l - k[#k - 1]))
end

--- The time step of a frame after a state, and the corner noise known before it.
-- @tparam ?table prev the previous state, or nil
-- @tparam ?number time this frame's time (s), or nil: `FRAME` after the previous
-- @treturn number dt, clamped to [`MIN_STEP`, `MAX_STEP`]
-- @treturn number the frame's time
-- @treturn number σ² (px²): the state's estimate, or `NOISE_SIGMA`² when it has none
-- @treturn number its degrees of freedom: the state's, or `NOISE_DOF`
-- @treturn number the state's own degrees of freedom (0 when it has no estimate)
function M.step_and_noise(prev, time)
  local s2, dof, t0 = 0, 0, nil
  if prev then s2, dof, t0 = prev.sigma2, prev.dof, prev.time end
  local dt
  if time == nil then
    dt = M.FRAME
    time = (t0 or 0) + dt
  else
    dt = t0 and time - t0 or M.FRAME
  end
  if not (dt >= M.MIN_STEP) then dt = M.MIN_STEP elseif dt > M.MAX_STEP then dt = M.MAX_STEP end
  if dof > 0 and s2 > 0 then return dt, time, s2, dof, dof end
  local sigma = M.NOISE_SIGMA
  return dt, time, sigma * sigma, M.NOISE_DOF, 0
end

local filter = require("tagpose.track.filter")

--- One frame of the filter: which candidate is the pose, given the track so far.
-- @tparam ?table prev the previous state, or nil (or a state without hypotheses) to start a
--   track: from that state's noise estimate (`sigma2`, `dof`) when it has one
-- @tparam table a the frame's first candidate (the better fit; see the module's header)
-- @tparam ?table b its second candidate, or nil when there is one minimum
-- @tparam number size the tag's side in pixels
-- @tparam ?number time the frame's time (s); nil: `FRAME` after the previous state's
-- @tparam table out the state to fill (may be `prev`)
-- @tparam[opt] number llr the frame's own evidence for a against b, replacing `evidence`
-- @treturn int 1 or 2: the candidate to return
-- @treturn number its posterior probability (through `confidence` for a calibrated one);
--   `out.first` is the first candidate's, and for smoothing `out.back_first` is
--   P(the previous frame's first candidate was true | this frame's first is), given the frames
--   so far (0.5 when there was no previous frame), `out.back_second` the same given that this
--   frame's second candidate is true
function M.step(prev, a, b, size, time, out, llr)
  return filter.step(M, prev, a, b, size, time, out, llr)
end

--- Is this a state of this filter (a record this module made, with a consistent header)?
-- @tparam any t
-- @treturn boolean
function M.is_state(t)
  if type(t) ~= "table" or getmetatable(t) ~= STATE then return false end
  local n, h = t.count, t.hypotheses
  if type(n) ~= "number" or n < 0 or n > M.HYPOTHESES or n ~= math.floor(n)
    or type(h) ~= "table" or h[n * M.STRIDE + 1] ~= nil or (n > 0 and h[n * M.STRIDE] == nil) then
    return false
  end
  local s2, dof, p = t.sigma2, t.dof, t.first
  return is_finite(t.time) and is_finite(s2) and s2 >= 0 and is_finite(dof) and dof >= 0
    and type(p) == "number" and p >= 0 and p <= 1
end

--- A copy of a state (into `out`, or a new record).
-- @tparam table s a state
-- @tparam[opt] table out the record to fill
-- @treturn table the copy
function M.copy(s, out)
  out = out or M.new_state()
  out.time, out.sigma2, out.dof, out.first, out.back_first, out.back_second, out.count = s.time,
    s.sigma2, s.dof, s.first, s.back_first, s.back_second, s.count
  local h, o = s.hypotheses, out.hypotheses
  local n = s.count * M.STRIDE
  for i = 1, n do o[i] = h[i] end
  for i = n + 1, #o do o[i] = nil end
  return out
end

--- A state from a pose of the caller's own (no state): both it and its alternative (or its
-- mirror) as paths at rest, equally likely unless `opts.first` says otherwise, with the noise
-- unknown unless `opts.sigma2` gives it.
-- @tparam table out the state to fill
-- @tparam {number,...} q quaternion `{w, x, y, z}` of the pose
-- @tparam ?{number,...} t its position `{x, y, z}` (nil: on the optical axis)
-- @tparam ?{number,...} q2 quaternion of its alternative (nil: its mirror)
-- @tparam ?{number,...} t2 position of the alternative
-- @tparam[opt] table opts `first`: the probability that the pose (not its alternative) is on
--   the true branch, in (0, 1); `variance`: each path's tilt variance (default 0.01);
--   `sigma2`: the corner noise variance (px²) to start the running estimate with
-- @treturn table out
function M.from_pose(out, q, t, q2, t2, opts)
  t = t or { 0, 0, 1 }
  local ax, ay = M.tilt(q[1], q[2], q[3], q[4], t[1], t[2], t[3])
  local bx, by = -ax, -ay
  if q2 then
    t2 = t2 or t
    bx, by = M.tilt(q2[1], q2[2], q2[3], q2[4], t2[1], t2[2], t2[3])
  end
  local first = opts and opts.first
  local lw1, lw2 = 0, 0
  if first then lw1, lw2 = log(first), log(1 - first) end
  local v = opts and opts.variance or 0.01
  local s2 = opts and opts.sigma2 or 0
  out.time, out.sigma2, out.dof, out.first, out.back_first, out.back_second, out.count = 0, s2,
    s2 > 0 and M.NOISE_DOF or 0, first or 0.5, 0.5, 0.5, 2
  local h = out.hypotheses
  h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9] = ax, ay, 0, 0, v, 0, M.RATE, lw1, 1
  h[10], h[11], h[12], h[13], h[14], h[15], h[16], h[17], h[18] = bx, by, 0, 0, v, 0,
    M.RATE, lw2, 2
  for i = 19, #h do h[i] = nil end
  return out
end

local flat = {} -- scratch: a prior's rotation, flat
local prior_q, prior_alt = {}, {} -- scratch quaternions of a prior and its alternative
local prior_t, prior_alt_t = {}, {} -- and their positions
local made = M.new_state() -- scratch: the state made from a prior without one

-- The quaternion of a pose table (its rotation or quaternion field) into out[1..4], or nil.
local function pose_quaternion(p, out)
  local r = rotation.of_pose(p, flat)
  if not r then return nil end
  out[1], out[2], out[3], out[4] = rotation.to_quaternion(r)
  return out
end

-- The position {x, y, z} of a pose table into out[1..3] (in front of the camera), or nil.
local function pose_position(p, out)
  local pt = type(p) == "table" and p.position
  if type(pt) == "table" and is_finite(pt.x) and is_finite(pt.y) and is_finite(pt.z)
    and pt.z > 0 then
    out[1], out[2], out[3] = pt.x, pt.y, pt.z
    return out
  end
  return nil
end

--- The track state a prior pose carries (its `track`: a solve's result has one, made when
-- first read if the solve had no prior), or one made from its pose and its alternative's
-- (`from_pose`; the noise is then taken from the next frame).
-- @tparam table prior a pose table (a `tagpose.solve` result, or the user's own)
-- @treturn table the state (the prior's own, or a scratch record valid until the next call)
-- @return nil when the prior has no usable state, quaternion or rotation
function M.from_prior(prior)
  local t = prior.track
  if M.is_state(t) then return t end
  local q = pose_quaternion(prior, prior_q)
  if not q then return nil end
  local alt = prior.alternative
  local qa = pose_quaternion(alt, prior_alt)
  return M.from_pose(made, q, pose_position(prior, prior_t), qa,
    qa and pose_position(alt, prior_alt_t))
end

return M
