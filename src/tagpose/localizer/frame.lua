--- One camera frame's robot pose: the map tags it saw turned into observations, a start found
-- among the poses each tag alone allows, the fit (`tagpose.localizer.fit`) with the priors, the
-- tags that do not agree with the rest (or with the priors) taken out one at a time, and the
-- covariance.
--
-- Each tag seen alone gives two robot poses (the two minima of the planar ambiguity, from
-- `tagpose.solve`, carried through the mount and the map). Each is scored by the whole frame:
-- every tag's χ² at that pose, capped (a tag that does not agree costs the cap, whatever its
-- error), plus the priors'; the best starts the fit, or the `start` given (the estimate the
-- filter predicts). A tag whose χ² after the fit exceeds the gate for its 8 residuals is
-- rejected and the rest fitted again; so is a frame whose priors alone are past their gate (a
-- lone phantom detection, a tag placed elsewhere than the map says, seen alone, puts the robot
-- in the air or tilted).
--
-- That joint fit of every tag can be dragged by one gross outlier (a phantom detection: a
-- random quad with a map id) until the real tags look worse than it and leave one by one. So
-- when it loses a tag, fails, or the priors refuse it, a consensus is grown from each start in
-- turn (best score first, those the priors refuse aside, a start whose tag an earlier
-- consensus keeps skipped): the tags that agree with the start, fitted together, then each other
-- tag kept when the fit with it adds no more than `LOO_GATE` to the χ². The solution the priors
-- take beats one they refuse; then the one that keeps more tags wins, then the lower χ².
-- @module tagpose.localizer.frame

local fit = require("tagpose.localizer.fit")
local rotation = require("tagpose.core.rotation")

local huge, sqrt = math.huge, math.sqrt

-- linearisations of a start's fit to its own tag
local START_ITERATIONS = 4

local M = {}

--- χ² gate of one tag's 8 residuals (P = 1e-4 for Gaussian corners of the given σ).
M.TAG_GATE = 31.8
--- Gate of what one tag adds to a fit's χ² (χ²(8) for a tag that agrees; the mount's error
-- widens it: 1.5 `TAG_GATE`).
M.LOO_GATE = 47.7
--- Cost of a tag that does not agree with a start, in the start's score.
M.CAP = 200
--- χ² gate of the priors at the fit (3 or 4 residuals: P ≈ 1e-4).
M.PRIOR_GATE = 23.5

-- A pose's robot → field rotation and position from a tag's camera-frame pose (r flat tag →
-- camera, t in metres), the tag's place (flat tag → field rotation, centre) and the mount.
local function robot_pose(tag, mount, r, t)
  -- camera → field: R_fc = R_ft R_ctᵀ; its centre c = p - R_fc t
  local rfc = rotation.multiply_transpose(tag.r, r, {})
  local cx = tag.x - (rfc[1] * t[1] + rfc[2] * t[2] + rfc[3] * t[3])
  local cy = tag.y - (rfc[4] * t[1] + rfc[5] * t[2] + rfc[6] * t[3])
  local cz = tag.z - (rfc[7] * t[1] + rfc[8] * t[2] + rfc[9] * t[3])
  -- robot → field: R = R_fc Mᵀ; t = c - R m
  local R = rotation.multiply_transpose(rfc, mount.r, {})
  local m = mount.t
  return { r = R, t = { cx - (R[1] * m[1] + R[2] * m[2] + R[3] * m[3]),
    cy - (R[4] * m[1] + R[5] * m[2] + R[6] * m[3]),
    cz - (R[7] * m[1] + R[8] * m[2] + R[9] * m[3]) } }
end
M.robot_pose = robot_pose

local function copy_pose(p)
  local r = {}
  for i = 1, 9 do r[i] = p.r[i] end
  return { r = r, t = { p.t[1], p.t[2], p.t[3] } }
end

-- The priors' χ² at a pose (the fit's own terms: `fit.prior_cost`).
local function prior_chi2(pr, pose)
  return fit.prior_cost(pr, pose.r, pose.t[3])
end

-- The score of a start: the priors' cost and each active tag's χ², capped.
local function score(obs, n, active, pr, pose, sigma)
  local r, t = pose.r, pose.t
  local s = 0
  for i = 1, n do
    if active[i] then
      local c = fit.tag_cost(obs[i], r, t[1], t[2], t[3], sigma)
      s = s + (c < M.CAP and c or M.CAP)
    end
  end
  return s + prior_chi2(pr, pose)
end

-- From a pose and a set of active tags: fit, take out the worst tag past `TAG_GATE` one at a
-- time, then (three tags or more) the worst by leave-one-out past `LOO_GATE`, then bring back a
-- tag left out that agrees with the fit of the rest. Returns the fit's χ², the tags kept, the
-- rejected list (ids and χ²) and each tag's leave-one-out χ² of the first round; nil when a tag
-- falls behind a camera.
local function refine(obs, n, active, kept, pr, pose, sigma, rejected)
  local chi2
  local loo = {}
  while true do
    chi2 = fit.fit(obs, n, active, pr, pose, sigma)
    if not (chi2 < huge) then return nil end
    local worst, worst_c = nil, M.TAG_GATE
    for i = 1, n do
      if active[i] then
        local c = fit.tag_cost(obs[i], pose.r, pose.t[1], pose.t[2], pose.t[3], sigma)
        if c > worst_c then worst, worst_c = i, c end
      end
    end
    if not worst or kept == 1 then break end
    active[worst] = false
    kept = kept - 1
    rejected[#rejected + 1] = { id = obs[worst].id, chi2 = worst_c, i = worst }
  end
  -- leave-one-out: with three tags or more, what each tag adds to the fit's χ² (the χ² with it
  -- less the χ² of the fit of the others: χ²(8) for a tag that agrees, whatever its own
  -- residuals); the worst past `LOO_GATE` leaves. A tag off its map place by 10 cm is absorbed
  -- by a joint fit of far tags, its own residuals small, the others' raised: only this shows it.
  while kept >= 3 do
    local worst, worst_c = nil, M.LOO_GATE
    for i = 1, n do
      if active[i] then
        active[i] = false
        local p = copy_pose(pose)
        local c = chi2 - fit.fit(obs, n, active, pr, p, sigma)
        if loo[obs[i].id] == nil then loo[obs[i].id] = c end
        if c > worst_c then worst, worst_c = i, c end
        active[i] = true
      end
    end
    if not worst then break end
    active[worst] = false
    kept = kept - 1
    rejected[#rejected + 1] = { id = obs[worst].id, chi2 = worst_c, i = worst }
    chi2 = fit.fit(obs, n, active, pr, pose, sigma)
  end
  -- a tag left out that agrees with the fit of the rest comes back, until none does
  for _ = 1, n do
    local back = false
    for k = #rejected, 1, -1 do
      local i = rejected[k].i
      if i and fit.tag_cost(obs[i], pose.r, pose.t[1], pose.t[2], pose.t[3], sigma)
        < M.TAG_GATE then
        active[i], kept, back = true, kept + 1, true
        table.remove(rejected, k)
      end
    end
    if not back then break end
    chi2 = fit.fit(obs, n, active, pr, pose, sigma)
  end
  return chi2, kept, loo
end

-- From a start: the tags that agree with it (χ² under `CAP`) fitted together, then each other
-- tag, the one the fit puts nearest first, kept when it adds at most `LOO_GATE` to the fit's χ²
-- (a far tag's own pose is too loose to agree with a near tag's start, a phantom adds
-- thousands), then `refine`. `set` is filled with the tags kept, `rejected` with the others.
-- Returns as `refine`, or nil.
local function consensus(obs, n, eligible, set, pr, pose, sigma, rejected)
  local count = 0
  for i = 1, n do
    set[i] = eligible[i] and fit.tag_cost(obs[i], pose.r, pose.t[1], pose.t[2], pose.t[3],
      sigma) < M.CAP
    if set[i] then count = count + 1 end
  end
  if count == 0 then return nil end
  local c0 = fit.fit(obs, n, set, pr, pose, sigma)
  if not (c0 < huge) then return nil end
  local more = true
  while more do
    more = false
    local order = {}
    for i = 1, n do
      if eligible[i] and not set[i] then
        local c = fit.tag_cost(obs[i], pose.r, pose.t[1], pose.t[2], pose.t[3], sigma)
        order[#order + 1] = { i = i, c = c < huge and c or huge }
      end
    end
    table.sort(order, function(a, b)
      if a.c ~= b.c then return a.c < b.c end
      return a.i < b.i
    end)
    for _, o in ipairs(order) do
      set[o.i] = true
      local p = copy_pose(pose)
      local c = fit.fit(obs, n, set, pr, p, sigma)
      if c < huge and c - c0 <= M.LOO_GATE then
        pose.r, pose.t, c0, count, more = p.r, p.t, c, count + 1, true
      else
        set[o.i] = false
      end
    end
  end
  for i = 1, n do
    if eligible[i] and not set[i] then
      rejected[#rejected + 1] = { id = obs[i].id, chi2 = fit.tag_cost(obs[i], pose.r,
        pose.t[1], pose.t[2], pose.t[3], sigma), i = i }
    end
  end
  return refine(obs, n, set, count, pr, pose, sigma, rejected)
end

--- Solve one frame: every tag fitted together from the best start, then the disagreeing ones
-- out; when that loses a tag, fails or the priors refuse it, a consensus grown from each start
-- (a phantom detection drags a joint fit until the real tags look worse than it; a far tag's
-- start can disagree with a near one that fits it well). The one the priors take wins, then
-- the one that keeps more tags, then the lower χ². `loo` is the winner's, with the joint fit's
-- for the tags the winner left out before its own leave-one-out (a tag off its map place shows
-- there).
-- @tparam {table,...} obs observations (`tagpose.localizer.fit`), each also with `id` and
--   `starts` (the robot poses its tag alone gives: one or two)
-- @tparam int n how many
-- @tparam table pr the priors (`fit.fit`)
-- @tparam number sigma σ, px
-- @tparam table nuisance σ of the mount and map (`fit.covariance`)
-- @tparam[opt] table start a pose to start from (tried beside each tag's)
-- @tparam[opt] table distrust `{[id] = why}`: tags left out whatever they show
-- @treturn table|nil `{pose =, covariance = flat 6×6, noise = its corners' share, used = {ids},
--   rejected = {{id =, why =}}, chi2 =, kept =, loo = {[id] = χ² added}}`, or nil and the
--   rejected list when no tag can be kept
function M.solve(obs, n, pr, sigma, nuisance, start, distrust)
  local active, eligible = {}, {}
  local fixed = {}
  local kept = 0
  for i = 1, n do
    local why = distrust and distrust[obs[i].id]
    active[i], eligible[i] = not why, not why
    if why then
      fixed[#fixed + 1] = { id = obs[i].id, why = why }
    else
      kept = kept + 1
    end
  end
  if kept == 0 then return nil, fixed end
  local best, best_score = nil, huge
  local seeds = {}
  local function try(p, i)
    local s = score(obs, n, active, pr, p, sigma)
    if s < huge then
      seeds[#seeds + 1] = { pose = p, score = s, prior = prior_chi2(pr, p), i = i or 0,
        k = #seeds }
    end
    if s < best_score then best, best_score = p, s end
  end
  if start then try(start) end
  -- each tag's starts, first fitted to that tag with the priors (a lone tag's pose is off the
  -- floor and tilted by its noise, which would count against the right one)
  local alone = {}
  for i = 1, n do
    if active[i] then
      alone[i] = true
      for _, p0 in ipairs(obs[i].starts) do
        local p = copy_pose(p0)
        if fit.fit(obs, n, alone, pr, p, sigma, START_ITERATIONS) < huge then try(p, i) end
      end
      alone[i] = nil
    end
  end
  if not best then return nil, fixed end
  -- every tag
  local pose = copy_pose(best)
  local rejected = {}
  local chi2, nkept, loo = refine(obs, n, active, kept, pr, pose, sigma, rejected)
  -- the consensus, when the joint fit lost a tag, failed, or the priors refuse it: from each
  -- start in order of score (ties: the order tried), one the priors refuse or whose tag a
  -- consensus already keeps aside
  local ok1 = chi2 and prior_chi2(pr, pose) <= M.PRIOR_GATE
  if not chi2 or nkept < kept or not ok1 then
    table.sort(seeds, function(a, b)
      if a.score ~= b.score then return a.score < b.score end
      return a.k < b.k
    end)
    local covered = {}
    for _, sd in ipairs(seeds) do
      if not covered[sd.i] and (sd.prior <= M.PRIOR_GATE or sd == seeds[1]) then
        local p2, rej2, set = copy_pose(sd.pose), {}, {}
        local c2, k2, l2 = consensus(obs, n, eligible, set, pr, p2, sigma, rej2)
        if c2 then
          for i = 1, n do
            if set[i] then covered[i] = true end
          end
          -- (a solution the priors refuse loses to one they take)
          local ok2 = prior_chi2(pr, p2) <= M.PRIOR_GATE
          if not chi2 or (ok2 and not ok1) or (ok2 == ok1 and (k2 > nkept
            or (k2 == nkept and c2 < chi2))) then
            for id, v in pairs(loo or {}) do
              if l2[id] == nil then l2[id] = v end
            end
            chi2, nkept, loo, pose, rejected, active, ok1 = c2, k2, l2, p2, rej2, set, ok2
          end
          if ok1 and nkept == kept then break end
        end
      end
    end
  end
  if not chi2 then return nil, fixed end
  for _, r in ipairs(rejected) do
    r.why = ("disagrees with the other tags (χ² %.0f over its 8 residuals)"):format(r.chi2)
    r.chi2, r.i = nil, nil
  end
  for _, r in ipairs(fixed) do rejected[#rejected + 1] = r end
  local pc = prior_chi2(pr, pose)
  -- the priors refuse the fit of several tags: the one without which they take it, if any (a
  -- tag off its map place tilts or lifts the robot to fit)
  while pc > M.PRIOR_GATE and nkept >= 2 do
    local best_i, best_c, best_p
    for i = 1, n do
      if active[i] then
        active[i] = false
        local p = copy_pose(pose)
        local c = fit.fit(obs, n, active, pr, p, sigma)
        if c < huge and prior_chi2(pr, p) <= M.PRIOR_GATE and (not best_c or c < best_c) then
          best_i, best_c, best_p = i, c, p
        end
        active[i] = true
      end
    end
    if not best_i then break end
    active[best_i] = false
    nkept, chi2, pose = nkept - 1, best_c, best_p
    rejected[#rejected + 1] = { id = obs[best_i].id,
      why = ("with it the floor, gravity or heading priors disagree (χ² %.0f)"):format(pc) }
    pc = prior_chi2(pr, pose)
  end
  if pc > M.PRIOR_GATE then
    -- the priors refuse these tags: the frame again without them, when others are left (a
    -- phantom beside one real tag may win the fit, and only the priors tell)
    local without, others = {}, false
    for k, v in pairs(distrust or {}) do without[k] = v end
    local why = ("the floor, gravity or heading priors disagree (χ² %.0f)"):format(pc)
    for i = 1, n do
      if active[i] then
        without[obs[i].id] = why
      elseif eligible[i] then
        others = true
      end
    end
    if others then return M.solve(obs, n, pr, sigma, nuisance, start, without) end
    for i = 1, n do
      if active[i] then rejected[#rejected + 1] = { id = obs[i].id, why = why } end
    end
    return nil, rejected
  end
  local cov, noise, sens = fit.covariance(obs, n, active, pr, pose, sigma, nuisance)
  if not cov then return nil, rejected end
  local used = {}
  for i = 1, n do
    if active[i] then used[#used + 1] = obs[i].id end
  end
  return { pose = pose, covariance = cov, noise = noise, sens = sens, used = used,
    rejected = rejected, chi2 = chi2, kept = nkept, active = active, loo = loo }
end

--- The other minimum of a solved frame: the best fit of the same tags from the starts that
-- land more than 5 cm or 2° from the solution.
-- @tparam {table,...} obs
-- @tparam int n
-- @tparam table sol a result of `solve`
-- @tparam table pr the priors
-- @tparam number sigma σ, px
-- @tparam table nuisance as for `solve`
-- @treturn table|nil `{pose =, chi2 =, covariance =, used =}`
function M.other(obs, n, sol, pr, sigma, nuisance)
  local best, best_c
  local p0 = sol.pose
  for i = 1, n do
    if sol.active[i] then
      for _, st in ipairs(obs[i].starts) do
        local p = copy_pose(st)
        local c = fit.fit(obs, n, sol.active, pr, p, sigma)
        local dx, dy, dz = p.t[1] - p0.t[1], p.t[2] - p0.t[2], p.t[3] - p0.t[3]
        local far = dx * dx + dy * dy + dz * dz > 0.05 ^ 2
          or rotation.angle(p.r, p0.r) > 0.035
        if c < huge and far and (not best_c or c < best_c) then best, best_c = p, c end
      end
    end
  end
  if not best or prior_chi2(pr, best) > M.PRIOR_GATE then return nil end
  local cov = fit.covariance(obs, n, sol.active, pr, best, sigma, nuisance)
  if not cov then return nil end
  return { pose = best, chi2 = best_c, covariance = cov, used = sol.used }
end

--- The robot poses a tag alone gives, from the camera-frame poses of `tagpose.solve`.
-- @tparam table tag a read map tag (`tagpose.rigid.model`)
-- @tparam table mount `{r =, t =}`
-- @tparam table pose a result of `tagpose.solve` (metres)
-- @treturn {table,...} one or two robot poses
function M.starts(tag, mount, pose)
  local out = {}
  local p = pose
  while p do
    local r = rotation.from_nested(p.rotation, {})
    local t = { p.position.x, p.position.y, p.position.z }
    out[#out + 1] = robot_pose(tag, mount, r, t)
    if p == pose then p = pose.alternative else p = nil end
  end
  return out
end

--- σ of a value from a flat 6×6's diagonal.
function M.sd(cov, i)
  local v = cov[(i - 1) * 6 + i]
  return v > 0 and sqrt(v) or 0
end

return M
