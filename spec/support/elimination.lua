-- Small dense linear solves on flat arrays, by the textbook methods: the oracles against which
-- the specs check the library's closed forms and unrolled kernels (tagpose.square,
-- tagpose.lsq.spd6; tagpose.linsolve.cholesky). Not part of the library.
--
-- Matrices are flat, row-major and 1-based: entry (i, j) of an `n`-column matrix is
-- `a[(i - 1) * n + j]`. Right-hand sides are flat too: `nrhs` columns, entry (i, k) at
-- `b[(i - 1) * nrhs + k]`. Both are overwritten in place (the solution is left in `b`), so a
-- caller passes scratch arrays it owns and nothing is allocated here.
--
-- A singular or numerically singular system is reported with `nil, message`; it is never
-- divided through.

local abs = math.abs

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
      return nil, "elimination: matrix is not finite"
    end
  end
  if not (scale < math.huge) then return nil, "elimination: matrix is not finite" end
  if scale == 0 then return nil, "elimination: matrix is singular" end
  local limit = tol * scale
  for k = 1, n do
    -- choose the row with the largest pivot in column k
    local p, best = k, abs(a[(k - 1) * n + k])
    for i = k + 1, n do
      local v = abs(a[(i - 1) * n + k])
      if v > best then p, best = i, v end
    end
    if not (best > limit) then return nil, "elimination: matrix is singular" end
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

return M
