-- The sampling error of a confidence's ECE on sets of a given size: single-tag sets with ground
-- truth, scored whole and in consecutive pieces of ROWS rows (as many sets of that size), beside
-- the same pieces with outcomes drawn from the confidence itself (what a perfectly calibrated
-- confidence would score on them).
--
--   luajit bench/confidence_sets.lua DIR ... [--rows 2000] [--spread-limit E] [--spread S]
--     [--kappa K]
--
-- DIR: a set (corners.csv, truth.csv, camera.lua; bench/make_tags.lua's or bench/dev's), or a
-- directory of them. Each row is solved with the set's σ (meta.json `sigma_px`) as
-- examples/uncertainty.lua does, and scored the same way: over the rows whose two candidates
-- differ by more than 10°, the expected calibration error (10 equal bins) of pose.confidence,
-- "right" meaning the pose is the candidate nearer the truth; wrong@.95 the share of the rows at
-- 0.95 or more that are wrong. --spread-limit, --spread and --kappa override
-- tagpose.uncertainty's SPREAD_LIMIT, SPREAD and KAPPA (`--spread-limit 1e300`: the confidence
-- without a limit). Prints each set's ECE and wrong@.95, then over every piece of every set: the
-- ECE's mean, 95th percentile and largest, how many pieces reach 0.030, and the same for the
-- drawn outcomes; and over every set, the rows at a confidence of 0.99 or more: how many, how
-- many of them wrong, and how many the confidence expects wrong. Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;./bench/lib/?.lua;" .. package.path
local bench = require("confidence")
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")
local uncertainty = require("tagpose.uncertainty")

local deg, ceil = math.deg, math.ceil

local function usage(msg)
  io.stderr:write((msg and msg .. "\n" or "") .. "usage: luajit bench/confidence_sets.lua DIR "
    .. "... [--rows 2000] [--spread-limit E] [--spread S] [--kappa K]\n")
  os.exit(2)
end

local opt = { rows = 2000 }
local handlers = {
  ["--rows"] = function(take)
    opt.rows = tonumber(take() or "") or usage("--rows needs a number")
  end,
}
for a, name in pairs({ ["--spread-limit"] = "SPREAD_LIMIT", ["--spread"] = "SPREAD",
  ["--kappa"] = "KAPPA" }) do
  handlers[a] = function(take)
    uncertainty[name] = tonumber(take() or "") or usage(a .. " needs a number")
  end
end
opt.dirs = bench.arguments(arg, handlers, usage)
if #opt.dirs == 0 then usage() end
local sets = bench.sets(opt.dirs)

local function sigma_of(dir)
  local f = io.open(dir .. "/meta.json", "r")
  if not f then return nil end
  local text = f:read("*a")
  f:close()
  local s = tonumber(text:match('"sigma_px"%s*:%s*([%d.eE+-]+)') or "")
  return s and s > 0 and s or nil
end

-- ECE (10 equal bins) and wrong@.95 of the confidences c[i0..i1] with outcomes y
local score = bench.calibration

-- Park-Miller (the same outcomes on every VM)
local state = 20240
local function uniform()
  state = (16807 * state) % 2147483647
  return state / 2147483647
end

local pieces, drawn = {}, {}
local top = { n = 0, wrong = 0, expected = 0 } -- the rows at 0.99 or more, every set's
for _, dir in ipairs(sets) do
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local rows = assert(log.read_corners(dir .. "/corners.csv"))
  local truth = assert(log.read_csv(dir .. "/truth.csv"))
  local options = { sigma = sigma_of(dir) }
  local c, y, d, starts = {}, {}, {}, {} -- per scored row; starts: first scored row per piece
  for i, row in ipairs(rows) do
    if (i - 1) % opt.rows == 0 then starts[#starts + 1] = #c + 1 end
    local pose = tagpose.solve(row.corners, camera, info.tag_size, options)
    local alt = pose and pose.alternative
    if alt then
      local r, ra = rotation.from_nested(pose.rotation), rotation.from_nested(alt.rotation)
      if deg(rotation.angle(r, ra)) > 10 then
        local t = truth[i]
        local rt = rotation.from_quaternion(t.qw, t.qx, t.qy, t.qz)
        local n = #c + 1
        c[n], y[n] = pose.confidence, rotation.angle(rt, r) <= rotation.angle(rt, ra)
        d[n] = uniform() < c[n]
        if c[n] >= 0.99 then
          top.n, top.expected = top.n + 1, top.expected + 1 - c[n]
          if not y[n] then top.wrong = top.wrong + 1 end
        end
      end
    end
  end
  local e, wrong, high = score(c, y, 1, #c)
  print(("%-40s %6d rows  ECE %.4f  wrong@.95 %.2f %% (%d of %d)"):format(dir, #rows, e,
    100 * wrong / math.max(high, 1), wrong, high))
  -- whole pieces only
  for k = 1, #starts do
    if k * opt.rows <= #rows then
      local last = (starts[k + 1] or #c + 1) - 1
      pieces[#pieces + 1] = score(c, y, starts[k], last)
      drawn[#drawn + 1] = score(c, d, starts[k], last)
    end
  end
end

local function summary(name, list)
  if #list == 0 then return end
  table.sort(list)
  local sum, reach = 0, 0
  for _, e in ipairs(list) do
    sum = sum + e
    if e >= 0.03 then reach = reach + 1 end
  end
  print(("%s: %d sets of %d rows, ECE mean %.4f, 95th percentile %.4f, largest %.4f; "
    .. "%d at 0.030 or more"):format(name, #list, opt.rows, sum / #list,
    list[ceil(0.95 * #list)], list[#list], reach))
end
summary("ground truth", pieces)
summary("outcomes drawn from the confidence", drawn)
print(("confidence 0.99 or more: %d rows, %d wrong where the confidence expects %.1f"):format(
  top.n, top.wrong, top.expected))
