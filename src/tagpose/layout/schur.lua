--- The damped step of the bundle adjustment (`tagpose.layout.bundle`), with every frame's six
-- unknowns eliminated (Schur complement).
--
-- The step solves `(H + λ·diag H) δ = -g`. With `A_f` a frame's block, `B_fi` its coupling to
-- tag `i` and `C` the tags' block, the reduced system over the tags is
-- `(C - Σ_f B_fᵀ A_f⁻¹ B_f) δy = -g_y + Σ_f B_fᵀ A_f⁻¹ g_f`, of order 6·(tags - 1) (the
-- reference is held), built in time linear in the frames: with `A_f = L Lᵀ`, `Z = L⁻¹B` and
-- `z = L⁻¹g_f`, a frame takes `ZᵀZ` from the reduced matrix and adds `Zᵀz` to its right-hand
-- side. The reduced system is scaled to a unit diagonal and solved by Cholesky; then
-- `δx_f = -L⁻ᵀ(z + Z·δy)`.
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

-- Frame fi eliminated: its damped block factored into P.inv, its Z blocks into P.Z, z into
-- zf; ZᵀZ and Zᵀz into the reduced system (order n). False when the block is not positive
-- definite.
local function eliminate(P, fi, f, n)
  local A, gA, B, L, Z, free, ot = P.A, P.gA, P.B, P.inv, P.Z, P.free, P.ot
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
      for o2 = first, o do
        local a2 = free[ot[o2]]
        if a2 > 0 then
          -- Z_oᵀ Z_o2 out of block (a, a2), and out of (a2, a) transposed
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
  return true
end

-- The reduced system (order n) scaled to a unit diagonal and solved: the tags' steps into y.
local function solve_reduced(P, n, y)
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
  local free = P.free
  for i = 1, P.ntags do
    local a = free[i]
    for k = 1, 6 do
      y[6 * (i - 1) + k] = a > 0 and rhs[6 * (a - 1) + k] * scale[6 * (a - 1) + k] or 0
    end
  end
  return true
end

-- The frames' steps from the tags': δx_f = -L⁻ᵀ(z + Z·δy).
local function back_substitute(P, y, x)
  local L, Z, ot = P.inv, P.Z, P.ot
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
end

--- The damped step from the normal equations of `tagpose.layout.bundle.linearise`.
-- @tparam table P the problem
-- @tparam number lambda the damping (the diagonal is multiplied by `1 + lambda`)
-- @tparam table D the step to fill: `D.x` (6 per frame: δθ, δτ), `D.y` (6 per tag: δφ, δp;
--   zero for the reference)
-- @treturn boolean false when the damped system is not positive definite
function M.step(P, lambda, D)
  local f, m = 1 + lambda, 0
  for i = 1, P.ntags do
    if P.free[i] > m then m = P.free[i] end
  end
  local n = 6 * m
  tag_blocks(P, f, n)
  for fi = 1, P.nframes do
    if not eliminate(P, fi, f, n) then return false end
  end
  if not solve_reduced(P, n, D.y) then return false end
  back_substitute(P, D.y, D.x)
  return true
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
