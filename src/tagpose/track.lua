--- Tracking: choosing between the two poses of the planar ambiguity with the help of the
-- previous frame.
--
-- A square seen from afar or nearly face-on has two poses that reproject almost alike, and
-- noise decides which one has the smaller error: choosing by the error alone flips between
-- them from frame to frame. Choosing "the one closest to the previous frame" is no better: it
-- locks onto whichever branch the first frame took, right or wrong.
--
-- The rule here is a two-hypothesis filter. A track carries, from frame to frame:
--
-- * a reference rotation for each branch (the branch of the pose returned last frame, and the
--   other), each an exponentially smoothed quaternion (`ALPHA`), so the noise of single frames
--   does not decide which new candidate continues which branch;
-- * the log-odds `L` that the returned branch is the right one;
-- * an estimate of the corner noise, `σ²`, from the running mean of the best candidate's sum
--   of squared residuals (`SSE / 2`, its expectation for two residual degrees of freedom).
--
-- Each frame: the two candidates are matched to the two references (least total rotation
-- distance); `L` passes through a two-state Markov transition that forgets old evidence at
-- `SWITCH` per frame, and completely when the two references meet (`CROSSING`: the branches
-- cross when the tag passes face-on, and which is which is then unknown); then each candidate's
-- reprojection adds its evidence, `KAPPA · (SSE_other − SSE) / (2σ²)`; the branch with
-- `L ≥ 0` is returned. Because the carried log-odds never exceed `ln((1 − SWITCH) / SWITCH)`,
-- the prior never keeps a candidate whose SSE exceeds the other's by more than
-- `2σ² · ln((1 − SWITCH) / SWITCH) / KAPPA` (about `23 σ²`): a clearly worse fit always loses.
-- And because evidence keeps accumulating, a track that started on the wrong branch moves to
-- the right one as soon as the frames say so.
--
-- The state is a flat array of ten numbers, stored as `pose.track`:
-- `{aw, ax, ay, az, bw, bx, by, bz, L, σ²}` (a: the returned pose's branch, b: the other).
-- @module tagpose.track

local compat = require("tagpose.compat")
local rotation = require("tagpose.rotation")

local sqrt, exp, log, acos, min, max = math.sqrt, math.exp, math.log, math.acos, math.min,
  math.max
local is_finite = compat.is_finite

local M = {}

--- Smoothing factor of the branch references (weight of the new frame).
M.ALPHA = 0.3
--- Weight of one frame's reprojection evidence (less than 1: the two minima are not the
-- true pose, so the Gaussian likelihood ratio overstates the evidence).
M.KAPPA = 0.5
--- Per-frame probability that the branches exchange identity, away from crossings.
M.SWITCH = 0.003
--- Angle (radians) of the branch references below which their identity is lost: the
-- switching probability is `max(SWITCH, exp(-(θ / CROSSING)²) / 2)`.
M.CROSSING = 12 * math.pi / 180
--- Weight of a new frame in the running noise estimate.
M.NOISE_MEMORY = 0.1
--- Floor of the noise variance estimate (px²).
M.NOISE_FLOOR = 1e-4

-- unit quaternion (1 - a) p + a q, q's sign aligned to p's
local function blend(pw, px, py, pz, qw, qx, qy, qz, a)
  if pw * qw + px * qx + py * qy + pz * qz < 0 then a = -a end
  local b = 1 - (a < 0 and -a or a)
  local w, x, y, z = b * pw + a * qw, b * px + a * qx, b * py + a * qy, b * pz + a * qz
  local n = sqrt(w * w + x * x + y * y + z * z)
  return w / n, x / n, y / n, z / n
end

local function closeness(aw, ax, ay, az, bw, bx, by, bz)
  local d = aw * bw + ax * bx + ay * by + az * bz
  return d < 0 and -d or d
end

--- Start a track from one frame's candidates.
-- @tparam {number,...} out the state to fill
-- @tparam {number,...} q1 quaternion `{w, x, y, z}` of the returned candidate
-- @tparam number sse1 its sum of squared residuals (px²)
-- @tparam[opt] {number,...} q2 the other candidate's quaternion
-- @tparam[opt] number sse2 its sum of squared residuals
-- @treturn {number,...} out
function M.start(out, q1, sse1, q2, sse2)
  local s2 = max(sse1 / 2, M.NOISE_FLOOR)
  out[1], out[2], out[3], out[4] = q1[1], q1[2], q1[3], q1[4]
  if q2 then
    out[5], out[6], out[7], out[8] = q2[1], q2[2], q2[3], q2[4]
    out[9] = M.KAPPA * (sse2 - sse1) / (2 * s2)
  else
    out[5], out[6], out[7], out[8] = q1[1], q1[2], q1[3], q1[4]
    out[9] = 0
  end
  out[10] = s2
  return out
end

local flat = {} -- scratch: a prior's rotation, flat
local made = {} -- scratch: the state made from a prior without one

-- The quaternion of a pose table (its quaternion or rotation field) into out[1..4], or nil.
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
    rotation.from_nested(rt, flat)
    for i = 1, 9 do
      if not is_finite(flat[i]) then return nil end
    end
    out[1], out[2], out[3], out[4] = rotation.to_quaternion(flat)
    return out
  end
  return nil
end

local prior_q, prior_alt = {}, {} -- scratch quaternions of a prior and its alternative

--- The track state a prior pose carries (its `track`), or one made from its pose and its
-- alternative's (whose noise is then taken from the next frame).
-- @tparam table prior a pose table (a `tagpose.solve` result, or the user's own)
-- @treturn {number,...} the state (the prior's own `track`, or a scratch array valid until the
--   next call)
-- @return nil when the prior has no usable state, quaternion or rotation
function M.from_prior(prior)
  local t = prior.track
  if type(t) == "table" then
    local ok = true
    for i = 1, 10 do
      if not is_finite(t[i]) then ok = false end
    end
    if ok and t[10] > 0 then return t end
  end
  local q = pose_quaternion(prior, prior_q)
  if not q then return nil end
  local alt = pose_quaternion(prior.alternative, prior_alt) or q
  for i = 1, 4 do
    made[i], made[4 + i] = q[i], alt[i]
  end
  made[9], made[10] = 0, nil
  return made
end

--- Choose between this frame's candidates given the previous frame's track state.
-- @tparam {number,...} prev the previous state (ten numbers)
-- @tparam {number,...} q1 quaternion of the candidate with the smaller error
-- @tparam number sse1 its sum of squared residuals (px²)
-- @tparam[opt] {number,...} q2 the other candidate's quaternion (nil when there is one
--   candidate)
-- @tparam[opt] number sse2 its sum of squared residuals
-- @tparam {number,...} out the new state to fill (may be `prev`)
-- @treturn int 1 or 2: the candidate to return
function M.choose(prev, q1, sse1, q2, sse2, out)
  local aw, ax, ay, az = prev[1], prev[2], prev[3], prev[4]
  local bw, bx, by, bz = prev[5], prev[6], prev[7], prev[8]
  local L, s2 = prev[9], prev[10]
  -- a state made from a pose (`from_prior`) takes its noise from this frame
  if s2 == nil then s2 = max(0.5 * sse1, M.NOISE_FLOOR) end
  if not q2 then q2, sse2 = q1, sse1 end
  -- which candidate continues branch a
  local c1a = closeness(q1[1], q1[2], q1[3], q1[4], aw, ax, ay, az)
  local c1b = closeness(q1[1], q1[2], q1[3], q1[4], bw, bx, by, bz)
  local c2a = closeness(q2[1], q2[2], q2[3], q2[4], aw, ax, ay, az)
  local c2b = closeness(q2[1], q2[2], q2[3], q2[4], bw, bx, by, bz)
  local qa, sa, qb, sb = q1, sse1, q2, sse2
  local ia = 1
  if c2a + c1b > c1a + c2b then qa, sa, qb, sb, ia = q2, sse2, q1, sse1, 2 end
  -- transition: forget at SWITCH per frame, and all at a crossing of the references
  local theta = 2 * acos(min(1, closeness(aw, ax, ay, az, bw, bx, by, bz)))
  local e = max(M.SWITCH, 0.5 * exp(-(theta / M.CROSSING) ^ 2))
  if L > 50 then L = 50 elseif L < -50 then L = -50 end
  local eL = exp(L)
  L = log(((1 - e) * eL + e) / (e * eL + (1 - e)))
  -- evidence of this frame
  s2 = max((1 - M.NOISE_MEMORY) * s2 + M.NOISE_MEMORY * 0.5 * min(sse1, sse2), M.NOISE_FLOOR)
  L = L + M.KAPPA * (sb - sa) / (2 * s2)
  aw, ax, ay, az = blend(aw, ax, ay, az, qa[1], qa[2], qa[3], qa[4], M.ALPHA)
  bw, bx, by, bz = blend(bw, bx, by, bz, qb[1], qb[2], qb[3], qb[4], M.ALPHA)
  if L >= 0 then
    out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8] = aw, ax, ay, az, bw, bx, by, bz
    out[9], out[10] = L, s2
    return ia
  end
  out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8] = bw, bx, by, bz, aw, ax, ay, az
  out[9], out[10] = -L, s2
  return 3 - ia
end

return M
