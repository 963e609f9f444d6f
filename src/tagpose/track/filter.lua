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
--    choose;
-- 4. **emit**: the kept children become the state, with the posterior of each candidate and
--    the smoothing numbers.
--
-- The children live in this module's scratch arrays, one array per quantity (`cx, cy`: the
-- tilt; `cvx, cvy`: its rate; `cpp, cpv, cvv`: the per-axis covariance; `clw`: the log-weight;
-- `cw`: the weight; `cpick`: the candidate chosen; `cfrom`: the previous frame's candidate the
-- parent chose, 0 for a new path). A state's `hypotheses` is `tagpose.track.STRIDE` numbers per
-- hypothesis: τx, τy, their rates, the position variance, the position-rate covariance, the
-- rate variance, the log-weight (the state's weights sum to one in probability) and the
-- candidate it chose. Only this module reads or writes it.
-- @module tagpose.track.filter

local sqrt, exp, log, min, max = math.sqrt, math.exp, math.log, math.min, math.max

local M = {}

local LOG_DISK = log(1 / math.pi) -- log density of a tilt vector uniform over the unit disk
local TWO_PI = 2 * math.pi
local TINY = 1e-300 -- the least weight a kept hypothesis carries

-- scratch for the children of one frame, as parallel arrays (see the module's header)
local cx, cy, cvx, cvy, cpp, cpv, cvv, clw, cw, cpick, cfrom = {}, {}, {}, {}, {}, {}, {}, {},
  {}, {}, {}
-- the kept children: all, and per candidate their index, tilt, rate and merging radius²
local kept = {}
local k1, k1x, k1y, k1vx, k1vy, k1r = {}, {}, {}, {}, {}, {}
local k2, k2x, k2y, k2vx, k2vy, k2r = {}, {}, {}, {}, {}, {}
local seen, stamp = {}, 0 -- seen[i] == stamp: child i was considered in the first pass

-- A track's first frame: a path at each candidate, weighted by the evidence (what `step`
-- does with no hypotheses, without its loops).
local function start(T, out, time, s2, ax, ay, bx, by, r2, has2, ev)
  -- log-weights of the two paths, summing to one in probability (ev is within ±700)
  local a = ev >= 0 and -ev or ev
  local lw_better = -log(1 + exp(a))
  local lw1, lw2 = lw_better, a + lw_better
  if ev < 0 then lw1, lw2 = lw2, lw1 end
  local p1 = has2 and exp(lw1) or 1
  if not has2 then lw1 = 0 end
  out.time, out.sigma2, out.first, out.back_first, out.back_second = time, s2, p1, 0.5, 0.5
  local h = out.hypotheses
  h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9] = ax, ay, 0, 0, r2, 0, T.RATE, lw1, 1
  local n = 1
  if has2 then
    h[10], h[11], h[12], h[13], h[14], h[15], h[16], h[17], h[18] = bx, by, 0, 0, r2, 0, T.RATE,
      lw2, 2
    n = 2
  end
  out.count = n
  for i = n * 9 + 1, #h do h[i] = nil end
  if p1 >= 0.5 then return 1, p1 end
  return 2, 1 - p1
end

-- The log of the share of the children of one hypothesis that choose the first candidate, and
-- of those that choose the second, when their candidates lie at d1 and d2 (their exponents)
-- from its prediction: -log(1 + e^(d1 - d2)) and -log(1 + e^(d2 - d1)). (Without a branch,
-- the difference held within ±700 by min and max: on LuaJIT a side exit here, in branch's
-- loop, is a trace that cannot be compiled, and a hypothesis far from one candidate takes it
-- often.)
local function shares(d1, d2)
  local d = min(max(d1 - d2, -700), 700)
  local soft = log(1 + exp(d))
  return -soft, d - soft
end

-- Steps 1 and 2: the children of every hypothesis of `prev` and the new paths, into the
-- scratch arrays; returns their count. (a: the first candidate's measurement, b the second's,
-- r2 their variance, half the frame's evidence halved; z1, z2 the candidates' tilt vectors
-- squared as complex numbers, rho2 the variance of each of their parts.)
local function branch(T, prev, dt, ax, ay, bx, by, has2, r2, half, z1r, z1i, z2r, z2i, rho2)
  -- (the scratch arrays as locals: an upvalue costs one more instruction at every use)
  -- luacheck: push ignore 431
  local cx, cy, cvx, cvy, cpp, cpv, cvv, clw, cpick, cfrom = cx, cy, cvx, cvy, cpp, cpv, cvv,
    clw, cpick, cfrom
  -- luacheck: pop
  local h, k, q = prev.hypotheses, 0, T.PROCESS
  local dt2 = dt * dt
  local q1, q2, q3 = q * dt, q * dt2 / 2, q * dt2 * dt / 3
  for o = 0, (prev.count - 1) * 9, 9 do
    local vx, vy = h[o + 3], h[o + 4]
    local x, y = h[o + 1] + vx * dt, h[o + 2] + vy * dt
    local pp0, pv0, vv0 = h[o + 5], h[o + 6], h[o + 7]
    local pp = pp0 + 2 * dt * pv0 + dt2 * vv0 + q3
    local pv = pv0 + dt * vv0 + q2
    local vv = vv0 + q1
    local from = h[o + 9]
    -- the frame's likelihood under the hypothesis: its tilt squared against the candidates',
    -- with the prediction's spread carried through the square
    local xx, yy, xy = x * x, y * y, 2 * x * y
    local S = 4 * (xx + yy + pp) * pp + rho2
    local qx = xx - yy
    local lw = h[o + 8] - log(TWO_PI * S)
    local dr, di = z1r - qx, z1i - xy
    local l1 = (dr * dr + di * di) / (2 * S)
    -- the Kalman update of either child: the same gains and covariance
    local s = pp + r2
    local g1, g2 = pp / s, pv / s
    local upp, upv, uvv = pp - g1 * pp, pv - g1 * pv, vv - g2 * pv
    local dx, dy = ax - x, ay - y
    k = k + 1
    cx[k], cy[k], cvx[k], cvy[k] = x + g1 * dx, y + g1 * dy, vx + g2 * dx, vy + g2 * dy
    cpp[k], cpv[k], cvv[k] = upp, upv, uvv
    cpick[k], cfrom[k] = 1, from
    if has2 then
      local ex, ey = bx - x, by - y
      local sa, sb = shares((dx * dx + dy * dy) / (2 * s), (ex * ex + ey * ey) / (2 * s))
      clw[k] = lw + half - l1 + sa
      dr, di = z2r - qx, z2i - xy
      k = k + 1
      cx[k], cy[k], cvx[k], cvy[k] = x + g1 * ex, y + g1 * ey, vx + g2 * ex, vy + g2 * ey
      cpp[k], cpv[k], cvv[k] = upp, upv, uvv
      clw[k], cpick[k], cfrom[k] = lw - half - (dr * dr + di * di) / (2 * S) + sb, 2, from
    else
      clw[k] = lw + half - l1
    end
  end
  -- a new path at either candidate, with the motion history forgotten
  local base = log(T.BIRTH) + LOG_DISK
  k = k + 1
  cx[k], cy[k], cvx[k], cvy[k], cpp[k], cpv[k], cvv[k] = ax, ay, 0, 0, r2, 0, T.RATE
  clw[k], cpick[k], cfrom[k] = base + half, 1, 0
  if has2 then
    k = k + 1
    cx[k], cy[k], cvx[k], cvy[k], cpp[k], cpv[k], cvv[k] = bx, by, 0, 0, r2, 0, T.RATE
    clw[k], cpick[k], cfrom[k] = base - half, 2, 0
  end
  return k
end

-- The children's weights (relative to the best), and for smoothing the probability of the
-- previous frame's first candidate given each of this frame's: returns a, b.
local function weigh(k, p_prev)
  local clw, cw, cpick, cfrom = clw, cw, cpick, cfrom -- luacheck: ignore 431
  local top = -math.huge
  for i = 1, k do
    if clw[i] > top then top = clw[i] end
  end
  local j11, j12, j21, j22 = 0, 0, 0, 0
  for i = 1, k do
    local w = exp(clw[i] - top)
    cw[i] = w
    local from = cfrom[i]
    if from == 0 then
      -- a new path: its previous choice as the previous frame believed
      if cpick[i] == 1 then
        j11, j21 = j11 + w * p_prev, j21 + w * (1 - p_prev)
      else
        j12, j22 = j12 + w * p_prev, j22 + w * (1 - p_prev)
      end
    elseif from == 1 then
      if cpick[i] == 1 then j11 = j11 + w else j12 = j12 + w end
    elseif cpick[i] == 1 then
      j21 = j21 + w
    else
      j22 = j22 + w
    end
  end
  local a, b = 0.5, 0.5
  if j11 + j21 > 0 then a = j11 / (j11 + j21) end
  if j12 + j22 > 0 then b = j12 / (j12 + j22) end
  return a, b
end

-- The children of each candidate in order of weight, best first, ties in the order they were
-- made (a stable sort), in `run1` and `run2`: each candidate's children come nearly in order
-- already (their parents are kept best first), so an insertion sort of each is quick. Their
-- merge by weight (ties: the child made first) is the order of all the children.
local run1, run2 = {}, {}

local function sort(k)
  local cw, cpick, run1, run2 = cw, cpick, run1, run2 -- luacheck: ignore 431
  local n1, n2 = 0, 0
  for i = 1, k do
    local w = cw[i]
    -- (an insertion written out: a function call per child costs more than the sort)
    if cpick[i] == 1 then
      local j = n1
      while j >= 1 and cw[run1[j]] < w do
        run1[j + 1] = run1[j]
        j = j - 1
      end
      run1[j + 1] = i
      n1 = n1 + 1
    else
      local j = n2
      while j >= 1 and cw[run2[j]] < w do
        run2[j + 1] = run2[j]
        j = j - 1
      end
      run2[j + 1] = i
      n2 = n2 + 1
    end
  end
  return n1, n2
end

-- Child i of candidate `pick` is merged into the first kept child of the same candidate that
-- coincides with it, or kept (as the m + 1-th, the c + 1-th of its candidate). Returns the
-- counts after it.
local function consider(i, pick, m, c, limit, r2)
  local x, y, vx, vy = cx[i], cy[i], cvx[i], cvy[i]
  local kx, ky, kvx, kvy, kr, ki = k1x, k1y, k1vx, k1vy, k1r, k1
  if pick ~= 1 then kx, ky, kvx, kvy, kr, ki = k2x, k2y, k2vx, k2vy, k2r, k2 end
  for u = 1, c do
    -- (the sum's terms are not negative: one alone as large as the radius rules the child
    -- out, to the bit)
    local dx, r = kx[u] - x, kr[u]
    if dx * dx < r then
      local dy, dvx, dvy = ky[u] - y, kvx[u] - vx, kvy[u] - vy
      if dx * dx + dy * dy + 0.01 * (dvx * dvx + dvy * dvy) < r then
        local into = ki[u]
        cw[into] = cw[into] + cw[i]
        return m, c
      end
    end
  end
  m, c = m + 1, c + 1
  kept[m] = i
  ki[c], kx[c], ky[c], kvx[c], kvy[c], kr[c] = i, x, y, vx, vy, limit * (cpp[i] + r2)
  if not (cw[i] > TINY) then cw[i] = TINY end
  return m, c
end

-- The next child in the order of all the children, from positions a and b of the runs (of
-- lengths n1 and n2): its index and the positions after it (nil when none is left).
local function next_child(a, b, n1, n2)
  if a > n1 then
    if b > n2 then return nil end
    return run2[b], a, b + 1
  end
  local i = run1[a]
  if b > n2 then return i, a + 1, b end
  local j = run2[b]
  local wi, wj = cw[i], cw[j]
  if wi > wj or (wi == wj and i < j) then return i, a + 1, b end
  return j, a, b + 1
end

-- The first pass of step 3, best first: the children of a weight that is not zero in doubles,
-- until `room` are kept (`consider` and the merge of the runs written out: this is the
-- filter's innermost loop). Returns how many of each candidate are kept.
local function first_pass(now, room, limit, r2, n1, n2)
  -- luacheck: push ignore 431
  local cw, cpick, cx, cy, cvx, cvy, cpp, kept, seen = cw, cpick, cx, cy, cvx, cvy, cpp, kept,
    seen
  local run1, run2 = run1, run2
  -- luacheck: pop
  local m, c1, c2, a, b = 0, 0, 0, 1, 1
  while m < room do
    local i
    if a > n1 then
      if b > n2 then break end
      i, b = run2[b], b + 1
    elseif b > n2 then
      i, a = run1[a], a + 1
    else
      local i1, i2 = run1[a], run2[b]
      local w1, w2 = cw[i1], cw[i2]
      if w1 > w2 or (w1 == w2 and i1 < i2) then i, a = i1, a + 1 else i, b = i2, b + 1 end
    end
    local w = cw[i]
    if w > TINY then
      seen[i] = now
      local x, y, vx, vy = cx[i], cy[i], cvx[i], cvy[i]
      local kx, ky, kvx, kvy, kr, ki, c = k1x, k1y, k1vx, k1vy, k1r, k1, c1
      local pick = cpick[i]
      if pick ~= 1 then kx, ky, kvx, kvy, kr, ki, c = k2x, k2y, k2vx, k2vy, k2r, k2, c2 end
      local into = nil
      for u = 1, c do
        local dx, r = kx[u] - x, kr[u]
        if dx * dx < r then
          local dy, dvx, dvy = ky[u] - y, kvx[u] - vx, kvy[u] - vy
          if dx * dx + dy * dy + 0.01 * (dvx * dvx + dvy * dvy) < r then
            into = ki[u]
            break
          end
        end
      end
      if into then
        cw[into] = cw[into] + w
      else
        m, c = m + 1, c + 1
        kept[m] = i
        ki[c], kx[c], ky[c], kvx[c], kvy[c], kr[c] = i, x, y, vx, vy, limit * (cpp[i] + r2)
        if pick == 1 then c1 = c else c2 = c end
      end
    end
  end
  return c1, c2
end

-- Step 3: merge the children that coincide into the better, keep the best, leaving `RESERVE`
-- places to the best of the candidate the others did not choose. Returns how many are kept
-- (in `kept`).
local function merge(T, r2, n1, n2)
  stamp = stamp + 1
  local now = stamp
  local limit, hypotheses, reserve = T.MERGE * T.MERGE, T.HYPOTHESES, T.RESERVE
  local c1, c2 = first_pass(now, hypotheses - reserve, limit, r2, n1, n2)
  local m = c1 + c2
  -- the second: the best of a candidate with fewer than `reserve` kept (the children of the
  -- other then do not fit: a candidate's own run is its part of the order)
  if c1 >= reserve and c2 >= reserve then return m end
  local run, n, pick = run1, n1, 1
  if c1 >= reserve then run, n, pick = run2, n2, 2 end
  if c1 < reserve and c2 < reserve then
    -- both: the order of all the children
    local i, a, b = next_child(1, 1, n1, n2)
    while i and m < hypotheses do
      if seen[i] ~= now then
        if cpick[i] == 1 then
          if c1 < reserve then m, c1 = consider(i, 1, m, c1, limit, r2) end
        elseif c2 < reserve then
          m, c2 = consider(i, 2, m, c2, limit, r2)
        end
      end
      i, a, b = next_child(a, b, n1, n2)
    end
    return m
  end
  local c = pick == 1 and c1 or c2
  for r = 1, n do
    if m >= hypotheses or c >= reserve then break end
    local i = run[r]
    if seen[i] ~= now then m, c = consider(i, pick, m, c, limit, r2) end
  end
  return m
end

-- Step 4: the kept children as the new state; returns the candidate to return and its
-- posterior.
local function emit(out, m, time, s2, a, b)
  local kept, cw, cpick = kept, cw, cpick -- luacheck: ignore 431
  local total, first = 0, 0
  for u = 1, m do
    local i = kept[u]
    local w = cw[i]
    total = total + w
    if cpick[i] == 1 then first = first + w end
  end
  local p1 = first / total
  out.time, out.sigma2, out.first, out.back_first, out.back_second, out.count = time, s2, p1, a,
    b, m
  local h = out.hypotheses
  for u = 1, m do
    local i, o = kept[u], (u - 1) * 9
    h[o + 1], h[o + 2], h[o + 3], h[o + 4] = cx[i], cy[i], cvx[i], cvy[i]
    h[o + 5], h[o + 6], h[o + 7] = cpp[i], cpv[i], cvv[i]
    h[o + 8], h[o + 9] = log(cw[i] / total), cpick[i]
  end
  for i = m * 9 + 1, #h do h[i] = nil end
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
    local k = branch(T, prev, dt, ax, ay, bx, by, has2, r2, 0.5 * ev, z1r, z1i, z2r, z2i,
      rho * rho)
    local back_first, back_second = weigh(k, prev.first)
    local m = merge(T, r2, sort(k))
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
