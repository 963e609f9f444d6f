--- The bundle adjustment under `tagpose.layout.calibrate`: the problem, its cost and its normal
-- equations over every frame's body pose and every tag's pose on the body (their damped step,
-- with the frames eliminated, is `tagpose.layout.schur`'s).
--
-- Unknowns: per frame `f` the body → camera pose `(R_f, t_f)`, per tag `i` its pose on the body
-- `(Q_i, p_i)`; one tag (the reference) is held fixed, which removes the six-dimensional gauge
-- (a move of the body frame leaves every image alike). A corner `c` of tag `i` seen in frame
-- `f` is at `X = R_f·(Q_i·c + p_i) + t_f` in the camera. Every step is taken in the body frame,
-- rotations by the Cayley transform of a small rotation vector: `R_f ← R_f·C(δθ_f)`,
-- `t_f ← t_f + R_f·δτ_f`, `Q_i ← C(δφ_i)·Q_i`, `p_i ← p_i + δp_i`. With `e` a row of
-- ∂pixel/∂X at the corner, `b = R_fᵀe`, `W = Q_i·c` and `X_b = W + p_i`, the residual's
-- Jacobian rows are
--
--     over (δθ_f, δτ_f):  (X_b × b, b)
--     over (δφ_i, δp_i):  (W × b, b)
--
-- Each observation (one tag in one frame: four corners) carries a weight, the robust loss's
-- (`ρ(s) = c²·ln(1 + s/c²)` of its squared residual `s`, weight `ρ'(s)`: a Cauchy loss on the
-- detection as a whole, since a bad detection is bad in all its corners).
--
-- Arrays are flat and 1-based: rotations row-major (9 per pose), translations 3 per pose,
-- pixels 8 per observation, 6×6 blocks row-major (36) or upper triangles (21).
-- @module tagpose.layout.bundle

local lens_model = require("tagpose.core.lens")
local lsq = require("tagpose.core.lsq")
local pose = require("tagpose.core.pose")

local huge, sqrt, log = math.huge, math.sqrt, math.log
local brown, fisheye = lens_model.brown, lens_model.fisheye
local cayley = lsq.cayley

local M = {}

local CX, CY = pose.CORNER_X, pose.CORNER_Y

local UPPER = lsq.UPPER

--- A new problem: the camera, the frames' and tags' counts, the observations. The caller fills
-- the arrays it returns before the first `cost`.
-- @tparam table camera a checked camera
-- @tparam int nframes
-- @tparam int ntags
-- @treturn table the problem: `fr`, `ft` (frame poses), `tq`, `tp` (tag poses), `half` (per
--   tag), `of`, `ot`, `px` (per observation: frame, tag, pixels), `first`, `last` (per frame:
--   its observations, which are sorted by frame), `free` (per tag: its unknowns' slot 1.., or
--   0 for the reference)
function M.new(camera, nframes, ntags)
  local P = { nframes = nframes, ntags = ntags, fr = {}, ft = {}, tq = {}, tp = {}, half = {},
    of = {}, ot = {}, px = {}, first = {}, last = {}, free = {}, s = {}, w = {},
    A = {}, gA = {}, C = {}, gC = {}, B = {}, inv = {}, Z = {} }
  P.K = lsq.pack(camera)
  return P
end

-- The pixel residual (ru, rv) of corner k of observation o at the poses (fr, ft, tq, tp), and
-- what the Jacobian rows need: the point Y = R_f·X_b (camera frame), W = Q·c (body frame), the
-- normalised projection and 1/z, the lens map's Jacobian and R_f; nil when the corner is behind
-- the camera.
local function corner(P, K, o, k, fr, ft, tq, tp)
  local f, i = P.of[o], P.ot[o]
  local fo, io, h = 9 * f - 9, 9 * i - 9, P.half[i]
  local a, b = CX[k] * h, CY[k] * h
  -- W = Q·c (body), X_b = W + p
  local w1 = tq[io + 1] * a + tq[io + 2] * b
  local w2 = tq[io + 4] * a + tq[io + 5] * b
  local w3 = tq[io + 7] * a + tq[io + 8] * b
  local po = 3 * i - 3
  local x1, x2, x3 = w1 + tp[po + 1], w2 + tp[po + 2], w3 + tp[po + 3]
  local r1, r2, r3, r4, r5, r6, r7, r8, r9 = fr[fo + 1], fr[fo + 2], fr[fo + 3], fr[fo + 4],
    fr[fo + 5], fr[fo + 6], fr[fo + 7], fr[fo + 8], fr[fo + 9]
  local y1 = r1 * x1 + r2 * x2 + r3 * x3
  local y2 = r4 * x1 + r5 * x2 + r6 * x3
  local y3 = r7 * x1 + r8 * x2 + r9 * x3
  local to = 3 * f - 3
  local z = y3 + ft[to + 3]
  if not (z > 0) then return nil end
  local iz = 1 / z
  local pu, pv = (y1 + ft[to + 1]) * iz, (y2 + ft[to + 2]) * iz
  local kind = K.lens
  local xd, yd, j11, j12, j21, j22 = pu, pv, 1, 0, 0, 1
  if kind == 1 then
    xd, yd, j11, j12, j21, j22 = brown(pu, pv, K.k1, K.k2, K.p1, K.p2, K.k3, K.k4, K.k5, K.k6)
  elseif kind == 2 then
    xd, yd, j11, j12, j21, j22 = fisheye(pu, pv, K.k1, K.k2, K.k3, K.k4)
  end
  local q = 8 * o - 8 + 2 * k
  local ru, rv = K.fx * xd + K.cx - P.px[q - 1], K.fy * yd + K.cy - P.px[q]
  return ru, rv, y1, y2, y3, w1, w2, w3, pu, pv, iz, j11, j12, j21, j22,
    r1, r2, r3, r4, r5, r6, r7, r8, r9
end

--- The robust loss of one observation's squared residual `s`: `c²·ln(1 + s/c²)`, with
-- `ln(1 + x)` taken as `ln(u)·x/(u - 1)`, `u = 1 + x` (exact to round-off where `1 + x`
-- rounds to 1: a large `c²` gives `s`, the plain square, not 0).
-- @tparam number s px²
-- @tparam number c2 px²
-- @treturn number
function M.rho(s, c2)
  local x = s / c2
  local u = 1 + x
  if u == 1 then return s end
  return c2 * log(u) * (x / (u - 1))
end

local rho = M.rho

--- The robust cost at a state, and each observation's squared residual into `P.s`.
-- @tparam table P the problem
-- @tparam table S the state `{fr =, ft =, tq =, tp =}`
-- @tparam[opt] number c2 the robust loss's `c²` (px², per observation); nil: plain squares
-- @treturn number the robust cost (`math.huge` when a corner is behind the camera)
-- @treturn number the sum of squared residuals
function M.cost(P, S, c2)
  local K, s = P.K, P.s
  local fr, ft, tq, tp = S.fr, S.ft, S.tq, S.tp
  local total, sse = 0, 0
  for o = 1, #P.of do
    local so = 0
    for k = 1, 4 do
      local ru, rv = corner(P, K, o, k, fr, ft, tq, tp)
      if not ru then return huge, huge end
      so = so + ru * ru + rv * rv
    end
    s[o] = so
    sse = sse + so
    total = total + (c2 and rho(so, c2) or so)
  end
  return total, sse
end

local U, V = {}, {} -- an observation's 6×6 sums (full) and T·U

-- The sums of observation o over its eight rows (weight sw²): U = Σ u uᵀ into U (full, 36),
-- and Σ u r returned.
local function sums(P, K, o, S, sw)
  local fx, fy = K.fx, K.fy
  local h11, h12, h13, h14, h15, h16, h22, h23, h24, h25, h26 = 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
  local h33, h34, h35, h36, h44, h45, h46, h55, h56, h66 = 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
  local g1, g2, g3, g4, g5, g6 = 0, 0, 0, 0, 0, 0
  for k = 1, 4 do
    local ru, rv, _, _, _, w1, w2, w3, pu, pv, iz, j11, j12, j21, j22,
      r1, r2, r3, r4, r5, r6, r7, r8, r9 = corner(P, K, o, k, S.fr, S.ft, S.tq, S.tp)
    for row = 1, 2 do
      local e1, e2, res
      if row == 1 then
        e1, e2, res = fx * j11 * iz, fx * j12 * iz, ru
      else
        e1, e2, res = fy * j21 * iz, fy * j22 * iz, rv
      end
      local e3 = -(e1 * pu + e2 * pv)
      e1, e2, e3, res = sw * e1, sw * e2, sw * e3, sw * res
      local b1 = r1 * e1 + r4 * e2 + r7 * e3
      local b2 = r2 * e1 + r5 * e2 + r8 * e3
      local b3 = r3 * e1 + r6 * e2 + r9 * e3
      local u1, u2, u3 = w2 * b3 - w3 * b2, w3 * b1 - w1 * b3, w1 * b2 - w2 * b1
      h11, h12, h13, h14 = h11 + u1 * u1, h12 + u1 * u2, h13 + u1 * u3, h14 + u1 * b1
      h15, h16, h22, h23 = h15 + u1 * b2, h16 + u1 * b3, h22 + u2 * u2, h23 + u2 * u3
      h24, h25, h26, h33 = h24 + u2 * b1, h25 + u2 * b2, h26 + u2 * b3, h33 + u3 * u3
      h34, h35, h36, h44 = h34 + u3 * b1, h35 + u3 * b2, h36 + u3 * b3, h44 + b1 * b1
      h45, h46, h55, h56 = h45 + b1 * b2, h46 + b1 * b3, h55 + b2 * b2, h56 + b2 * b3
      h66, g1, g2, g3 = h66 + b3 * b3, g1 + u1 * res, g2 + u2 * res, g3 + u3 * res
      g4, g5, g6 = g4 + b1 * res, g5 + b2 * res, g6 + b3 * res
    end
  end
  U[1], U[2], U[3], U[4], U[5], U[6] = h11, h12, h13, h14, h15, h16
  U[8], U[9], U[10], U[11], U[12] = h22, h23, h24, h25, h26
  U[15], U[16], U[17], U[18], U[22], U[23], U[24] = h33, h34, h35, h36, h44, h45, h46
  U[29], U[30], U[36] = h55, h56, h66
  for r = 2, 6 do
    for c = 1, r - 1 do U[(r - 1) * 6 + c] = U[(c - 1) * 6 + r] end
  end
  return g1, g2, g3, g4, g5, g6
end

-- Observation o's sums (U, g) into its tag's block, its frame's block and its coupling: the
-- coupling V = T·U (frame rows, tag columns), the frame's block V·Tᵀ, its gradient T·g.
local function scatter(P, o, tp, g1, g2, g3, g4, g5, g6)
  local A, gA, C, gC, B = P.A, P.gA, P.C, P.gC, P.B
  local i = P.ot[o]
  local ta, tg = 21 * i - 21, 6 * i - 6
  for k = 1, 21 do
    local rc = UPPER[k]
    C[ta + k] = C[ta + k] + U[(rc[1] - 1) * 6 + rc[2]]
  end
  gC[tg + 1], gC[tg + 2], gC[tg + 3] = gC[tg + 1] + g1, gC[tg + 2] + g2, gC[tg + 3] + g3
  gC[tg + 4], gC[tg + 5], gC[tg + 6] = gC[tg + 4] + g4, gC[tg + 5] + g5, gC[tg + 6] + g6
  local p1, p2, p3 = tp[3 * i - 2], tp[3 * i - 1], tp[3 * i]
  for c = 1, 6 do
    local x4, x5, x6 = U[18 + c], U[24 + c], U[30 + c]
    V[c] = U[c] - p3 * x5 + p2 * x6
    V[6 + c] = U[6 + c] + p3 * x4 - p1 * x6
    V[12 + c] = U[12 + c] - p2 * x4 + p1 * x5
    V[18 + c], V[24 + c], V[30 + c] = x4, x5, x6
  end
  local bo, fa, fg = 36 * o - 36, 21 * P.of[o] - 21, 6 * P.of[o] - 6
  for k = 1, 36 do B[bo + k] = V[k] end
  for k = 1, 21 do
    local rc = UPPER[k]
    local r, c = rc[1], rc[2]
    local o6 = (r - 1) * 6
    local v
    if c == 1 then
      v = V[o6 + 1] - p3 * V[o6 + 5] + p2 * V[o6 + 6]
    elseif c == 2 then
      v = V[o6 + 2] + p3 * V[o6 + 4] - p1 * V[o6 + 6]
    elseif c == 3 then
      v = V[o6 + 3] - p2 * V[o6 + 4] + p1 * V[o6 + 5]
    else
      v = V[o6 + c]
    end
    A[fa + k] = A[fa + k] + v
  end
  gA[fg + 1] = gA[fg + 1] + g1 - p3 * g5 + p2 * g6
  gA[fg + 2] = gA[fg + 2] + g2 + p3 * g4 - p1 * g6
  gA[fg + 3] = gA[fg + 3] + g3 - p2 * g4 + p1 * g5
  gA[fg + 4], gA[fg + 5], gA[fg + 6] = gA[fg + 4] + g4, gA[fg + 5] + g5, gA[fg + 6] + g6
end

--- The normal equations at a state, with each observation weighted by the robust loss at its
-- squared residual `P.s` (from `cost` at the same state).
--
-- Per residual row, with `b = R_fᵀe` (the row in the body frame), the tag's Jacobian is
-- `u = (W × b, b)` and the frame's `T·u`, `T = [[I, [p]×], [0, I]]`: the frame is perturbed
-- in the body frame, `R_f ← R_f·C(δθ)`, `t_f ← t_f + R_f·δτ`, so its Jacobian is
-- `(X_b × b, b)`, `X_b = W + p`. So an observation needs only `U = Σ u uᵀ` and `Σ u r` over its
-- eight rows: its tag block is `U`, its frame block `T U Tᵀ` and their coupling `T U`.
-- @tparam table P the problem
-- @tparam table S the state
-- @tparam[opt] number c2 the robust loss's `c²`; nil: weight 1
function M.linearise(P, S, c2)
  local A, gA, C, gC, w = P.A, P.gA, P.C, P.gC, P.w
  for i = 1, 21 * P.nframes do A[i] = 0 end
  for i = 1, 6 * P.nframes do gA[i] = 0 end
  for i = 1, 21 * P.ntags do C[i] = 0 end
  for i = 1, 6 * P.ntags do gC[i] = 0 end
  for o = 1, #P.of do
    local wo = c2 and 1 / (1 + P.s[o] / c2) or 1
    w[o] = wo
    scatter(P, o, S.tp, sums(P, P.K, o, S, sqrt(wo)))
  end
end

-- Pose j of (r, t) moved by step j of d into (r2, t2): on the left (a tag on the body,
-- `Q ← C(δφ)·Q`, `p ← p + δp`), or on the right (a frame, `R ← R·C(δθ)`, `t ← t + R·δτ`).
local function move(r, t, d, j, r2, t2, right)
  local o, to, dd = 9 * (j - 1), 3 * (j - 1), 6 * (j - 1)
  local c11, c12, c13, c21, c22, c23, c31, c32, c33 = cayley(d[dd + 1], d[dd + 2], d[dd + 3])
  local d4, d5, d6 = d[dd + 4], d[dd + 5], d[dd + 6]
  if right then
    local t1 = t[to + 1] + r[o + 1] * d4 + r[o + 2] * d5 + r[o + 3] * d6
    local t2_ = t[to + 2] + r[o + 4] * d4 + r[o + 5] * d5 + r[o + 6] * d6
    local t3 = t[to + 3] + r[o + 7] * d4 + r[o + 8] * d5 + r[o + 9] * d6
    for row = 0, 6, 3 do
      local a, b, c = r[o + row + 1], r[o + row + 2], r[o + row + 3]
      r2[o + row + 1] = a * c11 + b * c21 + c * c31
      r2[o + row + 2] = a * c12 + b * c22 + c * c32
      r2[o + row + 3] = a * c13 + b * c23 + c * c33
    end
    t2[to + 1], t2[to + 2], t2[to + 3] = t1, t2_, t3
    return
  end
  for col = 1, 3 do
    local a, b, c = r[o + col], r[o + 3 + col], r[o + 6 + col]
    r2[o + col] = c11 * a + c12 * b + c13 * c
    r2[o + 3 + col] = c21 * a + c22 * b + c23 * c
    r2[o + 6 + col] = c31 * a + c32 * b + c33 * c
  end
  t2[to + 1], t2[to + 2], t2[to + 3] = t[to + 1] + d4, t[to + 2] + d5, t[to + 3] + d6
end

--- The state reached by a step.
-- @tparam table P the problem
-- @tparam table S the state stepped from
-- @tparam table D the step (`step`)
-- @tparam table T the state to fill
-- @treturn table T
function M.apply(P, S, D, T)
  for fi = 1, P.nframes do move(S.fr, S.ft, D.x, fi, T.fr, T.ft, true) end
  for i = 1, P.ntags do move(S.tq, S.tp, D.y, i, T.tq, T.tp, false) end
  return T
end

return M
