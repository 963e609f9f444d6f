--- The uncertainty of a tag pose: the covariance of each candidate of the planar ambiguity and the
-- probability that it is on the true branch, from the candidates' Gauss-Newton normal equations
-- and σ (docs/uncertainty.md derives all of it and measures it).
--
-- A candidate is a record `{r =, tx =, ty =, tz =, sse =, normal =}` (`tagpose.core.pipeline`'s):
-- `r` the flat row-major rotation tag → camera, `t` the tag centre in the camera frame (tag-size
-- units), `sse` the sum of squared pixel residuals of the four corners, `normal` its normal
-- equations (H in the first 21 numbers, `tagpose.core.lsq`'s layout; pixels, no σ), and
-- optionally `qw, qx, qy, qz`, the rotation's unit quaternion. `assess` writes its uncertainty
-- into the same record: `confidence`, `k` (its chord factor) and `chord` (to the other minimum).
-- `sigma2` is σ² in px².
--
-- Covariances are nested 6×6 tables `c[i][j]`, in the order (x, y, z, rx, ry, rz): position in
-- tag-size units and a small rotation vector `r` in the camera frame, `R_true = exp([r]×) R`
-- (refine's left update). Each is σ² H⁻¹ plus, where the two candidates are the two minima of
-- the planar ambiguity, a rank-one term along the chord between them: the posterior of a branch
-- is not Gaussian along the tilt (a double well whose barrier is low when the tag is small,
-- far or nearly face-on, and whose truth lies more often towards the other minimum). How much
-- comes from the ambiguity's tilt-plane model (`tagpose.uncertainty.model`). The branch
-- probability is the two basins' posterior masses (Laplace at each minimum, a tilt prior
-- uniform in angle, the same model's correction for the barrier), its middle range held back
-- by `SPREAD`.
--
-- The branch probability (`assess`) is cheap: the factors of each H and one quadratic form
-- each. A covariance costs a full inverse and its table. This module is loaded on demand: a
-- pose's `confidence` and `covariance` are made when first read (`tagpose.result.pose`).
-- @module tagpose.uncertainty

local compat = require("tagpose.core.compat")
local rotation = require("tagpose.core.rotation")
local matrix = require("tagpose.uncertainty.matrix")
local model = require("tagpose.uncertainty.model")

local sqrt, log, exp, max, floor, huge = math.sqrt, math.log, math.exp, math.max, math.floor,
  math.huge
local atan2 = compat.atan2
local to_quaternion = rotation.to_quaternion
local factor, variance, inverse, fill = matrix.factor, matrix.variance, matrix.inverse,
  matrix.fill

local M = {}

--- σ (px) assumed when none is given: a corner detector on a robot camera (the real AprilTag
-- detector's corner error on clean renders is ~0.12 px; the real BuilderBot logs' residuals
-- give 0.15-0.28 px, `bench/corner_noise.lua`). Where a frame has too few residuals to tell,
-- the covariance is right near this σ and too wide below it (docs/uncertainty.md).
M.DEFAULT_SIGMA = 0.5
--- Weight of `DEFAULT_SIGMA` in degrees of freedom: σ² rests on `DEFAULT_DOF + 2` degrees of
-- freedom at least, the default filling in what the residuals' ν lack (`noise`); one tag's
-- frame (ν = 2) gives `σ² = (DEFAULT_DOF · DEFAULT_SIGMA² + sse) / (DEFAULT_DOF + 2)`.
M.DEFAULT_DOF = 8
--- Weight of one frame's branch log-odds L (a fractional likelihood; 1: the evidence as is).
-- Fitted by maximum likelihood on 133 000 synthetic ambiguous rows it is 0.95 ± 0.05.
M.KAPPA = 1
--- Relative error of L: the confidence is the logistic function of L averaged over an error
-- of L of standard deviation `min(SPREAD |L|, SPREAD_LIMIT)` (by the probit approximation,
-- `1 / (1 + exp(-z / sqrt(1 + π e² / 8)))`, z = KAPPA L, e = min(SPREAD |z|, SPREAD_LIMIT)).
-- It holds back the confidences of the middle range, where the model's evidence is
-- over-confident on small noisy tags (docs/uncertainty.md measures it) and a wrong branch at a
-- confidence of 0.95 or more costs a robot most.
M.SPREAD = 0.3
--- The largest standard deviation of L's error (log-odds): what the evidence approximates (the
-- barrier's correction, the tilt prior, the Laplace masses) is a few units at most, and the rows
-- decided by their residuals are right at least as often as L says. Without it the spread would
-- cap every confidence at 0.995 (on synthetic draws the rows it held at 0.99-0.995 were wrong
-- 2 times in 545 000); at 1.1 it acts from L = 3.67 on (a confidence of 0.953), so that every
-- confidence below 0.95 is as before.
M.SPREAD_LIMIT = 1.1

-- below this sine of the tilt (0.06°) a candidate is face-on: no tilt direction
local FACE_ON = 1e-3
-- log-odds beyond which one branch is decided: the tilt-plane terms (a few units at most)
-- move the confidence there by less than 1e-3, and a minimum that much better than the other
-- is a well of its own (no chord term)
local DECIDED = 40

-- scratch, written in place on every call and never handed out
local factors_a, factors_b = {}, {} -- the LDLᵀ factors of the two candidates' H
local packed = {} -- a packed H⁻¹
local product = {} -- a flat rotation
local both, logdets = {}, {} -- the two candidates' normal equations, and their ln det H

-- The tilt of a pose: the component a of the tag's normal n across the line of sight l to its
-- centre, as sin θ = |a| and a itself, with n·l and |t|.
local function tilt(n1, n2, n3, tx, ty, tz)
  local nt = sqrt(tx * tx + ty * ty + tz * tz)
  local l1, l2, l3 = tx / nt, ty / nt, tz / nt
  local nl = n1 * l1 + n2 * l2 + n3 * l3
  local a1, a2, a3 = n1 - nl * l1, n2 - nl * l2, n3 - nl * l3
  return sqrt(a1 * a1 + a2 * a2 + a3 * a3), a1, a2, a3, nl, nt
end
M.tilt = tilt

-- The separation, in its own marginal standard deviations squared, of candidate c (its
-- normal n, its tilt s, a, n·l, |t|) from the other's tilt (b) along c's tilt direction
-- p = a / s; F the factors of c's H, sigma2 σ². The tilt coordinate x = a·p moves with a pose
-- step (δω, δt) by (n × p)·δω - (n·l) p·δt / |t|, whose variance is σ² qᵀ H⁻¹ q for that q.
-- 0 when the other is not across. (Branch-free: the caller tests once, so that few values are
-- live where it branches.)
local function separation(n1, n2, n3, F, sigma2, s, a1, a2, a3, nl, nt, b1, b2, b3)
  local p1, p2, p3 = a1 / s, a2 / s, a3 / s
  local sep = s - (b1 * p1 + b2 * p2 + b3 * p3)
  local k = -nl / nt
  local var = sigma2 * variance(F, n2 * p3 - n3 * p2, n3 * p1 - n1 * p3, n1 * p2 - n2 * p1,
    k * p1, k * p2, k * p3)
  local m = max(sep, 0)
  return m * m / max(var, 1e-300)
end
M.separation = separation

-- The basins' part of the log-odds and the chord factors from the two separations (behind
-- the guard of `tilted`: on LuaJIT, a side trace from that guard with all of this in it could
-- not be compiled).
local function shapes(sa, sb, d2a, d2b, dc)
  local phi_a, va = model.lookup(d2a, dc)
  local phi_b, vb = model.lookup(d2b, -dc)
  -- the basins' shapes, and the tilt prior (uniform in angle: density ∝ 1 / sin θ)
  return phi_a - phi_b + log(sb / sa), (va - 1) / d2a, (vb - 1) / d2b
end

-- The tilt-plane part of the log-odds and the chord factors, when both candidates are off
-- face-on and across each other's tilt; else 0, 0, 0.
local function tilted(a, b, Fa, Fb, sigma2, dc)
  local ra, rb = a.r, b.r
  local sa, a1, a2, a3, anl, ant = tilt(ra[3], ra[6], ra[9], a.tx, a.ty, a.tz)
  local sb, b1, b2, b3, bnl, bnt = tilt(rb[3], rb[6], rb[9], b.tx, b.ty, b.tz)
  local d2a = separation(ra[3], ra[6], ra[9], Fa, sigma2, sa, a1, a2, a3, anl, ant, b1, b2, b3)
  local d2b = separation(rb[3], rb[6], rb[9], Fb, sigma2, sb, b1, b2, b3, bnl, bnt, a1, a2, a3)
  if not (sa > FACE_ON and sb > FACE_ON and d2a > 0 and d2b > 0 and d2a < huge
    and d2b < huge) then
    return 0, 0, 0
  end
  return shapes(sa, sb, d2a, d2b, dc)
end

--- The branch log-odds of candidate a over b and each one's chord factor (the model's extra
-- variance along the chord to the other, over the chord's square), from their factors.
-- @tparam table a a candidate record
-- @tparam table b the other minimum
-- @tparam number sigma2 σ² (px²)
-- @treturn number L, ln(P(a's branch) / P(b's branch)) given this frame, untempered
-- @treturn number a's chord factor
-- @treturn number b's chord factor
function M.analyse(a, b, sigma2)
  local Fa, Fb = factors_a, factors_b
  -- (a loop over the two: on LuaJIT it starts a trace of its own instead of swelling the
  -- solve's)
  both[1], both[2] = a.normal, b.normal
  for c = 1, 2 do logdets[c] = factor(both[c], c == 1 and Fa or Fb) end
  local dc = (b.sse - a.sse) / sigma2
  -- Laplace: each basin's mass exp(-χ²/2) (2π)³ det(H/σ²)^(-1/2), σ cancels in the ratio
  local L = 0.5 * dc + 0.5 * (logdets[2] - logdets[1])
  if L > DECIDED or L < -DECIDED then return L, 0, 0 end
  local shape, ka, kb = tilted(a, b, Fa, Fb, sigma2, dc)
  L = L + shape
  if not (L == L) then L = 0 end
  return L, ka, kb
end

local analyse = M.analyse

-- The factor on a covariance whose σ² was estimated from ν residual degrees of freedom (topped
-- up by the default, `noise`) that makes its 6-dof 95 % ellipsoid hold 95 % of the errors: for
-- ν = 2, 4, ..., 40, from `bench/ellipsoid_table.lua` (for DEFAULT_DOF = 8). From ν = 10 on it
-- is Student's: 6 F(6, ν; 0.95) / χ²(6; 0.95).
local ELLIPSOID = { 1.0623, 1.1385, 1.2345, 1.3604, 1.5330, 1.4277, 1.3570, 1.3063, 1.2681,
  1.2384, 1.2146, 1.1952, 1.1789, 1.1652, 1.1534, 1.1432, 1.1342, 1.1263, 1.1193, 1.1131 }
local ELLIPSOID_DOF = 2 * #ELLIPSOID

--- The factor on `σ² H⁻¹` when σ² was estimated from ν degrees of freedom (`noise`), for the
-- covariance's 95 % ellipsoid to be the pose's 95 % region (1 for a known σ; beyond the table
-- κ - 1 falls as 1/ν, to within 0.2 %).
-- @tparam number dof ν, the residuals' degrees of freedom (>= 0)
-- @treturn number κ (>= 1)
function M.ellipsoid(dof)
  if dof >= ELLIPSOID_DOF then return 1 + (ELLIPSOID[#ELLIPSOID] - 1) * ELLIPSOID_DOF / dof end
  local i = floor(0.5 * dof)
  local lo = i >= 1 and ELLIPSOID[i] or 1
  return lo + (ELLIPSOID[i + 1] - lo) * (0.5 * dof - i)
end

--- σ² to use: `sigma²` when given, else the residuals' estimate topped up with `DEFAULT_SIGMA`
-- to `DEFAULT_DOF + 2` degrees of freedom, `((DEFAULT_DOF + 2 - ν)₊ DEFAULT_SIGMA² + sse) /
-- max(DEFAULT_DOF + 2, ν)`: the default stands in for the degrees of freedom a frame lacks
-- (one tag has 2), and a fit with enough (a block of two faces, 10) is judged by its own.
-- @tparam number sse the sum of squared pixel residuals (px²) of the best fit
-- @tparam[opt] number sigma σ in pixels (`options.sigma`)
-- @tparam[opt] number dof ν, the residuals' degrees of freedom (default 2: one tag)
-- @treturn number σ² (px²)
-- @treturn number κ, the factor on the covariance for its 95 % ellipsoid (`ellipsoid`; 1 for
--   a given σ): the confidence takes σ², the covariance κ σ²
function M.noise(sse, sigma, dof)
  if sigma then return sigma * sigma, 1 end
  dof = dof or 2
  local top, d = M.DEFAULT_DOF + 2, M.DEFAULT_SIGMA
  return (max(top - dof, 0) * d * d + sse) / max(top, dof), M.ellipsoid(dof)
end

--- The per-frame log-likelihood ratio between the branches of a and b: ln of the posterior mass
-- of a's basin over b's given this frame's corners (σ² known, branches equally likely a
-- priori, the tilt uniform in angle within each). A tracker adds `KAPPA` times it to its
-- carried log-odds each frame, the way `probability` turns it into a confidence.
-- @tparam table a a candidate record
-- @tparam table b the other candidate
-- @tparam number sigma2 σ² (px²)
-- @treturn number ln(P(a's branch | this frame) / P(b's branch | this frame)), untempered
function M.log_odds(a, b, sigma2)
  return (analyse(a, b, sigma2))
end

--- The confidence of a branch whose log-odds are L: the logistic function of `KAPPA` L with
-- the spread `SPREAD` up to `SPREAD_LIMIT` (see there).
-- @tparam number L log-odds (`log_odds`)
-- @treturn number the probability, in [0, 1]
function M.probability(L)
  local z = M.KAPPA * L
  local t = M.SPREAD
  if t > 0 then
    -- π/8 times the error's variance, (SPREAD z)² up to SPREAD_LIMIT²
    local e, limit = 0.39269908169872414 * t * t * z * z, M.SPREAD_LIMIT
    local most = 0.39269908169872414 * limit * limit
    if not (e < most) then e = most end
    z = z / sqrt(1 + e)
  end
  if not (z == z) then return 0.5 end
  return 1 / (1 + exp(-z))
end

--- The chord from candidate a to b: the rotation vector of rb raᵀ, then tb - ta (from the
-- records' quaternions when they carry them, qb qa⁻¹).
-- @tparam table a a candidate record
-- @tparam table b another
-- @treturn number δω1, δω2, δω3, δt1, δt2, δt3
function M.chord(a, b)
  local w, x, y, z
  local aw, bw = a.qw, b.qw
  if aw and bw then
    local ax, ay, az, bx, by, bz = -a.qx, -a.qy, -a.qz, b.qx, b.qy, b.qz
    w = bw * aw - bx * ax - by * ay - bz * az
    x = bw * ax + bx * aw + by * az - bz * ay
    y = bw * ay - bx * az + by * aw + bz * ax
    z = bw * az + bx * ay - by * ax + bz * aw
    if w < 0 then w, x, y, z = -w, -x, -y, -z end
  else
    rotation.multiply_transpose(b.r, a.r, product)
    w, x, y, z = to_quaternion(product)
  end
  local s = sqrt(x * x + y * y + z * z)
  local f = 2
  if s > 1e-12 then f = 2 * atan2(s, w) / s end
  return f * x, f * y, f * z, b.tx - a.tx, b.ty - a.ty, b.tz - a.tz
end

local chord = M.chord

--- The covariance of a pose from its H, σ² and a rank-one term along a chord,
-- `σ² H⁻¹ + k d dᵀ`, in the contract's order (k, from `assess`, already carries σ²: it is the
-- model's extra variance along the tilt over the chord's square in those variances).
-- @tparam {number,...} N the normal equations (H in the first 21 numbers)
-- @tparam number sigma2 σ² (px²)
-- @tparam number k the chord's factor (0: none)
-- @tparam ?{number,...} d the chord, (δω, δt) (nil when k is 0)
-- @tparam[opt] table out nested 6×6 to fill (nil: a new one)
-- @treturn table the covariance
-- @treturn number ln det H (pivots below 1e-12 of their diagonal raised to it)
function M.from_normal(N, sigma2, k, d, out)
  local ld = factor(N, factors_a)
  return M.from_factors(factors_a, ld, sigma2, k, d, out)
end

--- The covariance from H's factors (`from_normal` without factoring H again).
-- @tparam {number,...} F the LDLᵀ factors (`tagpose.uncertainty.matrix.factor`)
-- @tparam number ld their ln det H
-- @tparam number sigma2 σ² (px²)
-- @tparam number k the chord's factor (0: none)
-- @tparam ?{number,...} d the chord
-- @tparam[opt] table out nested 6×6 to fill (nil: a new one)
-- @treturn table the covariance
-- @treturn number ld
function M.from_factors(F, ld, sigma2, k, d, out)
  if k == 0 or not d then
    return fill(out, inverse(F, packed), sigma2, 0, 0, 0, 0, 0, 0, 0), ld
  end
  return fill(out, inverse(F, packed), sigma2, k, d[1], d[2], d[3], d[4], d[5], d[6]), ld
end

--- The covariance of a candidate: `σ² H⁻¹` and, when `assess` found the candidate to be one of
-- two minima of the planar ambiguity, the rank-one term along its chord to the other
-- (`c.k`, `c.chord`).
-- @tparam table c a candidate record (`normal`; optionally `k` and `chord` from `assess`)
-- @tparam number sigma2 σ² (px²)
-- @tparam[opt] table out nested 6×6 to fill (nil: a new one)
-- @treturn table the covariance
-- @treturn number ln det H
function M.covariance(c, sigma2, out)
  return M.from_normal(c.normal, sigma2, c.k or 0, c.chord, out)
end

--- The branch analysis of two candidates, into their records: each one's `confidence` (the
-- probability that it is on the true branch; they sum to one), its chord factor `k` and its
-- `chord` to the other (six numbers, (δω, δt); an array made when the record has none). With
-- `b` nil, a is the only minimum: confidence 1, k 0.
-- @tparam table a a candidate record
-- @tparam[opt] table b the other minimum of the planar ambiguity
-- @tparam number sigma2 σ² (px²)
-- @treturn number the untempered log-odds of a's branch over b's (`log_odds`); `math.huge`
--   without b
function M.assess(a, b, sigma2)
  if not b then
    a.confidence, a.k = 1, 0
    return huge
  end
  local L, ka, kb = analyse(a, b, sigma2)
  local p = M.probability(L)
  a.confidence, b.confidence, a.k, b.k = p, 1 - p, ka, kb
  local d1, d2, d3, d4, d5, d6 = 0, 0, 0, 0, 0, 0
  if ka ~= 0 or kb ~= 0 then d1, d2, d3, d4, d5, d6 = chord(a, b) end
  local da, db = a.chord, b.chord
  if not da then
    da = {}
    a.chord = da
  end
  if not db then
    db = {}
    b.chord = db
  end
  da[1], da[2], da[3], da[4], da[5], da[6] = d1, d2, d3, d4, d5, d6
  db[1], db[2], db[3], db[4], db[5], db[6] = -d1, -d2, -d3, -d4, -d5, -d6
  return L
end

--- The covariance of a point carried rigidly by a pose, from the pose's: the point at
-- `o` from the pose's origin (camera frame) moves by `δc = δt + δω × o`, the rotation's
-- covariance stays; `J C Jᵀ`, `J = [[I, -[o]×], [0, I]]` in the contract's order.
-- @tparam table C the pose's covariance (nested 6×6, position first)
-- @tparam number o1 the point relative to the pose's origin, camera frame
-- @tparam number o2
-- @tparam number o3
-- @tparam[opt] table out nested 6×6 to fill (nil: a new one)
-- @treturn table the point's covariance
function M.move(C, o1, o2, o3, out)
  out = out or { {}, {}, {}, {}, {}, {} }
  -- the rows of -[o]×
  local m1, m2, m3 = { 0, o3, -o2 }, { -o3, 0, o1 }, { o2, -o1, 0 }
  local m = { m1, m2, m3 }
  local A = {} -- rows 1..3 of J C
  for i = 1, 3 do
    local mi, row = m[i], {}
    for j = 1, 6 do
      row[j] = C[i][j] + mi[1] * C[4][j] + mi[2] * C[5][j] + mi[3] * C[6][j]
    end
    A[i] = row
  end
  for i = 1, 3 do
    local Ai = A[i]
    for j = i, 3 do
      local mj = m[j]
      local v = Ai[j] + mj[1] * Ai[4] + mj[2] * Ai[5] + mj[3] * Ai[6]
      out[i][j], out[j][i] = v, v
    end
    for j = 4, 6 do out[i][j], out[j][i] = Ai[j], Ai[j] end
  end
  for i = 4, 6 do
    for j = 4, 6 do out[i][j] = C[i][j] end
  end
  return out
end

return M
