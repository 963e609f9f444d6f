--- The bundle adjustment under `tagpose.layout.calibrate`: the normal equations over every
-- frame's body pose and every tag's pose on the body, and their damped step with the frame
-- poses eliminated frame by frame (Schur complement).
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
-- The step solves `(H + λ·diag H) δ = -g` by eliminating each frame's six unknowns: with `A_f`
-- the frame's block, `B_fi` its coupling to tag `i` and `C` the tags' block, the reduced
-- system over the tags is `(C - Σ_f B_fᵀ A_f⁻¹ B_f) δy = -g_y + Σ_f B_fᵀ A_f⁻¹ g_f`, of order
-- 6·(tags - 1), built in time linear in the frames; then `δx_f = -A_f⁻¹ (g_f + B_f δy)`.
--
-- Arrays are flat and 1-based: rotations row-major (9 per pose), translations 3 per pose,
-- pixels 8 per observation, 6×6 blocks row-major (36) or upper triangles (21).
-- @module tagpose.layout.bundle

local camera_model = require("tagpose.camera")
local refine = require("tagpose.refine")
local linsolve = require("tagpose.linsolve")

local huge, sqrt, log = math.huge, math.sqrt, math.log
local lens, brown, fisheye = camera_model.lens, camera_model.brown, camera_model.fisheye
local cayley = refine.cayley

local M = {}

local CX = { -1, 1, 1, -1 }
local CY = { 1, 1, -1, -1 }

-- (row, col) of a 6×6 upper triangle's entries
local UPPER = {}
do
  local k = 0
  for a = 1, 6 do
    for b = a, 6 do
      k = k + 1
      UPPER[k] = { a, b }
    end
  end
end

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
  P.K = { camera.fx, camera.fy, camera.cx, camera.cy, lens(camera) }
  for i = 6, 13 do
    if P.K[i] == nil then P.K[i] = 0 end
  end
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
  local kind = K[5]
  local xd, yd, j11, j12, j21, j22 = pu, pv, 1, 0, 0, 1
  if kind == 1 then
    xd, yd, j11, j12, j21, j22 = brown(pu, pv, K[6], K[7], K[8], K[9], K[10], K[11], K[12],
      K[13])
  elseif kind == 2 then
    xd, yd, j11, j12, j21, j22 = fisheye(pu, pv, K[6], K[7], K[8], K[9])
  end
  local q = 8 * o - 8 + 2 * k
  local ru, rv = K[1] * xd + K[3] - P.px[q - 1], K[2] * yd + K[4] - P.px[q]
  return ru, rv, y1, y2, y3, w1, w2, w3, pu, pv, iz, j11, j12, j21, j22,
    r1, r2, r3, r4, r5, r6, r7, r8, r9
end

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
    total = total + (c2 and c2 * log(1 + so / c2) or so)
  end
  return total, sse
end

local U, V = {}, {} -- an observation's 6×6 sums (full) and T·U

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
  local K, A, gA, C, gC, B, w = P.K, P.A, P.gA, P.C, P.gC, P.B, P.w
  local fx, fy = K[1], K[2]
  local fr, ft, tq, tp = S.fr, S.ft, S.tq, S.tp
  for i = 1, 21 * P.nframes do A[i] = 0 end
  for i = 1, 6 * P.nframes do gA[i] = 0 end
  for i = 1, 21 * P.ntags do C[i] = 0 end
  for i = 1, 6 * P.ntags do gC[i] = 0 end
  for o = 1, #P.of do
    local wo = c2 and 1 / (1 + P.s[o] / c2) or 1
    w[o] = wo
    local sw = sqrt(wo)
    local h11, h12, h13, h14, h15, h16, h22, h23, h24, h25, h26 = 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    local h33, h34, h35, h36, h44, h45, h46, h55, h56, h66 = 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    local g1, g2, g3, g4, g5, g6 = 0, 0, 0, 0, 0, 0
    for k = 1, 4 do
      local ru, rv, _, _, _, w1, w2, w3, pu, pv, iz, j11, j12, j21, j22,
        r1, r2, r3, r4, r5, r6, r7, r8, r9 = corner(P, K, o, k, fr, ft, tq, tp)
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
    -- the tag's block U and gradient
    local i = P.ot[o]
    local ta, tg = 21 * i - 21, 6 * i - 6
    U[1], U[2], U[3], U[4], U[5], U[6] = h11, h12, h13, h14, h15, h16
    U[8], U[9], U[10], U[11], U[12] = h22, h23, h24, h25, h26
    U[15], U[16], U[17], U[18], U[22], U[23], U[24] = h33, h34, h35, h36, h44, h45, h46
    U[29], U[30], U[36] = h55, h56, h66
    for r = 2, 6 do
      for c = 1, r - 1 do U[(r - 1) * 6 + c] = U[(c - 1) * 6 + r] end
    end
    for k = 1, 21 do
      local rc = UPPER[k]
      C[ta + k] = C[ta + k] + U[(rc[1] - 1) * 6 + rc[2]]
    end
    gC[tg + 1], gC[tg + 2], gC[tg + 3] = gC[tg + 1] + g1, gC[tg + 2] + g2, gC[tg + 3] + g3
    gC[tg + 4], gC[tg + 5], gC[tg + 6] = gC[tg + 4] + g4, gC[tg + 5] + g5, gC[tg + 6] + g6
    -- the coupling V = T·U (frame rows, tag columns), the frame's block V·Tᵀ and gradient T·g
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
end

-- The Cholesky factor L (lower, row-major 6×6) of a damped block (upper triangle from `first`,
-- diagonal × f) into out[o + 1 .. o + 36]; false when it is not positive definite.
local function cholesky6(A, first, f, out, o)
  for k = 1, 21 do
    local rc = UPPER[k]
    local v = A[first + k]
    if rc[1] == rc[2] then v = v * f end
    out[o + (rc[2] - 1) * 6 + rc[1]] = v -- the lower triangle, (c, r)
  end
  for j = 1, 6 do
    local rj = o + (j - 1) * 6
    local d = out[rj + j]
    local scale = d
    for k = 1, j - 1 do d = d - out[rj + k] * out[rj + k] end
    if not (d > 1e-13 * scale) then return false end
    d = sqrt(d)
    out[rj + j] = d
    for i = j + 1, 6 do
      local ri = o + (i - 1) * 6
      local s = out[ri + j]
      for k = 1, j - 1 do s = s - out[ri + k] * out[rj + k] end
      out[ri + j] = s / d
    end
  end
  return true
end

-- Solve L·x = b in place for the 6 numbers x[xo + stride·(1..6)] (forward substitution).
local function forward6(L, lo, x, xo, stride)
  for i = 1, 6 do
    local ri = lo + (i - 1) * 6
    local s = x[xo + stride * i]
    for k = 1, i - 1 do s = s - L[ri + k] * x[xo + stride * k] end
    x[xo + stride * i] = s / L[ri + i]
  end
end

-- Solve Lᵀ·x = b in place (back substitution), x as for forward6.
local function backward6(L, lo, x, xo, stride)
  for i = 6, 1, -1 do
    local s = x[xo + stride * i]
    for k = i + 1, 6 do s = s - L[lo + (k - 1) * 6 + i] * x[xo + stride * k] end
    x[xo + stride * i] = s / L[lo + (i - 1) * 6 + i]
  end
end

local SR, rhs, scale, zf = {}, {}, {}, {} -- the reduced system and its scratch

-- The tags' own damped blocks and gradients into the reduced system (order n).
local function tag_blocks(P, f, n)
  local C, gC, free = P.C, P.gC, P.free
  for k = 1, n * n do SR[k] = 0 end
  for k = 1, n do rhs[k] = 0 end
  for i = 1, P.ntags do
    local a = free[i]
    if a > 0 then
      local base, ci = 6 * (a - 1), 21 * (i - 1)
      for k = 1, 21 do
        local rc = UPPER[k]
        local v = C[ci + k]
        if rc[1] == rc[2] then v = v * f end
        SR[(base + rc[1] - 1) * n + base + rc[2]] = v
        SR[(base + rc[2] - 1) * n + base + rc[1]] = v
      end
      for k = 1, 6 do rhs[base + k] = -gC[6 * (i - 1) + k] end
    end
  end
end

--- The damped step from the normal equations of `linearise`, eliminating the frames: with
-- `A_f = L Lᵀ`, `Z = L⁻¹B` and `z = L⁻¹g_f`, the frame takes `ZᵀZ` from the reduced matrix and
-- adds `Zᵀz` to its right-hand side; then `δx_f = -L⁻ᵀ(z + Z·δy)`.
-- @tparam table P the problem
-- @tparam number lambda the damping (the diagonal is multiplied by `1 + lambda`)
-- @tparam table D the step to fill: `D.x` (6 per frame: δθ, δτ), `D.y` (6 per tag: δφ, δp;
--   zero for the reference)
-- @treturn boolean false when the damped system is not positive definite
function M.step(P, lambda, D)
  local A, gA, B, L, Z, free, ot = P.A, P.gA, P.B, P.inv, P.Z, P.free, P.ot
  local f = 1 + lambda
  local m = 0
  for i = 1, P.ntags do
    if free[i] > m then m = free[i] end
  end
  local n = 6 * m
  tag_blocks(P, f, n)
  for fi = 1, P.nframes do
    local lo, go = 36 * (fi - 1), 6 * (fi - 1)
    if not cholesky6(A, 21 * (fi - 1), f, L, lo) then return false end
    for k = 1, 6 do zf[go + k] = gA[go + k] end
    forward6(L, lo, zf, go, 1)
    local first, last = P.first[fi], P.last[fi]
    for o = first, last do
      local bo = 36 * (o - 1)
      for k = 1, 36 do Z[bo + k] = B[bo + k] end
      for c = 1, 6 do forward6(L, lo, Z, bo + c - 6, 6) end
      local a = free[ot[o]]
      if a > 0 then
        local base = 6 * (a - 1)
        local q1, q2, q3, q4, q5, q6 = zf[go + 1], zf[go + 2], zf[go + 3], zf[go + 4],
          zf[go + 5], zf[go + 6]
        for c = 1, 6 do
          rhs[base + c] = rhs[base + c] + q1 * Z[bo + c] + q2 * Z[bo + 6 + c]
            + q3 * Z[bo + 12 + c] + q4 * Z[bo + 18 + c] + q5 * Z[bo + 24 + c] + q6 * Z[bo + 30 + c]
        end
        for o2 = first, last do
          local a2 = free[ot[o2]]
          if a2 > 0 and o2 <= o then
            -- Z_oᵀ Z_o2 into block (a, a2) and its transpose
            local b2, base2 = 36 * (o2 - 1), 6 * (a2 - 1)
            for r = 1, 6 do
              local z1, z2, z3 = Z[bo + r], Z[bo + 6 + r], Z[bo + 12 + r]
              local z4, z5, z6 = Z[bo + 18 + r], Z[bo + 24 + r], Z[bo + 30 + r]
              local x, y = (base + r - 1) * n + base2, (base2 - 1) * n + base + r
              for c = 1, 6 do
                local s = z1 * Z[b2 + c] + z2 * Z[b2 + 6 + c] + z3 * Z[b2 + 12 + c]
                  + z4 * Z[b2 + 18 + c] + z5 * Z[b2 + 24 + c] + z6 * Z[b2 + 30 + c]
                SR[x + c] = SR[x + c] - s
                if o2 ~= o then SR[y + c * n] = SR[y + c * n] - s end
              end
            end
          end
        end
      end
    end
  end
  -- the reduced system, scaled to a unit diagonal
  for k = 1, n do
    local d = SR[(k - 1) * n + k]
    if not (d > 0) then return false end
    scale[k] = 1 / sqrt(d)
  end
  for r = 1, n do
    local sr = scale[r]
    for c = 1, n do SR[(r - 1) * n + c] = SR[(r - 1) * n + c] * sr * scale[c] end
    rhs[r] = rhs[r] * sr
  end
  if n > 0 and not linsolve.cholesky(n, SR, rhs) then return false end
  local y = D.y
  for i = 1, P.ntags do
    local a = free[i]
    for k = 1, 6 do
      y[6 * (i - 1) + k] = a > 0 and rhs[6 * (a - 1) + k] * scale[6 * (a - 1) + k] or 0
    end
  end
  -- back to the frames
  local x = D.x
  for fi = 1, P.nframes do
    local go = 6 * (fi - 1)
    for k = 1, 6 do x[go + k] = zf[go + k] end
    for o = P.first[fi], P.last[fi] do
      local bo, yo = 36 * (o - 1), 6 * (ot[o] - 1)
      for r = 1, 6 do
        local s = 0
        for c = 1, 6 do s = s + Z[bo + (r - 1) * 6 + c] * y[yo + c] end
        x[go + r] = x[go + r] + s
      end
    end
    backward6(L, 36 * (fi - 1), x, go, 1)
    for k = 1, 6 do x[go + k] = -x[go + k] end
  end
  return true
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

--- The decrease of the cost a step promises to first order, `-(g·δ)`: twice the decrease of
-- the Gauss-Newton model for an undamped step.
-- @tparam table P the problem (its gradient from `linearise`)
-- @tparam table D the step
-- @treturn number
function M.promise(P, D)
  local s = 0
  local gA, gC, x, y = P.gA, P.gC, D.x, D.y
  for k = 1, 6 * P.nframes do s = s - gA[k] * x[k] end
  for k = 1, 6 * P.ntags do s = s - gC[k] * y[k] end
  return s
end

--- The largest move a step gives a corner of a tag on the body (length units): the size of
-- the step in the layout.
-- @tparam table P the problem
-- @tparam table S the state stepped from
-- @tparam table D the step
-- @treturn number
function M.tag_move(P, S, D)
  local y, most = D.y, 0
  for i = 1, P.ntags do
    local o = 6 * (i - 1)
    local r = sqrt(y[o + 1] ^ 2 + y[o + 2] ^ 2 + y[o + 3] ^ 2)
    local t = sqrt(y[o + 4] ^ 2 + y[o + 5] ^ 2 + y[o + 6] ^ 2)
    local p = S.tp
    local v = t + r * (sqrt(p[3 * i - 2] ^ 2 + p[3 * i - 1] ^ 2 + p[3 * i] ^ 2)
      + P.half[i] * 1.5)
    if v > most then most = v end
  end
  return most
end

return M
