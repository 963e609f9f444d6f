--- solveQuad: a root of two quadratics in two unknowns, by the report's gradient compensation.
--
-- The quadratics are `G(X, Y) = A·X² + B·Y² + C·X·Y + D·X + E·Y + F`, their coefficients in a
-- flat array `{A1, B1, C1, D1, E1, F1, A2, B2, C2, D2, E2, F2}` (as `square.quadratics` fills
-- it). The report's update moves `(X, Y)` by each function's Newton step along its own gradient:
--
--     (X, Y) ← (X, Y) − G1 ∇G1 / |∇G1|² − G2 ∇G2 / |∇G2|²
--
-- until `|G1| ≤ tol` and `|G2| ≤ tol`. On noisy corners that update sometimes cycles in a narrow
-- valley between two roots (the two conics nearly touch there) and never converges: about 1 %
-- of the rows of the noisy dev sets. It is therefore safeguarded: when `REPORT_STEPS` of its
-- steps have not converged, every real root of the pair is computed directly (the resultant
-- eliminates one unknown and leaves a quartic, whose real roots are isolated between the roots
-- of its derivative and polished by Newton's method on the 2×2 system), and the root nearest the
-- start is taken, the start point choosing the root as in the report. While the report's update
-- converges (about 99 % of noisy rows, every exact one) the result is the report's exactly.
--
-- `iterations` counts the report's steps plus the Newton steps that polish a root of the
-- safeguard; the safeguard's root isolation is a fixed, bounded amount of work on top.
-- @module tagpose.core.solvequad

local poly = require("tagpose.core.poly")

local abs, max = math.abs, math.max
local huge = math.huge

local M = {}

--- Default convergence threshold on `|G1|` and `|G2|` (the report's).
M.TOLERANCE = 1e-10
--- Default bound on the number of iterations.
M.MAX_ITERATIONS = 100
--- Report steps tried before the safeguard takes over (98 % of noisy rows converge in fewer).
M.REPORT_STEPS = 30
--- Newton steps at most to polish each root the safeguard finds.
M.POLISH_STEPS = 8

-- value of quadratic k (0 or 6 offset) at (X, Y)
local function g(q, o, X, Y)
  return q[o + 1] * X * X + q[o + 2] * Y * Y + q[o + 3] * X * Y + q[o + 4] * X + q[o + 5] * Y
    + q[o + 6]
end

local poly_roots = poly.roots

---------------------------------------------------------------------------------------------
-- Every real root of the pair, by the resultant.
---------------------------------------------------------------------------------------------

local res = {} -- resultant coefficients
local ys = {} -- its real roots
local qs = {} -- the coefficients, possibly with X and Y swapped
local xq, xs = {}, {} -- a quadratic in X and its roots

-- Newton on the 2x2 system from (X, Y), at most `steps` steps; returns X, Y, steps used
local function polish(q, X, Y, tol, steps)
  for k = 1, steps do
    local g1, g2 = g(q, 0, X, Y), g(q, 6, X, Y)
    if abs(g1) <= tol and abs(g2) <= tol then return X, Y, k - 1 end
    local g1x, g1y = 2 * q[1] * X + q[3] * Y + q[4], 2 * q[2] * Y + q[3] * X + q[5]
    local g2x, g2y = 2 * q[7] * X + q[9] * Y + q[10], 2 * q[8] * Y + q[9] * X + q[11]
    local det = g1x * g2y - g1y * g2x
    if det == 0 then return X, Y, k end
    X, Y = X - (g1 * g2y - g2 * g1y) / det, Y - (g2 * g1x - g1 * g2x) / det
  end
  return X, Y, steps
end

--- Every real root of the two quadratics.
-- @tparam {number,...} q the twelve coefficients
-- @tparam {number,...} out flat array to fill with `X1, Y1, X2, Y2, ...`
-- @tparam[opt] number tol threshold on `|G1|`, `|G2|` for a root (default `TOLERANCE`)
-- @tparam[opt] int max_steps bound on the Newton steps spent polishing, in all
-- @treturn int the number of roots (0 to 4, or up to 8 when the quadratics share a factor)
-- @treturn int Newton steps used to polish them
function M.roots(q, out, tol, max_steps)
  tol = tol or M.TOLERANCE
  max_steps = max_steps or 4 * M.POLISH_STEPS
  -- eliminate the unknown whose square has the larger coefficients
  local swap = max(abs(q[1]), abs(q[7])) < max(abs(q[2]), abs(q[8]))
  for o = 0, 6, 6 do
    if swap then
      qs[o + 1], qs[o + 2], qs[o + 3] = q[o + 2], q[o + 1], q[o + 3]
      qs[o + 4], qs[o + 5], qs[o + 6] = q[o + 5], q[o + 4], q[o + 6]
    else
      for k = 1, 6 do
        qs[o + k] = q[o + k]
      end
    end
  end
  -- as quadratics in X: G = a X² + (C Y + D) X + (B Y² + E Y + F)
  local a1, B1, C1, D1, E1, F1 = qs[1], qs[2], qs[3], qs[4], qs[5], qs[6]
  local a2, B2, C2, D2, E2, F2 = qs[7], qs[8], qs[9], qs[10], qs[11], qs[12]
  -- u = a1 c2 - a2 c1 (quadratic), w = a1 b2 - a2 b1 (linear), v = b1 c2 - b2 c1 (cubic);
  -- the resultant in Y is u² - w v
  local u0, u1, u2 = a1 * F2 - a2 * F1, a1 * E2 - a2 * E1, a1 * B2 - a2 * B1
  local w0, w1 = a1 * D2 - a2 * D1, a1 * C2 - a2 * C1
  local v0 = D1 * F2 - D2 * F1
  local v1 = C1 * F2 + D1 * E2 - C2 * F1 - D2 * E1
  local v2 = C1 * E2 + D1 * B2 - C2 * E1 - D2 * B1
  local v3 = C1 * B2 - C2 * B1
  res[1] = u0 * u0 - w0 * v0
  res[2] = 2 * u0 * u1 - w0 * v1 - w1 * v0
  res[3] = u1 * u1 + 2 * u0 * u2 - w0 * v2 - w1 * v1
  res[4] = 2 * u1 * u2 - w0 * v3 - w1 * v2
  res[5] = u2 * u2 - w1 * v3
  local ny = poly_roots(res, 4, ys)
  local count, steps = 0, 0
  for i = 1, ny do
    local Y = ys[i]
    local u, w = u0 + Y * (u1 + Y * u2), w0 + Y * w1
    local nx
    if w ~= 0 and abs(w) > 1e-9 * (abs(w0) + abs(w1 * Y)) then
      xs[1], nx = -u / w, 1
    else
      -- the X-parts of the two quadratics are proportional at this Y: both X-roots of the
      -- better-conditioned one are candidates
      if abs(a2) > abs(a1) then
        xq[1], xq[2], xq[3] = B2 * Y * Y + E2 * Y + F2, C2 * Y + D2, a2
      else
        xq[1], xq[2], xq[3] = B1 * Y * Y + E1 * Y + F1, C1 * Y + D1, a1
      end
      nx = poly_roots(xq, 2, xs)
    end
    for j = 1, nx do
      local allowed = max_steps - steps
      if allowed > M.POLISH_STEPS then allowed = M.POLISH_STEPS end
      local x, y, k = polish(qs, xs[j], Y, tol, allowed)
      steps = steps + k
      if abs(g(qs, 0, x, y)) <= tol and abs(g(qs, 6, x, y)) <= tol then
        if swap then x, y = y, x end
        count = count + 1
        out[2 * count - 1], out[2 * count] = x, y
      end
    end
  end
  return count, steps
end

local found = {}

-- The report's update from (X, Y) for at most `budget` steps: X, Y, the steps taken, and
-- whether |G1| and |G2| fell to `tol`. (A function of its own so that the loop's exits carry
-- few values: LuaJIT cannot compile them with many.)
local function report(q, X, Y, tol, budget)
  local A1, B1, C1, D1, E1, F1 = q[1], q[2], q[3], q[4], q[5], q[6]
  local A2, B2, C2, D2, E2, F2 = q[7], q[8], q[9], q[10], q[11], q[12]
  local k = 0
  while true do
    local g1 = A1 * X * X + B1 * Y * Y + C1 * X * Y + D1 * X + E1 * Y + F1
    local g2 = A2 * X * X + B2 * Y * Y + C2 * X * Y + D2 * X + E2 * Y + F2
    if g1 <= tol and g1 >= -tol and g2 <= tol and g2 >= -tol then return X, Y, k, true end
    if k >= budget then return X, Y, k, false end
    local g1x, g1y = 2 * A1 * X + C1 * Y + D1, 2 * B1 * Y + C1 * X + E1
    local g2x, g2y = 2 * A2 * X + C2 * Y + D2, 2 * B2 * Y + C2 * X + E2
    local n1, n2 = g1x * g1x + g1y * g1y, g2x * g2x + g2y * g2y
    -- a vanishing or non-finite gradient: the update is undefined
    if not (n1 > 0 and n2 > 0 and n1 + n2 < huge) then return X, Y, k, false end
    local s1, s2 = g1 / n1, g2 / n2
    X, Y = X - s1 * g1x - s2 * g2x, Y - s1 * g1y - s2 * g2y
    k = k + 1
  end
end

--- Find a root of the two quadratics, starting from `(X, Y)`.
-- @tparam {number,...} q the twelve coefficients
-- @tparam number X start
-- @tparam number Y start
-- @tparam[opt] number tol threshold on `|G1|` and `|G2|` (default `TOLERANCE`)
-- @tparam[opt] int max_iterations bound on iterations (default `MAX_ITERATIONS`)
-- @treturn number X
-- @treturn number Y
-- @treturn int iterations used
-- @return nil, string, int when there is no real root (the message says why), and the
--   iterations used
function M.solve(q, X, Y, tol, max_iterations)
  tol = tol or M.TOLERANCE
  max_iterations = max_iterations or M.MAX_ITERATIONS
  local X0, Y0 = X, Y
  local budget = M.REPORT_STEPS
  if budget > max_iterations then budget = max_iterations end
  local converged, k
  X, Y, k, converged = report(q, X, Y, tol, budget)
  if converged then return X, Y, k end
  if k >= max_iterations then
    return nil, "solvequad: no convergence in " .. max_iterations .. " iterations", k
  end
  -- safeguard: all real roots, the nearest to the start
  local n, steps = M.roots(q, found, tol, max_iterations - k)
  k = k + steps
  if n == 0 then return nil, "solvequad: the quadratics have no real root", k end
  local best, bx, by = huge, nil, nil
  for i = 1, n do
    local x, y = found[2 * i - 1], found[2 * i]
    local d = (x - X0) * (x - X0) + (y - Y0) * (y - Y0)
    if d < best then best, bx, by = d, x, y end
  end
  return bx, by, k
end

return M
