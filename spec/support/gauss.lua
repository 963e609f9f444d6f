-- Gaussian checks for the covariance specs: Cholesky, Mahalanobis², positive definiteness, and
-- the error of a pose against the truth in the covariance's order. Not part of the library.
local rotation = require("tagpose.core.rotation")

local sqrt, abs, huge = math.sqrt, math.abs, math.huge

local M = {}

--- Cholesky of a nested n×n matrix: the factor, or nil when not positive definite.
function M.cholesky(C, n)
  local L = {}
  for i = 1, n do L[i] = {} end
  for j = 1, n do
    local d = C[j][j]
    for k = 1, j - 1 do d = d - L[j][k] ^ 2 end
    if not (d > 0) then return nil end
    L[j][j] = sqrt(d)
    for i = j + 1, n do
      local s = C[i][j]
      for k = 1, j - 1 do s = s - L[i][k] * L[j][k] end
      L[i][j] = s / L[j][j]
    end
  end
  return L
end

--- eᵀ C⁻¹ e over the first #e rows and columns of C (by the Cholesky factor).
function M.mahalanobis(C, e)
  local L = assert(M.cholesky(C, #e), "covariance not positive definite")
  local y, m = {}, 0
  for i = 1, #e do
    local s = e[i]
    for k = 1, i - 1 do s = s - L[i][k] * y[k] end
    y[i] = s / L[i][i]
    m = m + y[i] * y[i]
  end
  return m
end

--- Is C a finite, symmetric, positive definite n×n (default 6) matrix?
function M.is_spd(C, n)
  n = n or 6
  for i = 1, n do
    for j = 1, n do
      local v = C[i][j]
      if not (v == v and abs(v) < huge and v == C[j][i]) then return false end
    end
  end
  return M.cholesky(C, n) ~= nil
end

--- The error of a pose table against the truth (flat rotation rt, position tt), in the
-- covariance's order: (t_true - t, r) with R_true = exp([r]×) R.
function M.error_of(p, rt, tt)
  local r = rotation.from_nested(p.rotation)
  local w, x, y, z = rotation.to_quaternion(rotation.multiply_transpose(rt, r))
  local s = sqrt(x * x + y * y + z * z)
  local f = s > 1e-12 and 2 * math.atan(s / w) / s or 2
  local q = p.position
  return { tt[1] - q.x, tt[2] - q.y, tt[3] - q.z, f * x, f * y, f * z }
end

return M
