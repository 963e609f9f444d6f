-- Fit the calibration of the tracking filter's confidence (`tagpose.track.CONFIDENCE`): the
-- increasing piecewise-linear map from the log-odds of the filter's posterior to the log-odds
-- of the confidence it returns.
--
--   luajit bench/fit_confidence.lua DIR ... [--knots 0,6,11,14,40] [--cap 9] [--set NAME=VALUE]
--
-- DIR: synthetic sequence sets (bench/make_sequences.lua), or directories of them. Each set is
-- fed frame by frame to `tagpose.tracker`; every tracked row past a track's first frame whose
-- two candidates differ by more than 10° gives a pair (the posterior's log-odds l, whether the
-- returned pose is the candidate nearer the truth). The map's values at the knots (l = 0 maps
-- to 0) are the increasing ones, at most `--cap` (default 9: beyond 99.99 % a wrong branch is
-- rare but not rarer, and the rows are too few to say how rare), that maximise the likelihood
-- of those outcomes (coordinate search); the slope beyond the last knot stays
-- `CONFIDENCE_TAIL`. Prints the table to put in
-- `tagpose.track`, and the expected calibration error (10 equal bins of confidence) of the
-- current map and of the fitted one on these rows. Fit on sets the figures are not reported on.

package.path = "./src/?.lua;./src/?/init.lua;./bench/lib/?.lua;" .. package.path
local bench = require("confidence")
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local track = require("tagpose.track")

local exp, deg, abs, floor = math.exp, math.deg, math.abs, math.floor

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: lua bench/fit_confidence.lua DIR ... "
    .. "[--knots 0,6,11,14,40] [--cap 9] [--set NAME=VALUE]\n")
  os.exit(2)
end

local opt = { knots = { 0, 6, 11, 14, 40 }, cap = 9 }
opt.dirs = bench.arguments(arg, {
  ["--knots"] = function(take)
    opt.knots = {}
    for v in (take() or usage("--knots needs values")):gmatch("[^,]+") do
      opt.knots[#opt.knots + 1] = tonumber(v) or usage("--knots: numbers expected")
    end
  end,
  ["--cap"] = function(take)
    opt.cap = tonumber(take() or "") or usage("--cap needs a number")
  end,
  ["--set"] = bench.set_constant(track, usage),
}, usage)
if #opt.dirs == 0 then usage() end
local sets = bench.sets(opt.dirs)
table.sort(sets)

-- the posteriors the tracker calibrates, in the order it does (one per tracked detection)
local calibrate = track.confidence
local posteriors = {}
track.confidence = function(p)
  posteriors[#posteriors + 1] = p
  return calibrate(p)
end

local L, right = {}, {} -- per scored row: the posterior's log-odds, whether it is right
for _, dir in ipairs(sets) do
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local rows = assert(log.read_corners(dir .. "/corners.csv"))
  local truth = assert(log.read_csv(dir .. "/truth.csv"))
  local tr = tagpose.tracker.new(camera, info.tag_size)
  local i = 1
  while i <= #rows do
    local j, frame = i, {}
    while j <= #rows and rows[j].frame == rows[i].frame do
      frame[#frame + 1] = { id = rows[j].tag, corners = rows[j].corners }
      j = j + 1
    end
    local before = #posteriors
    local seen = tr:update(frame, rows[i].fields.time or rows[i].frame / 30)
    local next_posterior = before
    for k = 1, #seen do
      local pose = seen[k].pose
      local alt = pose and pose.alternative
      if alt and not seen[k].new then
        next_posterior = next_posterior + 1
        local p = posteriors[next_posterior]
        local t = truth[i + k - 1]
        local rt = rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz)
        local r, ra = rotation.from_nested(pose.rotation), rotation.from_nested(alt.rotation)
        if deg(rotation.angle(r, ra)) > 10 then
          L[#L + 1] = p < 1 and math.log(p / (1 - p)) or 745
          right[#right + 1] = rotation.angle(rt, r) <= rotation.angle(rt, ra)
        end
      end
    end
    i = j
  end
end

-- the map through (knots[i], values[i]), slope `tail` beyond the last
local function map(l, knots, values)
  for i = 2, #knots do
    if l <= knots[i] then
      return values[i - 1] + (values[i] - values[i - 1]) * (l - knots[i - 1])
        / (knots[i] - knots[i - 1])
    end
  end
  return values[#values] + track.CONFIDENCE_TAIL * (l - knots[#knots])
end

local function loglik(knots, values)
  local s = 0
  for n = 1, #L do
    local z = map(L[n], knots, values)
    -- log of the logistic of ±z, without overflow
    local y = right[n] and z or -z
    s = s - (y > 0 and math.log(1 + exp(-y)) or (-y + math.log(1 + exp(y))))
  end
  return s
end

local function ece(confidence_of)
  local bins = {}
  for b = 1, 10 do bins[b] = { n = 0, c = 0, a = 0 } end
  for n = 1, #L do
    local c = confidence_of(L[n])
    local b = bins[c >= 1 and 10 or floor(c * 10) + 1]
    b.n, b.c = b.n + 1, b.c + c
    if right[n] then b.a = b.a + 1 end
  end
  local e = 0
  for b = 1, 10 do e = e + abs(bins[b].a - bins[b].c) / math.max(#L, 1) end
  return e
end

local knots = opt.knots
local values = {}
for i, k in ipairs(knots) do
  values[i] = i == 1 and 0 or math.min(opt.cap, map(k, { 0, 40 }, { 0, 9 }))
end
-- coordinate search, the values kept increasing and the first at 0
local step = 1
local best = loglik(knots, values)
while step > 1e-3 do
  local improved = false
  for i = 2, #values do
    for _, d in ipairs({ step, -step }) do
      local v = values[i] + d
      if v >= values[i - 1] and v <= opt.cap and (i == #values or v <= values[i + 1]) then
        local old = values[i]
        values[i] = v
        local ll = loglik(knots, values)
        if ll > best then
          best, improved = ll, true
        else
          values[i] = old
        end
      end
    end
  end
  if not improved then step = step / 2 end
end

local current = track.CONFIDENCE
local cur_knots, cur_values = {}, {}
for i = 1, #current, 2 do
  cur_knots[#cur_knots + 1], cur_values[#cur_values + 1] = current[i], current[i + 1]
end
local function logistic(z) return 1 / (1 + exp(-z)) end
local pairs_out = {}
for i = 1, #knots do
  pairs_out[#pairs_out + 1] = ("%g, %.2f"):format(knots[i], values[i])
end
print(("%d sets, %d rows with candidates > 10° apart [%s]"):format(#sets, #L, _VERSION
  .. (rawget(_G, "jit") and " (LuaJIT)" or "")))
print(("current map: ECE %.4f, log-likelihood %.1f"):format(ece(function(l)
  return logistic(map(l, cur_knots, cur_values)) end), loglik(cur_knots, cur_values)))
print(("fitted map:  ECE %.4f, log-likelihood %.1f"):format(ece(function(l)
  return logistic(map(l, knots, values)) end), best))
print("M.CONFIDENCE = { " .. table.concat(pairs_out, ", ") .. " }")
-- the reliability by the posterior's log-odds, and what each map says there
local edges = { 0, 1, 2, 3, 4, 6, 8, 11, 14, 20, 40, math.huge }
print("| posterior log-odds | rows | wrong | current map | fitted map |")
print("|---|---:|---:|---:|---:|")
for b = 1, #edges - 1 do
  local n, wrong = 0, 0
  for r = 1, #L do
    if L[r] >= edges[b] and L[r] < edges[b + 1] then
      n = n + 1
      if not right[r] then wrong = wrong + 1 end
    end
  end
  local mid = edges[b + 1] == math.huge and edges[b] or 0.5 * (edges[b] + edges[b + 1])
  print(("| %g–%g | %d | %.3f %% | %.3f %% | %.3f %% |"):format(edges[b], edges[b + 1], n,
    100 * wrong / math.max(n, 1), 100 * (1 - logistic(map(mid, cur_knots, cur_values))),
    100 * (1 - logistic(map(mid, knots, values)))))
end
