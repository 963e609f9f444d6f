--- Step 3 of the tracking filter (`tagpose.track.filter`): the children of one frame, best
-- first, merged where they coincide and the best `HYPOTHESES` kept, `RESERVE` places going to
-- the best of the candidate the others did not choose. This module also holds the children's
-- scratch arrays, which the filter's other steps fill and read.
--
-- The children live in these scratch arrays, one per quantity, by slot: slot j holds the two
-- children of the previous state's j-th hypothesis (the last slot, the new paths). Per slot
-- `spp, spv, svv` (the per-axis covariance the two share) and `sfrom` (the candidate the parent
-- chose, 0 for a new path); per child of the first candidate `x1, y1` (tilt), `vx1, vy1`
-- (rate), `lw1` (log-weight), `w1` (weight), of the second `x2, ..., w2`. Ties of weight go to
-- the child made first: the first candidate's of slot j before the second's of slot k exactly
-- when j <= k.
-- @module tagpose.track.merge

local M = {}

local TINY = 1e-300 -- the least weight a kept hypothesis carries

-- scratch for the children of one frame (see the module's header)
local spp, spv, svv, sfrom = {}, {}, {}, {}
local x1, y1, vx1, vy1, lw1, w1 = {}, {}, {}, {}, {}, {}
local x2, y2, vx2, vy2, lw2, w2 = {}, {}, {}, {}, {}, {}
-- each candidate's children in order of weight (slots), and the kept children: all (`kept`:
-- the slot, negated for the second candidate's), and per candidate their slot, tilt, rate and
-- merging radius²
local run1, run2, kept = {}, {}, {}
local k1, k1x, k1y, k1vx, k1vy, k1r = {}, {}, {}, {}, {}, {}
local k2, k2x, k2y, k2vx, k2vy, k2r = {}, {}, {}, {}, {}, {}

-- Child j of candidate `pick` is merged into the first kept child of the same candidate that
-- coincides with it, or kept (as the m + 1-th, the c + 1-th of its candidate). Returns the
-- counts after it.
local function consider(j, pick, m, c, limit, r2)
  local w, x, y, vx, vy = w1, x1[j], y1[j], vx1[j], vy1[j]
  local kx, ky, kvx, kvy, kr, ki = k1x, k1y, k1vx, k1vy, k1r, k1
  if pick ~= 1 then
    w, x, y, vx, vy = w2, x2[j], y2[j], vx2[j], vy2[j]
    kx, ky, kvx, kvy, kr, ki = k2x, k2y, k2vx, k2vy, k2r, k2
  end
  for u = 1, c do
    -- (the sum's terms are not negative: its first term or two alone as large as the radius
    -- rule the child out, to the bit; `first_pass` looks at them in turn)
    local dx, r = kx[u] - x, kr[u]
    if dx * dx < r then
      local dy, dvx, dvy = ky[u] - y, kvx[u] - vx, kvy[u] - vy
      if dx * dx + dy * dy + 0.01 * (dvx * dvx + dvy * dvy) < r then
        local into = ki[u]
        w[into] = w[into] + w[j]
        return m, c
      end
    end
  end
  m, c = m + 1, c + 1
  kept[m] = pick == 1 and j or -j
  ki[c], kx[c], ky[c], kvx[c], kvy[c], kr[c] = j, x, y, vx, vy, limit * (spp[j] + r2)
  if not (w[j] > TINY) then w[j] = TINY end
  return m, c
end

-- The first pass of step 3, best first: the children of a weight that is not zero in doubles,
-- until `room` are kept (`consider` and the runs' merge written out, once per candidate: the
-- filter's innermost loop). Returns how many of each candidate are kept and the places in the
-- runs where it stopped (a child before them of a weight above `TINY` was considered).
local function first_pass(room, limit, r2, n1, n2)
  -- luacheck: push ignore 431
  local w1, w2, run1, run2, kept, spp, TINY = w1, w2, run1, run2, kept, spp, TINY
  local x1, y1, vx1, vy1, x2, y2, vx2, vy2 = x1, y1, vx1, vy1, x2, y2, vx2, vy2
  local k1, k1x, k1y, k1vx, k1vy, k1r = k1, k1x, k1y, k1vx, k1vy, k1r
  local k2, k2x, k2y, k2vx, k2vy, k2r = k2, k2x, k2y, k2vx, k2vy, k2r
  -- luacheck: pop
  local m, c1, c2, a, b = 0, 0, 0, 1, 1
  -- the runs' heads: the slot of each run's next child (nil past its end) and its weight (a
  -- weight changes only once its child is kept: read when the child comes to the head, it is
  -- the weight it has when it is taken)
  local ja, wa, jb, wb = nil, 0, nil, 0
  if n1 >= 1 then ja = run1[1]; wa = w1[ja] end
  if n2 >= 1 then jb = run2[1]; wb = w2[jb] end
  while m < room do
    if ja and (not jb or wa > wb or (wa == wb and ja <= jb)) then
      if wa > TINY then
        local x, y, vx, vy, into = x1[ja], y1[ja], vx1[ja], vy1[ja], nil
        for u = 1, c1 do
          -- (the sum's terms are not negative: its first term, then its first two, as large as
          -- the radius rule the child out, to the bit, before the others are made)
          local dx, r = k1x[u] - x, k1r[u]
          local d2 = dx * dx
          if d2 < r then
            local dy = k1y[u] - y
            d2 = d2 + dy * dy
            if d2 < r then
              local dvx, dvy = k1vx[u] - vx, k1vy[u] - vy
              if d2 + 0.01 * (dvx * dvx + dvy * dvy) < r then
                into = k1[u]
                break
              end
            end
          end
        end
        if into then
          w1[into] = w1[into] + wa
        else
          m, c1 = m + 1, c1 + 1
          kept[m] = ja
          k1[c1], k1x[c1], k1y[c1], k1vx[c1], k1vy[c1], k1r[c1] = ja, x, y, vx, vy,
            limit * (spp[ja] + r2)
        end
      end
      a = a + 1
      if a <= n1 then ja = run1[a]; wa = w1[ja] else ja = nil end
    elseif jb then
      if wb > TINY then
        local x, y, vx, vy, into = x2[jb], y2[jb], vx2[jb], vy2[jb], nil
        for u = 1, c2 do
          local dx, r = k2x[u] - x, k2r[u]
          local d2 = dx * dx
          if d2 < r then
            local dy = k2y[u] - y
            d2 = d2 + dy * dy
            if d2 < r then
              local dvx, dvy = k2vx[u] - vx, k2vy[u] - vy
              if d2 + 0.01 * (dvx * dvx + dvy * dvy) < r then
                into = k2[u]
                break
              end
            end
          end
        end
        if into then
          w2[into] = w2[into] + wb
        else
          m, c2 = m + 1, c2 + 1
          kept[m] = -jb
          k2[c2], k2x[c2], k2y[c2], k2vx[c2], k2vy[c2], k2r[c2] = jb, x, y, vx, vy,
            limit * (spp[jb] + r2)
        end
      end
      b = b + 1
      if b <= n2 then jb = run2[b]; wb = w2[jb] else jb = nil end
    else
      break
    end
  end
  return c1, c2, a, b
end

-- The next child in the order of all the children, from places a and b of the runs (of
-- lengths n1 and n2): its slot, its candidate and the places after it (nil when none is left).
local function next_child(a, b, n1, n2)
  if a > n1 then
    if b > n2 then return nil end
    return run2[b], 2, a, b + 1
  end
  local ja = run1[a]
  if b > n2 then return ja, 1, a + 1, b end
  local jb = run2[b]
  local wa, wb = w1[ja], w2[jb]
  if wa > wb or (wa == wb and ja <= jb) then return ja, 1, a + 1, b end
  return jb, 2, a, b + 1
end

--- Step 3: merge the children that coincide into the better, keep the best, leaving `RESERVE`
-- places to the best of the candidate the others did not choose.
-- @tparam table T the model (`tagpose.track`: its constants)
-- @tparam number r2 the frame's measurement variance (per axis)
-- @tparam int n1 the length of `run1` (the first candidate's children in order of weight)
-- @tparam int n2 the length of `run2`
-- @treturn int how many are kept (in `kept`)
function M.merge(T, r2, n1, n2)
  local limit, hypotheses, reserve = T.MERGE * T.MERGE, T.HYPOTHESES, T.RESERVE
  local c1, c2, stop1, stop2 = first_pass(hypotheses - reserve, limit, r2, n1, n2)
  local m = c1 + c2
  -- the second: the best of a candidate with fewer than `reserve` kept (the children of the
  -- other then do not fit: a candidate's own run is its part of the order), of those the
  -- first pass did not consider
  if c1 >= reserve and c2 >= reserve then return m end
  if c1 < reserve and c2 < reserve then
    -- both: the order of all the children
    local j, pick, a, b = next_child(1, 1, n1, n2)
    while j and m < hypotheses do
      if pick == 1 then
        if c1 < reserve and not (a - 1 < stop1 and w1[j] > TINY) then
          m, c1 = consider(j, 1, m, c1, limit, r2)
        end
      elseif c2 < reserve and not (b - 1 < stop2 and w2[j] > TINY) then
        m, c2 = consider(j, 2, m, c2, limit, r2)
      end
      j, pick, a, b = next_child(a, b, n1, n2)
    end
    return m
  end
  local run, n, pick, c, stop, w = run1, n1, 1, c1, stop1, w1
  if c1 >= reserve then run, n, pick, c, stop, w = run2, n2, 2, c2, stop2, w2 end
  for r = 1, n do
    if m >= hypotheses or c >= reserve then break end
    local j = run[r]
    if not (r < stop and w[j] > TINY) then m, c = consider(j, pick, m, c, limit, r2) end
  end
  return m
end

-- the scratch arrays the filter's other steps fill and read
M.spp, M.spv, M.svv, M.sfrom = spp, spv, svv, sfrom
M.x1, M.y1, M.vx1, M.vy1, M.lw1, M.w1 = x1, y1, vx1, vy1, lw1, w1
M.x2, M.y2, M.vx2, M.vy2, M.lw2, M.w2 = x2, y2, vx2, vy2, lw2, w2
M.run1, M.run2, M.kept = run1, run2, kept

return M
