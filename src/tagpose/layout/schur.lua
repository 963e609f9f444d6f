--- The damped step of the bundle adjustment (`tagpose.layout.bundle`), with one side of the
-- unknowns eliminated (Schur complement): every frame's six, or every tag's six.
--
-- The step solves `(H + λ·diag H) δ = -g`. With `A_f` a frame's block, `B_fi` its coupling to
-- tag `i` and `C_i` a tag's block, the frames' unknowns interact only through the tags and the
-- tags' only through the frames, so either side can be eliminated block by block:
--
-- * **frames** eliminated: the reduced system over the tags is
--   `(C - Σ_f B_fᵀ A_f⁻¹ B_f) δy = -g_y + Σ_f B_fᵀ A_f⁻¹ g_f`, of order 6·(tags - 1) (the
--   reference is held). With `A_f = L Lᵀ`, `Z = L⁻¹B` and `z = L⁻¹g_f`, a frame takes `ZᵀZ`
--   from the reduced matrix and adds `Zᵀz` to its right-hand side; then
--   `δx_f = -L⁻ᵀ(z + Z·δy)`. Its cost grows with the square of the tags a frame sees and the
--   cube of the tags: the order for many frames of a few tags (a cube's log);
-- * **tags** eliminated: the reduced system over the frames is
--   `(A - Σ_i B_i C_i⁻¹ B_iᵀ) δx = -g_x + Σ_i B_i C_i⁻¹ g_i`, of order 6·frames, each free tag
--   taking its `WᵀW` (`W = L⁻¹Bᵀ`, `C_i = L Lᵀ`) over the pairs of frames that see it; then
--   `δy_i = -L⁻ᵀ(w + W·δx)`. Its cost grows with the square of the frames a tag is seen in and
--   the cube of the frames: linear in the tags a frame sees (a board of many tags over a few
--   frames).
--
-- Both solve the same system exactly (they differ by round-off); `order` picks the cheaper for
-- a problem from its counts of floating-point operations. The reduced system is scaled to a
-- unit diagonal and solved by Cholesky.
--
-- Blocks are 6×6, row-major (36) or upper triangles (21), in the arrays of the problem.
-- @module tagpose.layout.schur

local linsolve = require("tagpose.layout.linsolve")
local lsq = require("tagpose.core.lsq")

local sqrt = math.sqrt

local M = {}

local UPPER = lsq.UPPER

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

-- The reduced system (order n, its lower triangle) scaled to a unit diagonal and solved in
-- place: the solution in rhs, unscaled. False when it is not positive definite.
local function solve_reduced(n)
  for k = 1, n do
    local d = SR[(k - 1) * n + k]
    if not (d > 0) then return false end
    scale[k] = 1 / sqrt(d)
  end
  for r = 1, n do
    local sr, o = scale[r], (r - 1) * n
    for c = 1, r do SR[o + c] = SR[o + c] * sr * scale[c] end
    rhs[r] = rhs[r] * sr
  end
  if n > 0 and not linsolve.cholesky(n, SR, rhs) then return false end
  for k = 1, n do rhs[k] = rhs[k] * scale[k] end
  return true
end

-- Subtract Z_oᵀ Z_o2 from block (a, a2) of the reduced system (order n; `base`, `base2` the
-- blocks' first rows less one), in its lower triangle only (what the Cholesky reads): as is
-- when a >= a2, else transposed into (a2, a). Z_o2's 36 numbers are read once, into locals
-- (these products are most of a step).
local function subtract_pair(Z, bo, b2, base, base2, n)
  local a11, a12, a13, a14, a15, a16 = Z[b2 + 1], Z[b2 + 2], Z[b2 + 3], Z[b2 + 4], Z[b2 + 5],
    Z[b2 + 6]
  local a21, a22, a23, a24, a25, a26 = Z[b2 + 7], Z[b2 + 8], Z[b2 + 9], Z[b2 + 10], Z[b2 + 11],
    Z[b2 + 12]
  local a31, a32, a33, a34, a35, a36 = Z[b2 + 13], Z[b2 + 14], Z[b2 + 15], Z[b2 + 16],
    Z[b2 + 17], Z[b2 + 18]
  local a41, a42, a43, a44, a45, a46 = Z[b2 + 19], Z[b2 + 20], Z[b2 + 21], Z[b2 + 22],
    Z[b2 + 23], Z[b2 + 24]
  local a51, a52, a53, a54, a55, a56 = Z[b2 + 25], Z[b2 + 26], Z[b2 + 27], Z[b2 + 28],
    Z[b2 + 29], Z[b2 + 30]
  local a61, a62, a63, a64, a65, a66 = Z[b2 + 31], Z[b2 + 32], Z[b2 + 33], Z[b2 + 34],
    Z[b2 + 35], Z[b2 + 36]
  for r = 1, 6 do
    local z1, z2, z3 = Z[bo + r], Z[bo + 6 + r], Z[bo + 12 + r]
    local z4, z5, z6 = Z[bo + 18 + r], Z[bo + 24 + r], Z[bo + 30 + r]
    local s1 = z1 * a11 + z2 * a21 + z3 * a31 + z4 * a41 + z5 * a51 + z6 * a61
    local s2 = z1 * a12 + z2 * a22 + z3 * a32 + z4 * a42 + z5 * a52 + z6 * a62
    local s3 = z1 * a13 + z2 * a23 + z3 * a33 + z4 * a43 + z5 * a53 + z6 * a63
    local s4 = z1 * a14 + z2 * a24 + z3 * a34 + z4 * a44 + z5 * a54 + z6 * a64
    local s5 = z1 * a15 + z2 * a25 + z3 * a35 + z4 * a45 + z5 * a55 + z6 * a65
    local s6 = z1 * a16 + z2 * a26 + z3 * a36 + z4 * a46 + z5 * a56 + z6 * a66
    if base >= base2 then
      local x = (base + r - 1) * n + base2
      SR[x + 1], SR[x + 2], SR[x + 3] = SR[x + 1] - s1, SR[x + 2] - s2, SR[x + 3] - s3
      SR[x + 4], SR[x + 5], SR[x + 6] = SR[x + 4] - s4, SR[x + 5] - s5, SR[x + 6] - s6
    else
      local y = base2 * n + base + r
      SR[y] = SR[y] - s1
      SR[y + n] = SR[y + n] - s2
      SR[y + 2 * n] = SR[y + 2 * n] - s3
      SR[y + 3 * n] = SR[y + 3 * n] - s4
      SR[y + 4 * n] = SR[y + 4 * n] - s5
      SR[y + 5 * n] = SR[y + 5 * n] - s6
    end
  end
end

-- Add Z_oᵀ q (q the six numbers from v[vo + 1]) to rhs from base + 1.
local function add_projected(Z, bo, v, vo, base)
  local q1, q2, q3, q4, q5, q6 = v[vo + 1], v[vo + 2], v[vo + 3], v[vo + 4], v[vo + 5],
    v[vo + 6]
  for c = 1, 6 do
    rhs[base + c] = rhs[base + c] + q1 * Z[bo + c] + q2 * Z[bo + 6 + c] + q3 * Z[bo + 12 + c]
      + q4 * Z[bo + 18 + c] + q5 * Z[bo + 24 + c] + q6 * Z[bo + 30 + c]
  end
end

-- Add Z_o q (q the six numbers from v[vo + 1]) to out from go + 1.
local function add_product(Z, bo, v, vo, out, go)
  for r = 1, 6 do
    local s = 0
    for c = 1, 6 do s = s + Z[bo + (r - 1) * 6 + c] * v[vo + c] end
    out[go + r] = out[go + r] + s
  end
end

-- Block i of the side eliminated (upper triangles in `blocks`, gradients in `g`), damped by f,
-- factored into L at 36(i - 1), and its gradient forward-substituted into zf at 6(i - 1): the
-- start of either elimination. False when the block is not positive definite.
local function factor(blocks, g, i, f, L)
  local lo, go = 36 * (i - 1), 6 * (i - 1)
  if not cholesky6(blocks, 21 * (i - 1), f, L, lo) then return false end
  for k = 1, 6 do zf[go + k] = g[go + k] end
  forward6(L, lo, zf, go, 1)
  return true
end

-- The damped blocks (upper triangles in `blocks`, gradients in `g`) of the side kept into the
-- reduced system (order n): block j at slot(j) (0: not in it).
local function kept_blocks(blocks, g, count, slot, f, n)
  for k = 1, n * n do SR[k] = 0 end
  for k = 1, n do rhs[k] = 0 end
  for j = 1, count do
    local a = slot and slot[j] or j
    if a > 0 then
      local base, bj = 6 * (a - 1), 21 * (j - 1)
      for k = 1, 21 do
        local rc = UPPER[k]
        local v = blocks[bj + k]
        if rc[1] == rc[2] then v = v * f end
        SR[(base + rc[1] - 1) * n + base + rc[2]] = v
        SR[(base + rc[2] - 1) * n + base + rc[1]] = v
      end
      for k = 1, 6 do rhs[base + k] = -g[6 * (j - 1) + k] end
    end
  end
end

-- Frames eliminated.

-- Frame fi eliminated: its damped block factored into P.inv, its Z blocks into P.Z, z into
-- zf; ZᵀZ and Zᵀz into the reduced system (order n). False when the block is not positive
-- definite.
local function eliminate_frame(P, fi, f, n)
  local B, L, Z, free, ot = P.B, P.inv, P.Z, P.free, P.ot
  local lo, go = 36 * (fi - 1), 6 * (fi - 1)
  if not factor(P.A, P.gA, fi, f, L) then return false end
  local first, last = P.first[fi], P.last[fi]
  for o = first, last do
    local bo = 36 * (o - 1)
    for k = 1, 36 do Z[bo + k] = B[bo + k] end
    for c = 1, 6 do forward6(L, lo, Z, bo + c - 6, 6) end
    local a = free[ot[o]]
    if a > 0 then
      local base = 6 * (a - 1)
      add_projected(Z, bo, zf, go, base)
      for o2 = first, o do
        local a2 = free[ot[o2]]
        if a2 > 0 then subtract_pair(Z, bo, 36 * (o2 - 1), base, 6 * (a2 - 1), n) end
      end
    end
  end
  return true
end

-- The frames' steps from the tags': δx_f = -L⁻ᵀ(z + Z·δy).
local function back_frames(P, y, x)
  local L, Z, ot = P.inv, P.Z, P.ot
  for fi = 1, P.nframes do
    local go = 6 * (fi - 1)
    for k = 1, 6 do x[go + k] = zf[go + k] end
    for o = P.first[fi], P.last[fi] do
      add_product(Z, 36 * (o - 1), y, 6 * (ot[o] - 1), x, go)
    end
    backward6(L, 36 * (fi - 1), x, go, 1)
    for k = 1, 6 do x[go + k] = -x[go + k] end
  end
end

local function step_frames(P, f, D)
  local m = 0
  for i = 1, P.ntags do
    if P.free[i] > m then m = P.free[i] end
  end
  local n = 6 * m
  kept_blocks(P.C, P.gC, P.ntags, P.free, f, n)
  for fi = 1, P.nframes do
    if not eliminate_frame(P, fi, f, n) then return false end
  end
  if not solve_reduced(n) then return false end
  local free, y = P.free, D.y
  for i = 1, P.ntags do
    local a = free[i]
    for k = 1, 6 do y[6 * (i - 1) + k] = a > 0 and rhs[6 * (a - 1) + k] or 0 end
  end
  back_frames(P, y, D.x)
  return true
end

-- Tags eliminated.

-- Subtract Z_oᵀ Z_o2 from block (f(o), f(o2)) of the reduced system over the frames (order
-- n), for o and each earlier observation o2 of its tag (seen[first .. s - 1], whose frames
-- come before o's: lower-triangle blocks), and Z_oᵀ Z_o from its diagonal block. Z_o's 36
-- numbers stay in locals over the pairs (these products are most of a step).
local function subtract_row(Z, bo, seen, first, s, of, base, n)
  local z11, z12, z13, z14, z15, z16 =
    Z[bo + 1], Z[bo + 2], Z[bo + 3], Z[bo + 4], Z[bo + 5], Z[bo + 6]
  local z21, z22, z23, z24, z25, z26 =
    Z[bo + 7], Z[bo + 8], Z[bo + 9], Z[bo + 10], Z[bo + 11], Z[bo + 12]
  local z31, z32, z33, z34, z35, z36 =
    Z[bo + 13], Z[bo + 14], Z[bo + 15], Z[bo + 16], Z[bo + 17], Z[bo + 18]
  local z41, z42, z43, z44, z45, z46 =
    Z[bo + 19], Z[bo + 20], Z[bo + 21], Z[bo + 22], Z[bo + 23], Z[bo + 24]
  local z51, z52, z53, z54, z55, z56 =
    Z[bo + 25], Z[bo + 26], Z[bo + 27], Z[bo + 28], Z[bo + 29], Z[bo + 30]
  local z61, z62, z63, z64, z65, z66 =
    Z[bo + 31], Z[bo + 32], Z[bo + 33], Z[bo + 34], Z[bo + 35], Z[bo + 36]
  for s2 = first, s do
    local o2 = seen[s2]
    local b2, base2 = 36 * (o2 - 1), 6 * (of[o2] - 1)
    for c = 1, 6 do
      local a1, a2, a3 = Z[b2 + c], Z[b2 + 6 + c], Z[b2 + 12 + c]
      local a4, a5, a6 = Z[b2 + 18 + c], Z[b2 + 24 + c], Z[b2 + 30 + c]
      local x = base * n + base2 + c
      SR[x] = SR[x] - (z11 * a1 + z21 * a2 + z31 * a3 + z41 * a4 + z51 * a5 + z61 * a6)
      SR[x + n] = SR[x + n] - (z12 * a1 + z22 * a2 + z32 * a3 + z42 * a4 + z52 * a5 + z62 * a6)
      SR[x + 2 * n] = SR[x + 2 * n] - (z13 * a1 + z23 * a2 + z33 * a3
        + z43 * a4 + z53 * a5 + z63 * a6)
      SR[x + 3 * n] = SR[x + 3 * n] - (z14 * a1 + z24 * a2 + z34 * a3
        + z44 * a4 + z54 * a5 + z64 * a6)
      SR[x + 4 * n] = SR[x + 4 * n] - (z15 * a1 + z25 * a2 + z35 * a3
        + z45 * a4 + z55 * a5 + z65 * a6)
      SR[x + 5 * n] = SR[x + 5 * n] - (z16 * a1 + z26 * a2 + z36 * a3
        + z46 * a4 + z56 * a5 + z66 * a6)
    end
  end
end


-- Each tag's observations (P.ot never changes): P.seen_first[i] .. P.seen_first[i + 1] - 1
-- index P.seen, in frame order.
local function observations_of_tags(P)
  if P.seen then return end
  local count, first, seen = {}, {}, {}
  for i = 1, P.ntags + 1 do count[i] = 0 end
  for o = 1, #P.ot do count[P.ot[o]] = count[P.ot[o]] + 1 end
  first[1] = 1
  for i = 1, P.ntags do first[i + 1] = first[i] + count[i] end
  for i = 1, P.ntags do count[i] = first[i] end
  for o = 1, #P.ot do
    local i = P.ot[o]
    seen[count[i]] = o
    count[i] = count[i] + 1
  end
  P.seen, P.seen_first = seen, first
end

-- Free tag i eliminated: its damped block factored into P.inv, W = L⁻¹Bᵀ of each of its
-- observations into P.Z, w = L⁻¹g into zf; WᵀW and Wᵀw into the reduced system over the
-- frames (order n). False when the block is not positive definite.
local function eliminate_tag(P, i, f, n)
  local B, L, Z, of, seen = P.B, P.inv, P.Z, P.of, P.seen
  local lo, go = 36 * (i - 1), 6 * (i - 1)
  if not factor(P.C, P.gC, i, f, L) then return false end
  local first, last = P.seen_first[i], P.seen_first[i + 1] - 1
  for s = first, last do
    local o = seen[s]
    local bo = 36 * (o - 1)
    for r = 1, 6 do
      for c = 1, 6 do Z[bo + (c - 1) * 6 + r] = B[bo + (r - 1) * 6 + c] end
    end
    for c = 1, 6 do forward6(L, lo, Z, bo + c - 6, 6) end
    local base = 6 * (of[o] - 1)
    add_projected(Z, bo, zf, go, base)
    subtract_row(Z, bo, seen, first, s, of, base, n)
  end
  return true
end

-- The tags' steps from the frames': δy_i = -L⁻ᵀ(w + W·δx), the reference's zero.
local function back_tags(P, x, y)
  local L, Z, of, seen = P.inv, P.Z, P.of, P.seen
  for i = 1, P.ntags do
    local go = 6 * (i - 1)
    if P.free[i] == 0 then
      for k = 1, 6 do y[go + k] = 0 end
    else
      for k = 1, 6 do y[go + k] = zf[go + k] end
      for s = P.seen_first[i], P.seen_first[i + 1] - 1 do
        local o = seen[s]
        add_product(Z, 36 * (o - 1), x, 6 * (of[o] - 1), y, go)
      end
      backward6(L, go * 6, y, go, 1)
      for k = 1, 6 do y[go + k] = -y[go + k] end
    end
  end
end

local function step_tags(P, f, D)
  observations_of_tags(P)
  local n = 6 * P.nframes
  kept_blocks(P.A, P.gA, P.nframes, nil, f, n)
  for i = 1, P.ntags do
    if P.free[i] > 0 and not eliminate_tag(P, i, f, n) then return false end
  end
  if not solve_reduced(n) then return false end
  local x = D.x
  for k = 1, n do x[k] = rhs[k] end
  back_tags(P, x, D.y)
  return true
end

--- The side whose elimination costs fewer floating-point operations for a problem (from its
-- observations' frames and tags, which never change): `"frames"` or `"tags"`.
-- @tparam table P the problem
-- @treturn string
function M.order(P)
  local per_frame, per_tag, free = {}, {}, P.free
  for o = 1, #P.of do
    if free[P.ot[o]] > 0 then
      per_frame[P.of[o]] = (per_frame[P.of[o]] or 0) + 1
      per_tag[P.ot[o]] = (per_tag[P.ot[o]] or 0) + 1
    end
  end
  local nt, nf = 0, P.nframes
  for i = 1, P.ntags do
    if free[i] > 0 then nt = nt + 1 end
  end
  -- the pairs of blocks taken out (216 each), the reduced system's Cholesky and its zeroing
  local frames, tags = 0, 0
  for _, k in pairs(per_frame) do frames = frames + 108 * k * (k + 1) end
  for _, k in pairs(per_tag) do tags = tags + 108 * k * (k + 1) end
  frames = frames + (6 * nt) ^ 3 / 6 + 2 * ((6 * nt) * (6 * nt))
  tags = tags + (6 * nf) ^ 3 / 6 + 2 * ((6 * nf) * (6 * nf))
  return tags < frames and "tags" or "frames"
end

--- The damped step from the normal equations of `tagpose.layout.bundle.linearise`.
-- @tparam table P the problem; `P.eliminate` (`"frames"` or `"tags"`, set by the first step
--   from `order` when nil) is the side eliminated
-- @tparam number lambda the damping (the diagonal is multiplied by `1 + lambda`)
-- @tparam table D the step to fill: `D.x` (6 per frame: δθ, δτ), `D.y` (6 per tag: δφ, δp;
--   zero for the reference)
-- @treturn boolean false when the damped system is not positive definite
function M.step(P, lambda, D)
  P.eliminate = P.eliminate or M.order(P)
  if P.eliminate == "tags" then return step_tags(P, 1 + lambda, D) end
  return step_frames(P, 1 + lambda, D)
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

return M
