--- Dense symmetric positive definite solves on flat arrays: the reduced systems of the layout
-- calibration's bundle adjustment (`tagpose.layout.schur`), whose order grows with the tags.
--
-- Matrices are flat, row-major and 1-based: entry (i, j) of an `n`-column matrix is
-- `a[(i - 1) * n + j]`. Both the matrix and the right-hand side are overwritten in place (the
-- solution is left in `b`), so the caller passes scratch arrays it owns and nothing is
-- allocated. A matrix that is not positive definite to working precision is reported with
-- `nil, message`; it is never divided through.
-- @module tagpose.layout.linsolve

local sqrt = math.sqrt

local M = {}

--- Default relative pivot threshold: a pivot smaller than this times the largest diagonal entry
-- means the matrix is not positive definite to working precision.
M.SINGULAR = 1e-13

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

return M
