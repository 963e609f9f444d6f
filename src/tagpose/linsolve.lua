--- Small dense linear solves on flat arrays.
--
-- Matrices are flat, row-major and 1-based: entry (i, j) of an `n`-column matrix is
-- `a[(i - 1) * n + j]`. Right-hand sides are flat too: `nrhs` columns, entry (i, k) at
-- `b[(i - 1) * nrhs + k]`. Both are overwritten in place (the solution is left in `b`), so a
-- caller passes scratch arrays it owns and nothing is allocated here.
--
-- A singular or numerically singular system is reported with `nil, message`; it is never
-- divided through.
-- @module tagpose.linsolve

local abs, sqrt = math.abs, math.sqrt

local M = {}

--- Default relative pivot threshold: a pivot smaller than this times the largest entry of the
-- matrix means the matrix is singular to working precision.
M.SINGULAR = 1e-13

--- Solve `a x = b` by Gaussian elimination with partial pivoting (largest magnitude pivot).
-- @tparam int n order of the system
-- @tparam {number,...} a flat n×n matrix, row-major; destroyed
-- @tparam {number,...} b flat n×nrhs right-hand sides, row-major; replaced by the solution
-- @tparam[opt=1] int nrhs number of right-hand side columns
-- @tparam[opt] number tol relative pivot threshold (default `SINGULAR`)
-- @treturn {number,...} `b`, now holding the solution
-- @return nil, string when the matrix is singular to working precision or not finite
function M.solve(n, a, b, nrhs, tol)
  nrhs = nrhs or 1
  tol = tol or M.SINGULAR
  local scale = 0
  for i = 1, n * n do
    local v = abs(a[i])
    if v > scale then
      scale = v
    elseif v ~= v then
      return nil, "linsolve: matrix is not finite"
    end
  end
  if not (scale < math.huge) then return nil, "linsolve: matrix is not finite" end
  if scale == 0 then return nil, "linsolve: matrix is singular" end
  local limit = tol * scale
  for k = 1, n do
    -- choose the row with the largest pivot in column k
    local p, best = k, abs(a[(k - 1) * n + k])
    for i = k + 1, n do
      local v = abs(a[(i - 1) * n + k])
      if v > best then p, best = i, v end
    end
    if not (best > limit) then return nil, "linsolve: matrix is singular" end
    if p ~= k then
      local rk, rp = (k - 1) * n, (p - 1) * n
      for j = k, n do
        a[rk + j], a[rp + j] = a[rp + j], a[rk + j]
      end
      rk, rp = (k - 1) * nrhs, (p - 1) * nrhs
      for j = 1, nrhs do
        b[rk + j], b[rp + j] = b[rp + j], b[rk + j]
      end
    end
    local rk = (k - 1) * n
    local pivot = a[rk + k]
    for i = k + 1, n do
      local ri = (i - 1) * n
      local f = a[ri + k] / pivot
      if f ~= 0 then
        a[ri + k] = 0
        for j = k + 1, n do
          a[ri + j] = a[ri + j] - f * a[rk + j]
        end
        local bi, bk = (i - 1) * nrhs, (k - 1) * nrhs
        for j = 1, nrhs do
          b[bi + j] = b[bi + j] - f * b[bk + j]
        end
      end
    end
  end
  -- back substitution
  for i = n, 1, -1 do
    local ri, bi = (i - 1) * n, (i - 1) * nrhs
    local pivot = a[ri + i]
    for j = 1, nrhs do
      local s = b[bi + j]
      for k = i + 1, n do
        s = s - a[ri + k] * b[(k - 1) * nrhs + j]
      end
      b[bi + j] = s / pivot
    end
  end
  return b
end

--- Solve `a x = b` for a symmetric positive definite `a` by Cholesky factorisation.
-- Only the lower triangle of `a` is read; it is overwritten by the factor.
-- @tparam int n order of the system
-- @tparam {number,...} a flat n×n symmetric matrix, row-major; destroyed
-- @tparam {number,...} b flat right-hand side of length n; replaced by the solution
-- @tparam[opt] number tol relative threshold on the squared pivots (default `SINGULAR`)
-- @treturn {number,...} `b`, now holding the solution
-- @return nil, string when `a` is not positive definite to working precision
function M.cholesky(n, a, b, tol)
  tol = tol or M.SINGULAR
  local scale = 0
  for i = 1, n do
    local v = a[(i - 1) * n + i]
    if v > scale then scale = v end
  end
  if not (scale > 0 and scale < math.huge) then
    return nil, "linsolve: matrix is not positive definite"
  end
  local limit = tol * scale
  for j = 1, n do
    local rj = (j - 1) * n
    local d = a[rj + j]
    for k = 1, j - 1 do
      d = d - a[rj + k] * a[rj + k]
    end
    if not (d > limit) then return nil, "linsolve: matrix is not positive definite" end
    d = sqrt(d)
    a[rj + j] = d
    for i = j + 1, n do
      local ri = (i - 1) * n
      local s = a[ri + j]
      for k = 1, j - 1 do
        s = s - a[ri + k] * a[rj + k]
      end
      a[ri + j] = s / d
    end
  end
  -- forward: L y = b
  for i = 1, n do
    local ri = (i - 1) * n
    local s = b[i]
    for k = 1, i - 1 do
      s = s - a[ri + k] * b[k]
    end
    b[i] = s / a[ri + i]
  end
  -- backward: L^T x = y
  for i = n, 1, -1 do
    local s = b[i]
    for k = i + 1, n do
      s = s - a[(k - 1) * n + i] * b[k]
    end
    b[i] = s / a[(i - 1) * n + i]
  end
  return b
end

--- Solve a 6×6 symmetric positive definite system by an unrolled LDLᵀ factorisation (no square
-- roots), on scalars, so nothing is allocated: the upper triangle `a11, a12, ..., a16, a22, ...,
-- a66` row by row, then the right-hand side `b1..b6`. `e_ij = l_ij · d_j` are kept so each
-- product is formed once.
-- @treturn number x1 .. x6, the solution
-- @return nil when the matrix is not positive definite to working precision (a pivot falls
--   below `SINGULAR` times its own diagonal entry, a test that does not depend on the units of
--   the unknowns)
function M.spd6(a11, a12, a13, a14, a15, a16, a22, a23, a24, a25, a26,
    a33, a34, a35, a36, a44, a45, a46, a55, a56, a66,
    b1, b2, b3, b4, b5, b6)
  local d1 = a11
  if not (d1 > M.SINGULAR * a11) then return nil end
  local e21 = a12
  local l21 = e21 / d1
  local e31 = a13
  local l31 = e31 / d1
  local e41 = a14
  local l41 = e41 / d1
  local e51 = a15
  local l51 = e51 / d1
  local e61 = a16
  local l61 = e61 / d1
  local d2 = a22 - l21 * e21
  if not (d2 > M.SINGULAR * a22) then return nil end
  local e32 = a23 - l31 * e21
  local l32 = e32 / d2
  local e42 = a24 - l41 * e21
  local l42 = e42 / d2
  local e52 = a25 - l51 * e21
  local l52 = e52 / d2
  local e62 = a26 - l61 * e21
  local l62 = e62 / d2
  local d3 = a33 - l31 * e31 - l32 * e32
  if not (d3 > M.SINGULAR * a33) then return nil end
  local e43 = a34 - l41 * e31 - l42 * e32
  local l43 = e43 / d3
  local e53 = a35 - l51 * e31 - l52 * e32
  local l53 = e53 / d3
  local e63 = a36 - l61 * e31 - l62 * e32
  local l63 = e63 / d3
  local d4 = a44 - l41 * e41 - l42 * e42 - l43 * e43
  if not (d4 > M.SINGULAR * a44) then return nil end
  local e54 = a45 - l51 * e41 - l52 * e42 - l53 * e43
  local l54 = e54 / d4
  local e64 = a46 - l61 * e41 - l62 * e42 - l63 * e43
  local l64 = e64 / d4
  local d5 = a55 - l51 * e51 - l52 * e52 - l53 * e53 - l54 * e54
  if not (d5 > M.SINGULAR * a55) then return nil end
  local e65 = a56 - l61 * e51 - l62 * e52 - l63 * e53 - l64 * e54
  local l65 = e65 / d5
  local d6 = a66 - l61 * e61 - l62 * e62 - l63 * e63 - l64 * e64 - l65 * e65
  if not (d6 > M.SINGULAR * a66) then return nil end
  local y1 = b1
  local y2 = b2 - l21 * y1
  local y3 = b3 - l31 * y1 - l32 * y2
  local y4 = b4 - l41 * y1 - l42 * y2 - l43 * y3
  local y5 = b5 - l51 * y1 - l52 * y2 - l53 * y3 - l54 * y4
  local y6 = b6 - l61 * y1 - l62 * y2 - l63 * y3 - l64 * y4 - l65 * y5
  local x6 = y6 / d6
  local x5 = y5 / d5 - l65 * x6
  local x4 = y4 / d4 - l54 * x5 - l64 * x6
  local x3 = y3 / d3 - l43 * x4 - l53 * x5 - l63 * x6
  local x2 = y2 / d2 - l32 * x3 - l42 * x4 - l52 * x5 - l62 * x6
  local x1 = y1 / d1 - l21 * x2 - l31 * x3 - l41 * x4 - l51 * x5 - l61 * x6
  return x1, x2, x3, x4, x5, x6
end

return M
