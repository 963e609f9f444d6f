--- One frame of the tracking filter (`tagpose.track` describes the model): its steps are
--
-- 1. **predict**: each hypothesis's constant-rate Kalman filter on the tilt vector moves on by
--    the time since the last frame;
-- 2. **branch**: each hypothesis has a child per candidate of the frame: the child takes that
--    candidate's tilt as its measurement; its weight gains the frame's likelihood under the
--    hypothesis (the candidates' tilts squared against the prediction's), the share of it on
--    that candidate's side (by the candidates' distances from the prediction) and the frame's
--    evidence for the candidate. A new path may start at either candidate (`BIRTH`);
-- 3. **merge**: the children, best first, are merged where they coincide and the best
--    `HYPOTHESES` kept, `RESERVE` places going to the best of the candidate the others did not
--    choose (`tagpose.track.merge`, which holds the children's scratch arrays);
-- 4. **emit**: the kept children become the state, with the posterior of each candidate and
--    the smoothing numbers.
--
-- A state's `hypotheses` is `tagpose.track.STRIDE` numbers per hypothesis: τx, τy, their
-- rates, the position variance, the position-rate covariance, the rate variance, the
-- log-weight (the weights sum to one in probability) and the candidate it chose. Only this
-- module reads or writes it.
-- @module tagpose.track.filter

local compat = require("tagpose.core.compat")
local children = require("tagpose.track.merge")

local sqrt, exp, log, min, max = math.sqrt, math.exp, math.log, math.min, math.max
local JIT = compat.jit

-- The nine numbers of a hypothesis, from place o of a state's array (o + 8 its last): on PUC
-- Lua table.unpack, one call that costs fewer instructions than nine reads; on LuaJIT a
-- function its traces take in (a trace cannot go through unpack: it ends there)
local read_hypothesis = compat.unpack
if JIT then
  read_hypothesis = function(h, o)
    return h[o], h[o + 1], h[o + 2], h[o + 3], h[o + 4], h[o + 5], h[o + 6], h[o + 7], h[o + 8]
  end
end

local M = {}

local LOG_DISK = log(1 / math.pi) -- log density of a tilt vector uniform over the unit disk
local TWO_PI = 2 * math.pi

-- the children's scratch arrays (`tagpose.track.merge` describes them)
local spp, spv, svv, sfrom = children.spp, children.spv, children.svv, children.sfrom
local x1, y1, vx1, vy1, lw1, w1 = children.x1, children.y1, children.vx1, children.vy1,
  children.lw1, children.w1
local x2, y2, vx2, vy2, lw2, w2 = children.x2, children.y2, children.vx2, children.vy2,
  children.lw2, children.w2
local run1, run2, kept = children.run1, children.run2, children.kept
local merge = children.merge

-- A track's first frame: a path at each candidate, weighted by the evidence (what `step`
-- does with no hypotheses, without its loops).
local function start(T, out, time, s2, ax, ay, bx, by, r2, has2, ev)
  -- log-weights of the two paths, summing to one in probability (ev is within ±700)
  local a = ev >= 0 and -ev or ev
  local lw_better = -log(1 + exp(a))
  local lwa, lwb = lw_better, a + lw_better
  if ev < 0 then lwa, lwb = lwb, lwa end
  local p1 = has2 and exp(lwa) or 1
  if not has2 then lwa = 0 end
  out.time, out.sigma2, out.first, out.back_first, out.back_second = time, s2, p1, 0.5, 0.5
  local h = out.hypotheses
  h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9] = ax, ay, 0, 0, r2, 0, T.RATE, lwa, 1
  local n = 1
  if has2 then
    h[10], h[11], h[12], h[13], h[14], h[15], h[16], h[17], h[18] = bx, by, 0, 0, r2, 0, T.RATE,
      lwb, 2
    n = 2
  end
  out.count = n
  for i = n * 9 + 1, #h do h[i] = nil end
  if p1 >= 0.5 then return 1, p1 end
  return 2, 1 - p1
end

-- Steps 1 and 2: the children of every hypothesis of `prev` and the new paths, into the
-- scratch arrays; returns the slots. (a: the first candidate's
-- measurement, b the second's, r2 their variance, half the frame's evidence halved; z1, z2 the
-- candidates' tilt vectors squared as complex numbers, rho2 the variance of each of their
-- parts.) Every number shared by two expressions is made once: the same operations, once.
local function branch(T, prev, dt, ax, ay, bx, by, has2, r2, half, z1r, z1i, z2r, z2i, rho2)
  -- (the scratch arrays and constants as locals: an upvalue costs one more instruction at
  -- every use, and so does an integer beyond ±127 compared)
  -- luacheck: push ignore 431
  local spp, spv, svv, sfrom, x1, y1, vx1, vy1, lw1 = spp, spv, svv, sfrom, x1, y1, vx1, vy1, lw1
  local x2, y2, vx2, vy2, lw2 = x2, y2, vx2, vy2, lw2
  local TWO_PI, JIT, LOW, HIGH = TWO_PI, JIT, -700, 700
  -- luacheck: pop
  local h, j, q = prev.hypotheses, 0, T.PROCESS
  local dt2, dt_2 = dt * dt, 2 * dt
  local q1, q2, q3 = q * dt, q * dt2 / 2, q * dt2 * dt / 3
  -- (o: a hypothesis's first place; the bound is that of the first places less one, so the
  -- loop runs as often as they would, whatever number `count` holds)
  for o = 1, (prev.count - 1) * 9 + 1, 9 do
    local x0, y0, vx, vy, pp0, pv0, vv0, lw0, from = read_hypothesis(h, o, o + 8)
    local x, y = x0 + vx * dt, y0 + vy * dt
    local pp = pp0 + dt_2 * pv0 + dt2 * vv0 + q3
    local pv = pv0 + dt * vv0 + q2
    local vv = vv0 + q1
    -- the frame's likelihood under the hypothesis: its tilt squared against the candidates',
    -- with the prediction's spread carried through the square
    local xx, yy, xy = x * x, y * y, 2 * x * y
    local S = 4 * (xx + yy + pp) * pp + rho2
    local qx, S_2 = xx - yy, 2 * S
    local lw = lw0 - log(TWO_PI * S)
    local dr, di = z1r - qx, z1i - xy
    local l1 = (dr * dr + di * di) / S_2
    -- the Kalman update of either child: the same gains and covariance
    local s = pp + r2
    local g1, g2 = pp / s, pv / s
    local dx, dy = ax - x, ay - y
    j = j + 1
    x1[j], y1[j], vx1[j], vy1[j] = x + g1 * dx, y + g1 * dy, vx + g2 * dx, vy + g2 * dy
    spp[j], spv[j], svv[j], sfrom[j] = pp - g1 * pp, pv - g1 * pv, vv - g2 * pv, from
    local l = lw + half - l1
    if has2 then
      -- the log of the share of the children that choose either candidate, as they lie at e1
      -- and e2 (their exponents) from the prediction: -log(1 + exp(e1 - e2)) and -log(1 +
      -- exp(e2 - e1)), the difference held within ±700: on LuaJIT by min and max (a side exit
      -- here is a trace that cannot be compiled), on PUC Lua by branches (two calls of C
      -- functions cost more; the same number, NaN and -0 included)
      local ex, ey, s_2 = bx - x, by - y, 2 * s
      local d = (dx * dx + dy * dy) / s_2 - (ex * ex + ey * ey) / s_2
      if JIT then
        d = min(max(d, LOW), HIGH)
      elseif d < LOW then
        d = LOW
      elseif d > HIGH then
        d = HIGH
      end
      local soft = log(1 + exp(d))
      l = l + -soft
      dr, di = z2r - qx, z2i - xy
      x2[j], y2[j], vx2[j], vy2[j] = x + g1 * ex, y + g1 * ey, vx + g2 * ex, vy + g2 * ey
      local l2 = lw - half - (dr * dr + di * di) / S_2 + (d - soft)
      lw2[j] = l2
    end
    lw1[j] = l
  end
  -- a new path at either candidate, with the motion history forgotten
  local base = log(T.BIRTH) + LOG_DISK
  j = j + 1
  x1[j], y1[j], vx1[j], vy1[j], lw1[j] = ax, ay, 0, 0, base + half
  spp[j], spv[j], svv[j], sfrom[j] = r2, 0, T.RATE, 0
  if has2 then x2[j], y2[j], vx2[j], vy2[j], lw2[j] = bx, by, 0, 0, base - half end
  return j
end

-- One candidate's children: their weights relative to the greatest log-weight `top` (into
-- `w`), and their order of weight, best first, into `run` (insertion, stable: the children
-- come nearly in order, their parents kept best first, so a child is most often no heavier
-- than the last placed, whose weight `low` holds; placed at the end then, it is compared once).
-- (Written out, not a function per child: a call per child costs more than the sort.) Returns
-- the weight of the children whose parents chose the previous frame's first candidate and of
-- those whose parents chose its second, a new path's shared as the previous frame believed
-- (`p_prev`, the first's probability).
local function order(ns, top, lw, w, run, p_prev)
  local sfrom = sfrom -- luacheck: ignore 431
  local low = math.huge -- (no weight is above it: the first child goes first)
  local one, two = 0, 0
  for j = 1, ns do
    local wj = exp(lw[j] - top)
    w[j] = wj
    if low < wj then
      local r = j - 2
      run[j] = run[j - 1]
      while r >= 1 and w[run[r]] < wj do
        run[r + 1] = run[r]
        r = r - 1
      end
      run[r + 1] = j
    else
      run[j], low = j, wj
    end
    local from = sfrom[j]
    if from == 1 then
      one = one + wj
    elseif from == 0 then
      -- the new paths: their previous choice as the previous frame believed
      one, two = one + wj * p_prev, two + wj * (1 - p_prev)
    else
      two = two + wj
    end
  end
  return one, two
end

-- The children's weights (relative to the best), each candidate's children in order of
-- weight, best first, in `run1` and `run2` (the runs' merge by weight is the order of all the
-- children), and for smoothing the probability of the previous frame's first candidate given
-- each of this frame's. Returns the runs' lengths and the two probabilities.
local function weigh(ns, has2, p_prev)
  local lw1, lw2 = lw1, lw2 -- luacheck: ignore 431
  local top = -math.huge
  for j = 1, ns do
    if lw1[j] > top then top = lw1[j] end
    if has2 and lw2[j] > top then top = lw2[j] end
  end
  local a, b, n2 = 0.5, 0.5, 0
  local one, two = order(ns, top, lw1, w1, run1, p_prev)
  if one + two > 0 then a = one / (one + two) end
  if has2 then
    one, two = order(ns, top, lw2, w2, run2, p_prev)
    if one + two > 0 then b = one / (one + two) end
    n2 = ns
  end
  return ns, n2, a, b
end

-- Step 4: the kept children as the new state; returns the candidate to return and its
-- posterior.
local function emit(out, m, time, s2, a, b)
  -- luacheck: push ignore 431
  local kept, w1, w2, spp, spv, svv = kept, w1, w2, spp, spv, svv
  local x1, y1, vx1, vy1, x2, y2, vx2, vy2 = x1, y1, vx1, vy1, x2, y2, vx2, vy2
  -- luacheck: pop
  local total, first = 0, 0
  for u = 1, m do
    local j = kept[u]
    if j > 0 then
      local w = w1[j]
      total = total + w
      first = first + w
    else
      total = total + w2[-j]
    end
  end
  local p1 = first / total
  out.time, out.sigma2, out.first, out.back_first, out.back_second, out.count = time, s2, p1, a,
    b, m
  -- (o: the place of the hypothesis's first number, moved on a stride at a time)
  local h, o = out.hypotheses, 1
  for u = 1, m do
    local j = kept[u]
    if j > 0 then
      h[o], h[o + 1], h[o + 2], h[o + 3] = x1[j], y1[j], vx1[j], vy1[j]
      h[o + 7], h[o + 8] = log(w1[j] / total), 1
    else
      j = -j
      h[o], h[o + 1], h[o + 2], h[o + 3] = x2[j], y2[j], vx2[j], vy2[j]
      h[o + 7], h[o + 8] = log(w2[j] / total), 2
    end
    h[o + 4], h[o + 5], h[o + 6] = spp[j], spv[j], svv[j]
    o = o + 9
  end
  for i = o, #h do h[i] = nil end
  if p1 >= 0.5 then return 1, p1 end
  return 2, 1 - p1
end

--- One frame of the filter (`tagpose.track.step` documents it).
-- @tparam table T the model (`tagpose.track`: its constants and measurement)
-- @tparam ?table prev the previous state with at least one hypothesis, or nil
-- @tparam table a the first candidate
-- @tparam ?table b the second, or nil
-- @tparam number size the tag's side in pixels
-- @tparam ?number time the frame's time (s)
-- @tparam table out the state to fill (may be `prev`)
-- @tparam[opt] number llr the frame's own evidence
-- @treturn int the candidate to return (1 or 2)
-- @treturn number its posterior probability
function M.step(T, prev, a, b, size, time, out, llr)
  local has2 = b ~= nil
  local sse1 = a.sse
  -- (everything read from prev before out, which may be prev, is written)
  local dt, now, s2, dof, own = T.step_and_noise(prev, time)
  -- the candidates' tilt vectors, squared as complex numbers, and the variance of each part of
  -- their noise; then shrunk, and their variance
  local ax, ay = T.tilt(a.qw, a.qx, a.qy, a.qz, a.tx, a.ty, a.tz)
  local bx, by = ax, ay
  if has2 then bx, by = T.tilt(b.qw, b.qx, b.qy, b.qz, b.tx, b.ty, b.tz) end
  local z1r, z1i, z2r, z2i = ax * ax - ay * ay, 2 * ax * ay, bx * bx - by * by, 2 * bx * by
  local rho = T.SQUARE_NOISE * sqrt(s2) / size
  local g, r2, xm = T.measurement(sqrt(ax * ax + ay * ay), size, s2)
  ax, ay, bx, by = g * ax, g * ay, g * bx, g * by
  local ev = 0
  if has2 then
    ev = llr or T.evidence(sse1, b.sse, s2, xm, dof)
    if ev ~= ev then ev = 0 elseif ev > 700 then ev = 700 elseif ev < -700 then ev = -700 end
  end
  local pick, p
  if not prev or prev.count == 0 then
    pick, p = start(T, out, now, s2, ax, ay, bx, by, r2, has2, ev)
  else
    local slots = branch(T, prev, dt, ax, ay, bx, by, has2, r2, 0.5 * ev, z1r, z1i, z2r, z2i,
      rho * rho)
    local n1, n2, back_first, back_second = weigh(slots, has2, prev.first)
    local m = merge(T, r2, n1, n2)
    pick, p = emit(out, m, now, s2, back_first, back_second)
    if not (p == p) then
      -- a state the caller damaged (not a number in it): start again from this frame
      pick, p = start(T, out, now, s2, ax, ay, bx, by, r2, has2, ev)
    end
  end
  -- the noise estimate, with the residuals of the candidate chosen
  out.sigma2, out.dof = T.noise(s2, own, pick == 1 and sse1 or b.sse)
  return pick, p
end

return M
