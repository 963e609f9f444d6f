--- Real roots of small polynomials: `c[1] + c[2] y + ... + c[n + 1] y^n`, degree at most 6.
--
-- Degrees 1 and 2 in closed form (the quadratic without cancellation). Above, the roots of the
-- derivative (found the same way, one degree lower) split the line into intervals where the
-- polynomial is monotone; each interval with a sign change holds exactly one root, found by
-- bisection safeguarded Newton, and a critical point where the polynomial vanishes to
-- round-off is a double root. Scratch arrays per degree, so nothing is allocated. Used by
-- solveQuad's safeguard (a quartic) and by the lens models' one-to-one region.
-- @module tagpose.core.poly

local abs, sqrt, max = math.abs, math.sqrt, math.max
local huge = math.huge

local M = {}

local deriv = { {}, {}, {}, {}, {}, {}, {} } -- deriv[n]: the derivative of a degree-n polynomial
local crit = { {}, {}, {}, {}, {}, {}, {} } -- crit[n]: the roots of that derivative

--- The value of the degree-n polynomial c at y (Horner).
-- @tparam {number,...} c coefficients, constant first
-- @tparam int n degree
-- @tparam number y
-- @treturn number
function M.value(c, n, y)
  local v = c[n + 1]
  for k = n, 1, -1 do
    v = v * y + c[k]
  end
  return v
end

-- The real roots of a c[3] x² + c[2] x + c[1] (c[3] not 0), ascending, into out; their count.
local peval = M.value

local function quadratic_roots(c, out)
  local a, b, cc = c[3], c[2], c[1]
  local disc = b * b - 4 * a * cc
  if disc < 0 then
    -- a (near-)double root just lost to round-off still counts as one
    if disc < -1e-14 * b * b then return 0 end
    disc = 0
  end
  local s = sqrt(disc)
  local t = -0.5 * (b + (b >= 0 and s or -s))
  if t == 0 then
    out[1] = 0
    return 1
  end
  local r1, r2 = t / a, cc / t
  if r1 > r2 then r1, r2 = r2, r1 end
  out[1], out[2] = r1, r2
  return 2
end

-- The one root of the degree-n polynomial c in (a, b), where it changes sign (pa its value at
-- a; d its derivative): bisection with Newton steps where they stay inside.
local function bracketed_root(c, d, n, a, b, pa)
  local y = 0.5 * (a + b)
  for _ = 1, 100 do
    local p = peval(c, n, y)
    if p == 0 then break end
    if (p < 0) == (pa < 0) then a, pa = y, p else b = y end
    local dp = peval(d, n - 1, y)
    local ny = dp ~= 0 and y - p / dp or a
    if not (ny > a and ny < b) then ny = 0.5 * (a + b) end
    if abs(ny - y) <= 1e-15 * max(1, abs(y)) then
      y = ny
      break
    end
    y = ny
  end
  return y
end

--- The real roots of a polynomial of degree at most 6, ascending.
-- @tparam {number,...} c coefficients `c[1] + c[2] y + ... + c[n + 1] y^n`
-- @tparam int n degree (leading coefficients that vanish relative to the largest are dropped)
-- @tparam {number,...} out array to fill with the roots
-- @treturn int how many
function M.roots(c, n, out)
  local scale = 0
  for k = 1, n + 1 do
    scale = max(scale, abs(c[k]))
  end
  if not (scale > 0 and scale < huge) then return 0 end
  while n > 0 and abs(c[n + 1]) <= 1e-14 * scale do
    n = n - 1
  end
  if n == 0 then return 0 end
  if n == 1 then
    out[1] = -c[1] / c[2]
    return 1
  end
  if n == 2 then return quadratic_roots(c, out) end
  -- degree 3 to 6: isolate by the critical points
  local d, cp = deriv[n], crit[n]
  for k = 1, n do
    d[k] = k * c[k + 1]
  end
  local nc = M.roots(d, n - 1, cp)
  local bound = 0
  for k = 1, n do
    bound = max(bound, abs(c[k] / c[n + 1]))
  end
  bound = 1 + bound
  local count = 0
  local lo = -bound
  local plo = peval(c, n, lo)
  for i = 1, nc + 1 do
    local hi = i <= nc and cp[i] or bound
    if hi > lo then
      local phi = peval(c, n, hi)
      if plo == 0 then
        if count == 0 or out[count] ~= lo then
          count = count + 1
          out[count] = lo
        end
      elseif (plo < 0) ~= (phi < 0) and phi ~= 0 then
        count = count + 1
        out[count] = bracketed_root(c, d, n, lo, hi, plo)
      elseif i <= nc and abs(phi) <= 1e-12 * scale * max(1, abs(hi)) ^ n then
        -- a double root at a critical point
        count = count + 1
        out[count] = hi
      end
      lo, plo = hi, phi
    end
  end
  return count
end


return M
