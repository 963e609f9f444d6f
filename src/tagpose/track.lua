--- Tracking: choosing between the two poses of the planar ambiguity with the help of the
-- earlier frames, by a multi-hypothesis filter with a motion model.
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
-- its weight gains the motion likelihood of that candidate and the frame's evidence for it
-- (below). A new path may also start at either candidate with a small weight (`BIRTH`), so
-- a hypothesis set that lost the truth recovers. Children that coincide are merged, the best
-- `HYPOTHESES` kept. The probability that a candidate is the true pose is the weight of the
-- hypotheses that chose it.
--
-- **The measurement.** A candidate's `τ` near face-on is biased away from zero (its size is
-- set by the noise: about `√(σ/w)`, σ the corner noise, w the tag's side in pixels) and its
-- direction is poorly known; so the filter takes `g·τ` with variance `r²` (per axis), where
-- with `x = |τ| / √(σ/w)`: `g = SHRINK` for `x ≤ SHRINK_FROM`, rising linearly to 1 at
-- `SHRINK_TO`, and `r = min(SPREAD, SPREAD_TAIL / x)·√(σ/w)`. These were measured on
-- synthetic sequences (bench/make_sequences.lua).
--
-- **The evidence** of one frame is a log-likelihood ratio between the two candidates,
-- `log P(corners | first) − log P(corners | second)`. It is `frame.llr` when the caller
-- supplies one (for example from a single-frame uncertainty model), otherwise `M.evidence`:
-- `κ(x)·(SSE₂ − SSE₁)/(2σ²)`, where the weight `κ` rises from 0 at `x = EVIDENCE_FROM` to
-- `EVIDENCE_MAX` at `EVIDENCE_TO` (near face-on the error difference says nothing about the
-- branch). σ² is `frame.sigma2` when given, else estimated online from the best candidate's
-- SSE (`SSE/2` for its two residual degrees of freedom, weight `NOISE_MEMORY` per frame).
--
-- **The confidence** returned is the filter's posterior probability of the chosen candidate,
-- calibrated by an increasing map of its log-odds (`CONFIDENCE`), fitted on the synthetic
-- sequences with the evidence above (a different evidence function needs its own): the
-- posterior is overconfident (its log-odds are about twice what the frames bear out), and
-- beyond 99.9 % a wrong branch is rare but not rarer.
--
-- The state is a flat array of numbers (`pose.track`): `STATE_TAG`, the number of
-- hypotheses `n`, σ² (0 while unknown), the time of its frame, the posterior probability of
-- that frame's first candidate, the two smoothing numbers `choose` returns (below), then per
-- hypothesis nine numbers: `τx, τy`, their rates, the position variance, the position-rate
-- covariance, the rate variance (per axis), the log-weight, and the candidate it chose (1 or
-- 2, in that frame's order).
-- @module tagpose.track

local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")

local sqrt, exp, log, min = math.sqrt, math.exp, math.log, math.min
local is_finite = compat.is_finite

local M = {}

--- First number of a state of this filter (a state from another version is not one).
M.STATE_TAG = 20240601
--- Numbers per hypothesis in the state.
M.STRIDE = 9
--- Header numbers before the hypotheses.
M.HEADER = 7
--- Nominal time between frames (s), when no time is given.
M.FRAME = 1 / 30
--- Most hypotheses kept.
M.HYPOTHESES = 16
--- Density of the white angular acceleration of the tilt vector, rad²/s³.
M.PROCESS = 0.03
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
--- Weight of the reprojection evidence (see above).
M.EVIDENCE_FROM = 1
M.EVIDENCE_TO = 3
M.EVIDENCE_MAX = 0.9
--- Weight of a new frame in the running noise estimate.
M.NOISE_MEMORY = 0.1
--- Floor of the noise variance estimate (px²).
M.NOISE_FLOOR = 1e-4
-- The calibration of the confidence (`M.CONFIDENCE`): pairs (posterior log-odds, confidence
-- log-odds) of a piecewise-linear increasing map, fitted to the reliability of the posterior
-- on synthetic sequences (see the module's header).
M.CONFIDENCE = { 0, 0, 6, 2.75, 11, 2.9, 14, 7.5, 40, 9 }
--- Slope of the confidence's calibration beyond its last pair.
M.CONFIDENCE_TAIL = 0.05
--- Bounds on the time between frames (s).
M.MIN_STEP = 1e-3
M.MAX_STEP = 60

local STRIDE, HEADER = M.STRIDE, M.HEADER
local LOG_DISK = log(1 / math.pi) -- log density of a tilt vector uniform over the unit disk
local TWO_PI = 2 * math.pi

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

-- the measurement model: shrink factor g and per-axis variance of a candidate's tilt vector of
-- magnitude m, for a tag of side `size` px and noise variance s2; and the normalised size x
local function measurement(m, size, s2)
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

--- The default evidence of one frame for its first candidate against its second:
-- `κ(x)·(sse2 − sse1)/(2·s2)`.
-- @tparam number sse1 first candidate's sum of squared residuals (px²)
-- @tparam number sse2 second candidate's
-- @tparam number s2 corner noise variance (px²)
-- @tparam number x the first candidate's tilt over `√(σ/w)` (see the module's header)
-- @treturn number log-likelihood ratio
function M.evidence(sse1, sse2, s2, x)
  local k
  if x <= M.EVIDENCE_FROM then
    return 0
  elseif x >= M.EVIDENCE_TO then
    k = M.EVIDENCE_MAX
  else
    k = M.EVIDENCE_MAX * (x - M.EVIDENCE_FROM) / (M.EVIDENCE_TO - M.EVIDENCE_FROM)
  end
  return k * (sse2 - sse1) / (2 * s2)
end

-- scratch for the children of one frame, as parallel arrays
local cx, cy, cvx, cvy, cpp, cpv, cvv, clw, cw, cpick, cfrom, order = {}, {}, {}, {}, {}, {},
  {}, {}, {}, {}, {}, {}
local kept, kept1, kept2, used = {}, {}, {}, {}

-- child i: the hypothesis (x, y, vx, vy predicted with covariance pp, pv, vv) takes the
-- measurement (mx, my), innovation variance s (its log-density's constant `norm`)
local function add_child(i, x, y, vx, vy, pp, pv, vv, lw, mx, my, s, norm, pick, from)
  local dx, dy = mx - x, my - y
  local k1, k2 = pp / s, pv / s
  cx[i], cy[i] = x + k1 * dx, y + k1 * dy
  cvx[i], cvy[i] = vx + k2 * dx, vy + k2 * dy
  cpp[i], cpv[i], cvv[i] = pp - k1 * pp, pv - k1 * pv, vv - k2 * pv
  clw[i] = lw - (dx * dx + dy * dy) / (2 * s) - norm
  cpick[i], cfrom[i] = pick, from
end

-- child i: a new path at the measurement (mx, my) of variance r2, at rest
local function add_birth(i, lw, mx, my, r2, pick)
  cx[i], cy[i], cvx[i], cvy[i] = mx, my, 0, 0
  cpp[i], cpv[i], cvv[i] = r2, 0, M.RATE
  clw[i], cpick[i], cfrom[i] = lw, pick, 0
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

-- The time step and the corner noise of a frame after a state: dt, time, the noise variance
-- for this frame, and the variance to carry on.
local function step_and_noise(prev, frame, sse1, sse2)
  local s2, t0 = 0, nil
  if prev then s2, t0 = prev[3], prev[4] end
  local time = frame.time
  local dt
  if time == nil then
    dt = M.FRAME
    time = (t0 or 0) + dt
  else
    dt = t0 and time - t0 or M.FRAME
  end
  if not (dt >= M.MIN_STEP) then dt = M.MIN_STEP elseif dt > M.MAX_STEP then dt = M.MAX_STEP end
  local known = frame.sigma2
  if known then return dt, time, known, known end
  local new = 0.5 * min(sse1, sse2)
  local carried = s2 > 0 and (1 - M.NOISE_MEMORY) * s2 + M.NOISE_MEMORY * new or new
  if not (carried >= M.NOISE_FLOOR) then carried = M.NOISE_FLOOR end
  return dt, time, carried, carried
end

-- A track's first frame: a path at each candidate, weighted by the evidence (what `choose`
-- does with no hypotheses, without its loops).
local function start(out, time, s2, ax, ay, bx, by, r2, has2, ev)
  -- log-weights of the two paths, summing to one in probability (ev is within ±700)
  local a = ev >= 0 and -ev or ev
  local lw_better = -log(1 + exp(a))
  local lw1, lw2 = lw_better, a + lw_better
  if ev < 0 then lw1, lw2 = lw2, lw1 end
  local p1 = has2 and exp(lw1) or 1
  if not has2 then lw1 = 0 end
  out[1], out[2], out[3], out[4], out[5], out[6], out[7] = M.STATE_TAG, has2 and 2 or 1, s2,
    time, p1, 0.5, 0.5
  local o = HEADER
  out[o + 1], out[o + 2], out[o + 3], out[o + 4] = ax, ay, 0, 0
  out[o + 5], out[o + 6], out[o + 7], out[o + 8], out[o + 9] = r2, 0, M.RATE, lw1, 1
  local n = 1
  if has2 then
    o = HEADER + STRIDE
    out[o + 1], out[o + 2], out[o + 3], out[o + 4] = bx, by, 0, 0
    out[o + 5], out[o + 6], out[o + 7], out[o + 8], out[o + 9] = r2, 0, M.RATE, lw2, 2
    n = 2
  end
  for i = HEADER + n * STRIDE + 1, #out do out[i] = nil end
  if p1 >= 0.5 then return 1, p1, 0.5, 0.5 end
  return 2, 1 - p1, 0.5, 0.5
end

--- One frame of the filter.
-- `frame` describes the frame's candidates: `q1 = {w, x, y, z}`, `t1 = {x, y, z}`, `sse1`
-- (px²) of the first; `q2`, `t2`, `sse2` of the second, or `q2 = nil` when there is one;
-- `size`, the tag's side in pixels; optionally `time` (s), `sigma2` (the corner noise
-- variance, px², when known) and `llr` (the frame's own evidence, replacing `M.evidence`).
-- @tparam ?{number,...} prev the previous state, or nil to start a track
-- @tparam table frame this frame (above)
-- @tparam {number,...} out the new state to fill (may be `prev`)
-- @treturn int 1 or 2: the candidate to return
-- @treturn number its posterior probability
-- @treturn number for smoothing: P(the previous frame's first candidate was true | this
--   frame's first is), given the frames so far (0.5 when there was no previous frame)
-- @treturn number the same given that this frame's second candidate is true
function M.choose(prev, frame, out)
  local n = prev and prev[2] or 0
  local q1, q2, sse1 = frame.q1, frame.q2, frame.sse1
  local sse2 = q2 and frame.sse2 or sse1
  local dt, time, s2, s2_next = step_and_noise(prev, frame, sse1, sse2)
  -- the candidates' tilt vectors, shrunk, and their variance
  local t1, size = frame.t1, frame.size
  local ax, ay = M.tilt(q1[1], q1[2], q1[3], q1[4], t1[1], t1[2], t1[3])
  local bx, by = ax, ay
  if q2 then
    local t2 = frame.t2
    bx, by = M.tilt(q2[1], q2[2], q2[3], q2[4], t2[1], t2[2], t2[3])
  end
  local g, r2, xm = measurement(sqrt(ax * ax + ay * ay), size, s2)
  ax, ay, bx, by = g * ax, g * ay, g * bx, g * by
  local ev = 0
  if q2 then
    ev = frame.llr or M.evidence(sse1, sse2, s2, xm)
    if ev ~= ev then ev = 0 elseif ev > 700 then ev = 700 elseif ev < -700 then ev = -700 end
  end
  local half = 0.5 * ev
  if n == 0 then return start(out, time, s2_next, ax, ay, bx, by, r2, q2 ~= nil, ev) end
  -- children of every hypothesis: it continues with the first or the second candidate (the
  -- state's log-weights sum to one in probability)
  local k, q = 0, M.PROCESS
  local dt2, dt3 = dt * dt, dt * dt * dt
  for h = 1, n do
    local o = HEADER + (h - 1) * STRIDE
    local lw = prev[o + 8]
    local vx, vy = prev[o + 3], prev[o + 4]
    local x, y = prev[o + 1] + vx * dt, prev[o + 2] + vy * dt
    local pp0, pv0, vv0 = prev[o + 5], prev[o + 6], prev[o + 7]
    local pp = pp0 + 2 * dt * pv0 + dt2 * vv0 + q * dt3 / 3
    local pv = pv0 + dt * vv0 + q * dt2 / 2
    local vv = vv0 + q * dt
    local from = prev[o + 9]
    local s = pp + r2
    local norm = log(TWO_PI * s)
    k = k + 1
    add_child(k, x, y, vx, vy, pp, pv, vv, lw + half, ax, ay, s, norm, 1, from)
    if q2 then
      k = k + 1
      add_child(k, x, y, vx, vy, pp, pv, vv, lw - half, bx, by, s, norm, 2, from)
    end
  end
  -- a new path at either candidate, with the motion history forgotten
  local base = n > 0 and log(M.BIRTH) + LOG_DISK or 0
  k = k + 1
  add_birth(k, base + half, ax, ay, r2, 1)
  if q2 then
    k = k + 1
    add_birth(k, base - half, bx, by, r2, 2)
  end
  -- weights, and the joint probability of (previous choice, this choice) for smoothing
  local top = -math.huge
  for i = 1, k do
    if clw[i] > top then top = clw[i] end
  end
  local j11, j12, j21, j22 = 0, 0, 0, 0
  local p_prev = prev and prev[5] or 0.5
  for i = 1, k do
    local w = exp(clw[i] - top)
    cw[i] = w
    local from = cfrom[i]
    if from == 0 then
      -- a new path: its previous choice as the previous frame believed
      if cpick[i] == 1 then
        j11, j21 = j11 + w * p_prev, j21 + w * (1 - p_prev)
      else
        j12, j22 = j12 + w * p_prev, j22 + w * (1 - p_prev)
      end
    elseif from == 1 then
      if cpick[i] == 1 then j11 = j11 + w else j12 = j12 + w end
    elseif cpick[i] == 1 then
      j21 = j21 + w
    else
      j22 = j22 + w
    end
  end
  local a, b = 0.5, 0.5
  if n > 0 then
    if j11 + j21 > 0 then a = j11 / (j11 + j21) end
    if j12 + j22 > 0 then b = j12 / (j12 + j22) end
  end
  -- the best children, by weight (insertion sort of at most 2·HYPOTHESES + 2)
  for i = 1, k do
    local w, j = cw[i], i - 1
    while j >= 1 and cw[order[j]] < w do
      order[j + 1] = order[j]
      j = j - 1
    end
    order[j + 1] = i
  end
  -- merge children that coincide, keep the best (of a weight that is not zero in doubles),
  -- leaving RESERVE places to the best of the candidate the others did not choose
  local m, limit = 0, M.MERGE * M.MERGE
  local count1, count2 = 0, 0
  for pass = 1, 2 do
    local room = pass == 1 and M.HYPOTHESES - M.RESERVE or M.HYPOTHESES
    for r = 1, k do
      local i = order[r]
      local pick = cpick[i]
      local fits = pass == 1 and cw[i] > 1e-300
        or pass == 2 and not used[i] and (pick == 1 and count1 or count2) < M.RESERVE
      if fits and m < room then
        used[i] = true
        local merged = false
        local x, y, vx, vy = cx[i], cy[i], cvx[i], cvy[i]
        local same = pick == 1 and kept1 or kept2
        for u = 1, pick == 1 and count1 or count2 do
          local j = same[u]
          local dx, dy = cx[j] - x, cy[j] - y
          local dvx, dvy = cvx[j] - vx, cvy[j] - vy
          if dx * dx + dy * dy + 0.01 * (dvx * dvx + dvy * dvy) < limit * (cpp[j] + r2) then
            cw[j] = cw[j] + cw[i]
            merged = true
            break
          end
        end
        if not merged then
          m = m + 1
          kept[m] = i
          if pick == 1 then
            count1 = count1 + 1
            kept1[count1] = i
          else
            count2 = count2 + 1
            kept2[count2] = i
          end
          if not (cw[i] > 1e-300) then cw[i] = 1e-300 end
        end
      end
    end
  end
  for i = 1, k do used[i] = nil end
  -- the new state
  local total, first = 0, 0
  for u = 1, m do
    local w = cw[kept[u]]
    total = total + w
    if cpick[kept[u]] == 1 then first = first + w end
  end
  local p1 = first / total
  out[1], out[2], out[3], out[4], out[5], out[6], out[7] = M.STATE_TAG, m, s2_next, time, p1, a, b
  for u = 1, m do
    local i, o = kept[u], HEADER + (u - 1) * STRIDE
    out[o + 1], out[o + 2], out[o + 3], out[o + 4] = cx[i], cy[i], cvx[i], cvy[i]
    out[o + 5], out[o + 6], out[o + 7] = cpp[i], cpv[i], cvv[i]
    out[o + 8], out[o + 9] = log(cw[i] / total), cpick[i]
  end
  for i = HEADER + m * STRIDE + 1, #out do out[i] = nil end
  if p1 >= 0.5 then return 1, p1, a, b end
  return 2, 1 - p1, a, b
end

--- Is this a state of this filter (finite numbers in the layout above)?
-- @tparam any t
-- @treturn boolean
function M.is_state(t)
  if type(t) ~= "table" or t[1] ~= M.STATE_TAG then return false end
  local n = t[2]
  if type(n) ~= "number" or n < 1 or n > M.HYPOTHESES or n ~= math.floor(n) then return false end
  if #t ~= HEADER + n * STRIDE then return false end
  for i = 3, #t do
    local v = t[i]
    if type(v) ~= "number" or v ~= v or v == math.huge or v == -math.huge then return false end
  end
  for i = 5, 7 do
    if not (t[i] >= 0 and t[i] <= 1) then return false end
  end
  if not (t[3] >= 0) then return false end
  for h = 1, n do
    local o = HEADER + (h - 1) * STRIDE
    if not (t[o + 5] > 0 and t[o + 7] > 0) then return false end
    if t[o + 9] ~= 1 and t[o + 9] ~= 2 then return false end
  end
  return true
end

--- A state from a pose of the caller's own (no state): both it and its alternative (or its
-- mirror) as paths, equally likely, at rest, with the noise unknown.
-- @tparam {number,...} out the state to fill
-- @tparam {number,...} q quaternion `{w, x, y, z}` of the pose
-- @tparam ?{number,...} t its position `{x, y, z}` (nil: on the optical axis)
-- @tparam ?{number,...} q2 quaternion of its alternative (nil: its mirror)
-- @tparam ?{number,...} t2 position of the alternative
-- @treturn {number,...} out
function M.from_pose(out, q, t, q2, t2)
  t = t or { 0, 0, 1 }
  local ax, ay = M.tilt(q[1], q[2], q[3], q[4], t[1], t[2], t[3])
  local bx, by = -ax, -ay
  if q2 then
    t2 = t2 or t
    bx, by = M.tilt(q2[1], q2[2], q2[3], q2[4], t2[1], t2[2], t2[3])
  end
  out[1], out[2], out[3], out[4], out[5], out[6], out[7] = M.STATE_TAG, 2, 0, 0, 0.5, 0.5, 0.5
  local o = HEADER
  out[o + 1], out[o + 2], out[o + 3], out[o + 4] = ax, ay, 0, 0
  out[o + 5], out[o + 6], out[o + 7], out[o + 8], out[o + 9] = 0.01, 0, M.RATE, 0, 1
  o = HEADER + STRIDE
  out[o + 1], out[o + 2], out[o + 3], out[o + 4] = bx, by, 0, 0
  out[o + 5], out[o + 6], out[o + 7], out[o + 8], out[o + 9] = 0.01, 0, M.RATE, 0, 2
  for i = HEADER + 2 * STRIDE + 1, #out do out[i] = nil end
  return out
end

local flat = {} -- scratch: a prior's rotation, flat
local prior_q, prior_alt = {}, {} -- scratch quaternions of a prior and its alternative
local prior_t, prior_alt_t = {}, {} -- and their positions
local made = {} -- scratch: the state made from a prior without one

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

--- The track state a prior pose carries (its `track`), or one made from its pose and its
-- alternative's (`from_pose`; the noise is then taken from the next frame).
-- @tparam table prior a pose table (a `tagpose.solve` result, or the user's own)
-- @treturn {number,...} the state (the prior's own `track`, or a scratch array valid until the
--   next call)
-- @return nil when the prior has no usable state, quaternion or rotation
function M.from_prior(prior)
  local t = prior.track
  if M.is_state(t) then return t end
  local q = pose_quaternion(prior, prior_q)
  if not q then return nil end
  local alt = pose_quaternion(prior.alternative, prior_alt)
  return M.from_pose(made, q, pose_position(prior, prior_t), alt,
    alt and pose_position(prior.alternative, prior_alt_t))
end

return M
