-- The factors of tagpose.uncertainty's ELLIPSOID: how much wider a covariance whose σ² was
-- estimated must be for its 6-dof 95 % ellipsoid to hold 95 % of the pose's errors
-- (docs/uncertainty.md, "The default σ", derives it).
--
--   lua5.4 bench/ellipsoid_table.lua [MAX_DOF]      (default 40; prints the Lua table)
--
-- Without options.sigma, σ² comes from the residuals of the frame's fits, ν degrees of freedom
-- (2 per tag alone, 8k - 6 for a fit of k tags), topped up with the default to
-- T = DEFAULT_DOF + 2 degrees of freedom when ν is short of it:
--
--     s² = ((T - ν)₊ σ₀² + SSE) / max(T, ν),        SSE ~ σ² χ²_ν.
--
-- The pose's error e, given σ, is N(0, σ² H⁻¹); the covariance reported is κ s² H⁻¹, and the
-- error is inside its 95 % ellipsoid when eᵀ H e / s² < κ q₀, q₀ = χ²₆(0.95) = 12.59. With
-- M² = eᵀ H e / σ² ~ χ²₆ independent of SSE (least squares: the residuals are orthogonal to
-- the fit), and σ = σ₀ where the default fills in (ν < T; for ν ≥ T no σ₀ is involved and this
-- holds for every σ):
--
--     P(χ²₆ < κ q₀ ((T - ν)₊ + χ²_ν) / max(T, ν)) = 0.95.
--
-- For ν ≥ T this is the F distribution's quantile, κ = 6 F₆,ν(0.95) / q₀: Student's t of the
-- σ estimated from ν degrees of freedom, in six dimensions. The probability has a closed form
-- for any ν: with c = κ q₀ / max(T, ν), a = (T - ν)₊, Y ~ χ²_ν = Gamma(ν/2, scale 2), and
-- P(χ²₆ < x) = 1 - e^(-x/2) (1 + x/2 + x²/8),
--
--     E[e^(-wY) Y^m] = (ν/2)(ν/2 + 1)...(ν/2 + m - 1) 2^m (1 + 2w)^-(ν/2 + m),
--
-- so each factor is a bisection on a sum of three terms. Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local uncertainty = require("tagpose.uncertainty")

local exp = math.exp
local Q6 = 12.591587243743977 -- chi-square 95 % quantile, 6 dof
local LEVEL = 0.95
local T = uncertainty.DEFAULT_DOF + 2
local MAX_DOF = tonumber(arg[1] or "40")

-- P(error inside the ellipsoid) for the factor kappa and ν degrees of freedom
local function coverage(kappa, nu)
  local a = math.max(T - nu, 0)
  local c = kappa * Q6 / math.max(T, nu)
  local k, u, w = 0.5 * nu, 0.5 * c * a, 0.5 * c
  -- 1 + z + z²/2 with z = u + w Y: constant, linear and quadratic coefficients in Y
  local c0, c1, c2 = 1 + u + 0.5 * u * u, (1 + u) * w, 0.5 * w * w
  local base = 1 + 2 * w
  local m0 = base ^ -k
  local m1 = k * 2 * base ^ -(k + 1)
  local m2 = k * (k + 1) * 4 * base ^ -(k + 2)
  return 1 - exp(-u) * (c0 * m0 + c1 * m1 + c2 * m2)
end

local function factor(nu)
  local lo, hi = 0.5, 50
  for _ = 1, 200 do
    local mid = 0.5 * (lo + hi)
    if coverage(mid, nu) < LEVEL then lo = mid else hi = mid end
  end
  return 0.5 * (lo + hi)
end

local out = {}
for nu = 2, MAX_DOF, 2 do out[#out + 1] = ("%.4f"):format(factor(nu)) end
print(("-- ν = 2, 4, ..., %d (T = %d)"):format(MAX_DOF, T))
local line = "local ELLIPSOID = { "
for i, s in ipairs(out) do
  local piece = s .. (i < #out and ", " or " }")
  if #line + #piece > 98 then
    print((line:gsub(" $", "")))
    line = "  "
  end
  line = line .. piece
end
print(line)
-- the tail, ν > MAX_DOF: κ - 1 falls as 1/ν (first order in 1/ν: (q₀ - 4) / (2ν) for p = 6)
for _, nu in ipairs({ 2 * MAX_DOF, 4 * MAX_DOF }) do
  local exact = factor(nu)
  local tail = 1 + (factor(MAX_DOF) - 1) * MAX_DOF / nu
  print(("-- check ν = %d: exact %.4f, tail %.4f"):format(nu, exact, tail))
end
