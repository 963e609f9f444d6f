--- Calibrating a layout from a recorded log: where the tags really are on the body.
--
-- The method (a bundle adjustment, `tagpose.layout.bundle`):
--
-- 1. Start. Every frame that sees two or more tags of the layout is solved with the nominal
--    layout (`tagpose.layout.solve`: each tag alone, then the joint fit): its body pose is the
--    frame's start. A frame that sees one tag says nothing about where the tags sit relative to
--    one another (its body pose absorbs any placement) and is left out; so is a frame whose
--    solve fails.
-- 2. Chaining. Tags seen together in a frame are linked; the tags linked, directly or through
--    others, to the reference tag (`options.reference`, default the tag seen most) are placed.
--    The others are reported with the reason and keep their nominal pose.
-- 3. Bundle adjustment over every frame's body pose and every placed tag's pose on the body,
--    the reference held fixed (the gauge), by Levenberg-Marquardt with the frame poses
--    eliminated frame by frame (Schur complement: time linear in the frames). A Cauchy loss on
--    each detection's squared residual, `ρ(s) = c²·ln(1 + s/c²)`, `c = robust·σ̂` per
--    coordinate (σ̂ from the median residual), keeps bad detections from pulling the layout.
--    It runs in stages: after each, σ̂ is estimated again (and after the first, each frame is
--    solved again with the layout reached, keeping the better pose: a frame whose start was on
--    the wrong branch is mended); it ends when σ̂ settles, or after `max_iterations`
--    linearisations in all.
-- 4. Gauge. The images fix the tags' poses relative to one another, not the body frame: the
--    result is moved rigidly onto the nominal layout (`tagpose.layout.align`). With
--    `options.gauge = "planes"` (the default) the motion brings the placed tags' planes onto
--    their nominal planes first (each corner's distance from its tag's nominal plane weighs
--    `1/IN_PLANE` times its distance within it): a tag is glued flat on its face, its errors
--    lie in the face's plane, so the body frame is the one the faces make (for a cube: its
--    faces' planes give the rotation and the centre; the in-plane places only what the planes
--    leave free). With `"corners"` it brings all the corners closest to their nominal places
--    alike (least squares, Horn's method): the tags' corrections are as small as they can be
--    in total. Either way the calibrated layout is in the nominal body frame as closely as the
--    data allow.
--
-- Lengths are in the layout's unit, angles in radians, residuals in pixels.
-- @module tagpose.layout.calibrate

local rotation = require("tagpose.core.rotation")
local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local model = require("tagpose.rigid.model")
local frame = require("tagpose.layout.solve")
local bundle = require("tagpose.layout.bundle")
local schur = require("tagpose.layout.schur")
local align = require("tagpose.layout.align")
local report = require("tagpose.layout.report")

local sqrt, huge, max = math.sqrt, math.huge, math.max

local M = {}

--- Default bound on the bundle adjustment's linearisations, over all stages.
M.MAX_ITERATIONS = 100
--- Bound on the stages (σ̂ estimated again between them).
M.MAX_STAGES = 4
--- The stages end when σ̂ changes by less than this fraction.
M.SIGMA_SETTLED = 0.05
--- Default robust scale, in σ̂: detections of RMS residual `robust·σ̂` weigh half.
M.ROBUST = 3
--- An iteration that lowers the cost by less than `COST_TOLERANCE·s²` ends a stage, `s²` the
-- cost per degree of freedom (≈ σ²): a change of the fit's χ² far below its statistical spread.
M.COST_TOLERANCE = 1e-3
--- ... or by less than `ROUND_OFF`² (px²) per residual (exact corners).
M.ROUND_OFF = 1e-10
--- Median of χ² with 8 degrees of freedom over 8: the median squared residual per coordinate of
-- a detection, in units of σ², when the fit takes nothing from it.
local CHI2_8_MEDIAN = 0.9180
--- With the gauge "planes", the weight of a tag's corners' distances from their nominal
-- places within the tag's plane, against 1 for their distances from the plane.
M.IN_PLANE = 1e-8
--- Detections whose robust weight falls below this are counted as outliers.
M.OUTLIER_WEIGHT = 0.5

-- Count the known, distinct ids of a frame's usable detections (no solving: frames with fewer
-- than two are no use), and its detections that are not usable (malformed, non-finite).
local corners = {}
local function known_ids(dets, tags)
  local seen, n, bad = {}, 0, 0
  for i = 1, #dets do
    local d = dets[i]
    local id = type(d) == "table" and d.id or nil
    if id ~= nil and tags[id] then
      if args.read_corners(d.corners, corners) ~= true then
        bad = bad + 1
      elseif not seen[id] then
        seen[id] = true
        n = n + 1
      end
    end
  end
  return n, bad
end

-- Union-find over tag ids.
local function find(parent, a)
  while parent[a] ~= a do
    parent[a] = parent[parent[a]]
    a = parent[a]
  end
  return a
end

-- Step 1: the frames' starts. Returns the kept frames `{index =, body =, ids =, dets =}` and
-- the counts for the report.
local function starts(frames, camera, tags, o)
  local kept, counts = {}, { total = #frames, used = 0, single = 0, unknown = 0, failed = 0,
    detections = 0, skipped = 0, elsewhere = 0 }
  local single_seen = {}
  for fi = 1, #frames do
    local dets = frames[fi]
    counts.detections = counts.detections + #dets
    local known, bad = known_ids(dets, tags)
    if known < 2 then counts.skipped = counts.skipped + bad end
    if known == 0 then
      counts.unknown = counts.unknown + 1
    elseif known == 1 then
      counts.single = counts.single + 1
      for i = 1, #dets do
        local d = dets[i]
        if type(d) == "table" and d.id ~= nil and tags[d.id] then single_seen[d.id] = true end
      end
    else
      local body, why = frame.solve(dets, camera, tags, { opencv = o.opencv })
      if not body then
        counts.failed = counts.failed + 1
        counts.first_failure = counts.first_failure or ("frame " .. fi .. ": " .. why)
      else
        counts.skipped = counts.skipped + #body.skipped
        if #body.tags < 2 then
          counts.single = counts.single + 1
          for i = 1, #body.ids do single_seen[body.ids[i]] = true end
        else
          kept[#kept + 1] = { index = fi, body = body, ids = body.ids, dets = dets }
        end
      end
    end
  end
  return kept, counts, single_seen
end

-- Step 2: the reference and the tags linked to it. Returns the reference id, the set of
-- placed ids, and the number of observations per id in the kept frames.
local function chain(kept, tags, reference)
  local parent, seen = {}, {}
  for _, id in ipairs(tags.ids) do parent[id], seen[id] = id, 0 end
  for _, k in ipairs(kept) do
    local ids = k.ids
    for i = 1, #ids do
      seen[ids[i]] = seen[ids[i]] + 1
      local a, b = find(parent, ids[1]), find(parent, ids[i])
      if a ~= b then parent[b] = a end
    end
  end
  if reference == nil then
    for _, id in ipairs(tags.ids) do
      if reference == nil or seen[id] > seen[reference] then reference = id end
    end
  end
  local placed = {}
  if seen[reference] > 0 then
    local root = find(parent, reference)
    for _, id in ipairs(tags.ids) do
      if seen[id] > 0 and find(parent, id) == root then placed[id] = true end
    end
  end
  return reference, placed, seen
end

-- Step 3's problem: the placed tags and the frames that see them, the starts.
local function problem(camera, kept, tags, placed, reference, opencv)
  local slot, order = {}, {}
  for _, id in ipairs(tags.ids) do
    if placed[id] then
      order[#order + 1] = id
      slot[id] = #order
    end
  end
  local frames_used = {}
  for _, k in ipairs(kept) do
    if placed[k.ids[1]] then frames_used[#frames_used + 1] = k end
  end
  local P = bundle.new(camera, #frames_used, #order)
  local S = { fr = {}, ft = {}, tq = {}, tp = {} }
  local free = 0
  for i, id in ipairs(order) do
    local t = tags[id]
    P.half[i] = t.half
    if id == reference then
      P.free[i] = 0
    else
      free = free + 1
      P.free[i] = free
    end
    for k = 1, 9 do S.tq[9 * (i - 1) + k] = t.r[k] end
    S.tp[3 * i - 2], S.tp[3 * i - 1], S.tp[3 * i] = t.x, t.y, t.z
  end
  local o = 0
  for f, k in ipairs(frames_used) do
    local b = k.body
    local r = rotation.from_nested(b.rotation)
    for j = 1, 9 do S.fr[9 * (f - 1) + j] = r[j] end
    S.ft[3 * f - 2], S.ft[3 * f - 1], S.ft[3 * f] = b.position.x, b.position.y, b.position.z
    P.first[f] = o + 1
    for j = 1, #b.tags do
      local d = k.dets[b.tags[j]]
      o = o + 1
      P.of[o], P.ot[o] = f, slot[b.ids[j]]
      args.read_corners(d.corners, corners, opencv)
      for c = 1, 8 do P.px[8 * (o - 1) + c] = corners[c] end
    end
    P.last[f] = o
  end
  return P, S, order, frames_used
end

-- The robust σ̂ from the observations' squared residuals (P.s): the median, scaled by the
-- degrees of freedom the fit takes.
local function robust_sigma(P)
  local n = #P.of
  local list = {}
  for o = 1, n do list[o] = P.s[o] / 8 end
  table.sort(list)
  local med = n % 2 == 1 and list[(n + 1) / 2] or 0.5 * (list[n / 2] + list[n / 2 + 1])
  local dof = 8 * n - 6 * P.nframes - 6 * (P.ntags - 1)
  local s2 = med / CHI2_8_MEDIAN * (8 * n) / max(dof, 1)
  return sqrt(max(s2, 1e-12))
end

local function copy_state(S, T)
  for _, key in ipairs({ "fr", "ft", "tq", "tp" }) do
    local a, b = S[key], T[key]
    for i = 1, #a do b[i] = a[i] end
  end
  return T
end

-- Levenberg-Marquardt at a fixed robust scale, from S (the result left in S, the other state
-- T a scratch). Returns the linearisations used and the cost.
local function adjust(P, S, T, c2, budget)
  local D = { x = {}, y = {} }
  local cost = bundle.cost(P, S, c2)
  local dof = max(8 * #P.of - 6 * P.nframes - 6 * (P.ntags - 1), 1)
  local lambda, used = 1e-3, 0
  local floor = 8 * #P.of * (M.ROUND_OFF * M.ROUND_OFF)
  local tolerance = max(M.COST_TOLERANCE * cost / dof, floor)
  while used < budget do
    bundle.linearise(P, S, c2)
    used = used + 1
    local accepted, new, done = false, huge, false
    while not accepted do
      if schur.step(P, lambda, D) then
        -- a step that promises (to first order) less than the tolerance: converged
        if schur.promise(P, D) <= 0.5 * tolerance then
          done = true
          break
        end
        bundle.apply(P, S, D, T)
        new = bundle.cost(P, T, c2)
        if new < cost then accepted = true end
      end
      if not accepted then
        lambda = lambda * 10
        if lambda > 1e10 then break end
      end
    end
    if not accepted then
      bundle.cost(P, S, c2) -- P.s back to S
      break
    end
    S.fr, T.fr, S.ft, T.ft, S.tq, T.tq, S.tp, T.tp = T.fr, S.fr, T.ft, S.ft, T.tq, S.tq, T.tp, S.tp
    local drop = cost - new
    cost = new
    lambda = max(lambda * 0.1, 1e-12)
    tolerance = max(M.COST_TOLERANCE * cost / dof, floor)
    if drop <= tolerance or done then break end
  end
  return used, cost
end

-- The tags as `tagpose.layout.solve` reads them, at the state's poses.
local function current_tags(P, S, order, tags)
  local out = {}
  for i, id in ipairs(order) do
    local r = {}
    for k = 1, 9 do r[k] = S.tq[9 * (i - 1) + k] end
    local x, y, z = S.tp[3 * i - 2], S.tp[3 * i - 1], S.tp[3 * i]
    local half = P.half[i]
    out[id] = { id = id, size = tags[id].size, half = half, r = r, x = x, y = y, z = z,
      points = model.corners(r, x, y, z, half, {}) }
  end
  return out
end

-- Solve every frame again with the layout reached; keep the new pose where it fits better.
local function reseat(P, S, T, c2, order, tags, frames_used, camera, opencv)
  local now = current_tags(P, S, order, tags)
  copy_state(S, T)
  local mended = 0
  for f, k in ipairs(frames_used) do
    local body = frame.solve(k.dets, camera, now, { opencv = opencv })
    if body then
      local r = rotation.from_nested(body.rotation)
      for j = 1, 9 do T.fr[9 * (f - 1) + j] = r[j] end
      T.ft[3 * f - 2], T.ft[3 * f - 1], T.ft[3 * f] = body.position.x, body.position.y,
        body.position.z
    end
  end
  -- per frame, the better of the two
  bundle.cost(P, S, c2)
  local before = {}
  for o = 1, #P.of do before[o] = P.s[o] end
  bundle.cost(P, T, c2)
  for f = 1, P.nframes do
    local a, b = 0, 0
    for o = P.first[f], P.last[f] do
      a = a + bundle.rho(before[o], c2)
      b = b + bundle.rho(P.s[o], c2)
    end
    if b < a then
      mended = mended + 1
      for j = 1, 9 do S.fr[9 * (f - 1) + j] = T.fr[9 * (f - 1) + j] end
      for j = 1, 3 do S.ft[3 * (f - 1) + j] = T.ft[3 * (f - 1) + j] end
    end
  end
  bundle.cost(P, S, c2)
  return mended
end

-- Step 4: move the placed tags rigidly onto their nominal places: their planes first, then
-- their corners in the planes (gauge "planes"), or all four corners of each alike ("corners").
local function to_nominal(P, S, order, tags, gauge)
  local a, b, pts, normals = {}, {}, {}, {}
  for i, id in ipairs(order) do
    local r = {}
    for k = 1, 9 do r[k] = S.tq[9 * (i - 1) + k] end
    model.corners(r, S.tp[3 * i - 2], S.tp[3 * i - 1], S.tp[3 * i], P.half[i], pts)
    local nominal, nr = tags[id].points, tags[id].r
    for k = 1, 12 do
      a[12 * (i - 1) + k], b[12 * (i - 1) + k] = pts[k], nominal[k]
    end
    for k = 1, 4 do
      local o = 12 * (i - 1) + 3 * (k - 1)
      normals[o + 1], normals[o + 2], normals[o + 3] = nr[3], nr[6], nr[9]
    end
  end
  local g, gx, gy, gz, rms
  if gauge == "corners" then
    g, gx, gy, gz, rms = align.rigid(a, b)
  else
    g, gx, gy, gz, rms = align.planes(a, b, normals, M.IN_PLANE)
  end
  local placed = {}
  for i, id in ipairs(order) do
    local r = {}
    for k = 1, 9 do r[k] = S.tq[9 * (i - 1) + k] end
    local x, y, z = S.tp[3 * i - 2], S.tp[3 * i - 1], S.tp[3 * i]
    placed[id] = {
      r = rotation.multiply(g, r),
      x = g[1] * x + g[2] * y + g[3] * z + gx,
      y = g[4] * x + g[5] * y + g[6] * z + gy,
      z = g[7] * x + g[8] * y + g[9] * z + gz,
    }
  end
  return placed, rms
end

--- Calibrate a layout (arguments checked by `tagpose.layout.calibrate`).
-- @tparam {table,...} frames arrays of detections
-- @tparam table camera a checked camera
-- @tparam table tags the nominal layout, read (`tagpose.rigid.model.read`)
-- @tparam table o the options: `max_iterations`, `reference`, `robust`, `sigma`, `opencv` (the
--   corners in OpenCV's order)
-- @tparam[opt] string name the layout's name, kept
-- @treturn table the calibrated layout
-- @treturn table the report (`tagpose.layout.report`)
-- @return nil, string when the log cannot calibrate the layout
function M.calibrate(frames, camera, tags, o, name)
  if #frames == 0 then return nil, "layout: the log has no frames" end
  if #tags.ids < 2 then return nil, "layout: a layout of one tag has nothing to calibrate" end
  local kept, counts, single_seen = starts(frames, camera, tags, o)
  if counts.unknown == counts.total then
    return nil, "layout: no frame sees a tag of the layout"
  end
  if #kept == 0 then
    return nil, "layout: no frame sees two tags of the layout together (" .. counts.single
      .. " frames see one, " .. counts.failed .. " could not be solved"
      .. (counts.first_failure and ("; " .. counts.first_failure) or "") .. ")"
  end
  local reference, placed, seen = chain(kept, tags, o.reference)
  if not placed[reference] then
    return nil, "layout: the reference tag " .. tostring(reference)
      .. " is never seen together with another tag"
  end
  local P, S, order, frames_used = problem(camera, kept, tags, placed, reference, o.opencv)
  counts.used, counts.elsewhere = #frames_used, #kept - #frames_used
  local T = copy_state(S, { fr = {}, ft = {}, tq = {}, tp = {} })
  local _, sse0 = bundle.cost(P, S)
  local budget, iterations, stages, mended = o.max_iterations or M.MAX_ITERATIONS, 0, 0, 0
  local K = o.robust or M.ROBUST
  local sigma = robust_sigma(P)
  while stages < M.MAX_STAGES and iterations < budget do
    stages = stages + 1
    local c2 = 8 * ((K * sigma) * (K * sigma))
    iterations = iterations + adjust(P, S, T, c2, budget - iterations)
    if stages == 1 then
      mended = reseat(P, S, T, c2, order, tags, frames_used, camera, o.opencv)
      if mended > 0 then
        iterations = iterations + adjust(P, S, T, c2, budget - iterations)
      end
    end
    local next_sigma = robust_sigma(P)
    local settled = math.abs(next_sigma - sigma) <= M.SIGMA_SETTLED * sigma
    sigma = next_sigma
    if settled and stages > 1 then break end
  end
  local c2 = 8 * ((K * sigma) * (K * sigma))
  bundle.cost(P, S, c2)
  local poses, alignment = to_nominal(P, S, order, tags, o.gauge)
  -- the layout
  local out = { name = name, tags = {} }
  for _, id in ipairs(tags.ids) do
    local t, p = tags[id], poses[id]
    if p then
      out.tags[id] = model.entry(p.r, p.x, p.y, p.z, t.size)
    else
      out.tags[id] = model.entry(t.r, t.x, t.y, t.z, t.size)
    end
  end
  local weights = {}
  for i = 1, #P.of do weights[i] = 1 / (1 + P.s[i] / c2) end
  local rep = report.build({
    P = P, order = order, tags = tags, poses = poses, seen = seen, single_seen = single_seen,
    placed = placed, reference = reference, counts = counts, weights = weights,
    outlier_weight = M.OUTLIER_WEIGHT, sigma = o.sigma, sigma_robust = sigma,
    iterations = iterations, stages = stages, mended = mended, alignment = alignment,
    rms_start = sqrt(sse0 / (8 * #P.of)), converged = iterations < budget,
  })
  return out, rep
end

compat.interpret(M.calibrate)

return M
