-- The table of tagpose.uncertainty: the planar ambiguity's tilt-plane model integrated
-- numerically (docs/uncertainty.md derives it).
--
--   luajit bench/uncertainty_table.lua [NR NPHI]     (lua5.4 works too, ~10x slower)
--
-- Prints the Lua table that src/tagpose/uncertainty/model.lua holds as TABLE. The model: in the
-- tag's tilt plane (the normal's component across the line of sight, a = (x, y), one candidate at
-- x > 0, the other at x < 0), after scale and roll are taken out, the corners measure the
-- traceless part of a aᵀ; with the perspective's small odd part as a linear tilt,
--
--     χ²(x, y) = K [(|a|² - 1)² + 4 y²] - λ x,        prior density ∝ 1 / |a|
--
-- (the tilt angle uniform a priori). For each candidate's own observables -- d², its separation
-- from the other along the tilt in its own marginal standard deviations, and Δc, the other's χ²
-- minus its own -- (K, λ) is solved for, and the posterior over the candidate's half plane (the
-- points nearer it than the other) integrated on a polar grid (NR x NPHI, default 500 x 1440):
--
--   φ  = ln(basin mass / its Laplace approximation at the minimum, prior included)
--   v  = the factor on the variance along the tilt that makes the 6-dof 95 % ellipsoid hold
--        95 % of the basin's mass (the tilt marginal from the grid, the five other
--        coordinates Gaussian: P(u²/v + χ²₅ < 12.59) = 0.95)
--
-- Rows: log2 d² = 0, 0.5, ..., 12; columns: w = -0.75, -0.625, ..., 0.75 with
-- Δc = 8 w / (1 - |w|) (-24 .. 24, finer near 0); a Δc beyond what the model allows for that d²
-- (the other minimum would vanish) is clamped to the limit.

local exp, sqrt, log, cos, sin, pi = math.exp, math.sqrt, math.log, math.cos, math.sin, math.pi
local NR, NPHI = tonumber(arg[1] or "500"), tonumber(arg[2] or "1440")
local LEVEL, Q6 = 0.95, 12.591587243743977 -- chi-square 95 % quantile, 6 dof

local function chi2(K, lam, x, y)
  local r2 = x * x + y * y
  return K * ((r2 - 1) ^ 2 + 4 * y * y) - lam * x
end

-- the minimum on the x axis near x0 (Newton on d/dx [K (x² - 1)² - λ x])
local function minimum(K, lam, x0)
  local x = x0
  for _ = 1, 100 do
    x = x - (4 * K * x * (x * x - 1) - lam) / (4 * K * (3 * x * x - 1))
  end
  return x
end

-- the observables of the candidate at x > 0: d² = (xA - xB)² h_xx(A) and Δc = χ²(B) - χ²(A)
local function observe(K, lam)
  local xA, xB = minimum(K, lam, 1.5), minimum(K, lam, -1.5)
  if not (xA > 0.5774 and xB < -0.5774) then return nil end
  local hx = 0.5 * K * (12 * xA * xA - 4)
  return (xA - xB) ^ 2 * hx, chi2(K, lam, xB, 0) - chi2(K, lam, xA, 0), xA, xB, hx
end

-- (K, λ) with observables (D, c), by damped Newton; nil when there is none
local function invert(D, c)
  local K, lam = (D - 3 * c) / 16, c / 2
  if K <= 0 then K = D / 64 end
  for _ = 1, 100 do
    local d, dc = observe(K, lam)
    if not d then return nil end
    local e1, e2 = d - D, dc - c
    if math.abs(e1) < 1e-11 * D and math.abs(e2) < 1e-11 * (1 + math.abs(c)) then
      return K, lam
    end
    local hK, hl = 1e-6 * K, 1e-6 * (math.abs(lam) + K)
    local d1, c1 = observe(K + hK, lam)
    local d2, c2 = observe(K, lam + hl)
    if not (d1 and d2) then return nil end
    local a, b, cc, dd = (d1 - d) / hK, (d2 - d) / hl, (c1 - dc) / hK, (c2 - dc) / hl
    local det = a * dd - b * cc
    local sK, sl = -(dd * e1 - b * e2) / det, -(-cc * e1 + a * e2) / det
    local f = 1
    while f > 1e-4 do
      local nK, nl = K + f * sK, lam + f * sl
      if nK > 0 and observe(nK, nl) then
        K, lam = nK, nl
        break
      end
      f = f * 0.5
    end
    if f <= 1e-4 then return nil end
  end
  return nil
end

-- the largest |Δc| of sign `sign` the model allows at d² = D
local function limit(D, sign)
  local lo, hi = 0, 1
  while invert(D, sign * hi) and hi < 1e4 do lo, hi = hi, hi * 2 end
  for _ = 1, 40 do
    local m = 0.5 * (lo + hi)
    if invert(D, sign * m) then lo = m else hi = m end
  end
  return lo
end

-- regularised lower incomplete gamma P(k/2, x/2): the chi-square CDF with k dof
local function chi2_cdf(x, k)
  if x <= 0 then return 0 end
  local a, z = k / 2, x / 2
  local term = 1 / a
  local sum = term
  for n = 1, 500 do
    term = term * z / (a + n)
    sum = sum + term
    if term < 1e-16 * sum then break end
  end
  local lg = 0 -- ln Γ(a), a integer or half-integer
  if a == math.floor(a) then
    for i = 2, a - 1 do lg = lg + log(i) end
  else
    lg = log(sqrt(pi))
    local v = 0.5
    while v < a - 0.25 do
      lg = lg + log(v)
      v = v + 1
    end
  end
  return exp(a * log(z) - z - lg) * sum
end

-- φ and v of the candidate at x > 0 of the model (K, λ)
local function integrate(K, lam)
  local _, _, xA, xB, hx = observe(K, lam)
  local hy = 0.5 * K * (4 * (xA * xA - 1) + 8)
  local cA = chi2(K, lam, xA, 0)
  local xm = 0.5 * (xA + xB)
  local rmax = math.max(xA, -xB) + 16 / sqrt(8 * K)
  local dr, dphi = rmax / NR, 2 * pi / NPHI
  -- the basin's mass and its tilt marginal, u = (x - xA) sqrt(hx), in bins of DU
  local DU = 0.02
  local hist, Z = {}, 0
  local sx = sqrt(hx)
  for i = 0, NR - 1 do
    local r = (i + 0.5) * dr
    for j = 0, NPHI - 1 do
      local ph = (j + 0.5) * dphi
      local x, y = r * cos(ph), r * sin(ph)
      if x > xm then
        -- prior 1/r times the area element r dr dφ
        local p = exp(-(chi2(K, lam, x, y) - cA) / 2)
        Z = Z + p
        local k = math.floor((x - xA) * sx / DU + 0.5)
        hist[k] = (hist[k] or 0) + p
      end
    end
  end
  local mass = Z * dr * dphi
  local laplace = 2 * pi / sqrt(hx * hy) / xA
  local function cover(v)
    local s = 0
    for k, p in pairs(hist) do
      local u = k * DU
      s = s + p * chi2_cdf(Q6 - u * u / v, 5)
    end
    return s / Z
  end
  local lo, hi = 0.05, 400
  local v
  if cover(hi) < LEVEL then
    v = hi
  elseif cover(lo) > LEVEL then
    v = lo
  else
    for _ = 1, 50 do
      local m = sqrt(lo * hi)
      if cover(m) < LEVEL then lo = m else hi = m end
    end
    v = sqrt(lo * hi)
  end
  return log(mass / laplace), v
end

local W = {}
for j = -6, 6 do W[#W + 1] = j / 8 end
print("-- generated by bench/uncertainty_table.lua " .. NR .. " " .. NPHI
  .. ": rows log2 d2 = 0 (0.5) 12; per row, for w = -0.75 (0.125) 0.75, phi and v")
print("local TABLE = {")
for i = 0, 24 do
  local D = 2 ^ (0.5 * i)
  local hi, lo = 0.995 * limit(D, 1), -0.995 * limit(D, -1)
  local cells = {}
  for _, w in ipairs(W) do
    local c = 8 * w / (1 - math.abs(w))
    c = math.max(lo, math.min(hi, c))
    local K, lam = invert(D, c)
    assert(K, "no model for d2 " .. D .. ", dc " .. c)
    local phi, v = integrate(K, lam)
    cells[#cells + 1] = ("%.4f, %.4f"):format(phi, v)
  end
  print(("  { %s }, -- d2 = %g"):format(table.concat(cells, ", "), D))
end
print("}")
