-- Speed and memory of tagpose.solve on a data set, for the Lua it runs on.
--
--   lua5.4 examples/benchmark.lua [DATASET_DIR] [--method refined|seed] [--passes N]
--   valgrind --tool=callgrind lua5.4 examples/benchmark.lua DATASET_DIR --solve-only 1
--
-- DATASET_DIR is a directory in the format of bench/dev (camera.lua, corners.csv); default:
-- the bundled example (examples/data/camera.lua and approach.csv). Prints µs per pose (median
-- over passes, after a warm-up pass; fresh result tables, and with options.into reusing one
-- table), bytes allocated per pose with the collector stopped (the same two ways), and the
-- solveQuad and refinement iteration counts.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local solvequad = require("tagpose.core.solvequad")

local args = { dir = nil, method = nil, passes = 15 }
do
  local i = 1
  while i <= #arg do
    local a = arg[i]
    if a == "--method" then
      i = i + 1
      args.method = arg[i]
    elseif a == "--passes" then
      i = i + 1
      args.passes = tonumber(arg[i])
    elseif a == "--solve-only" then
      i = i + 1
      args.solve_only = tonumber(arg[i])
    elseif a:sub(1, 2) == "--" then
      io.stderr:write("unknown option " .. a .. "\n")
      os.exit(2)
    else
      args.dir = a
    end
    i = i + 1
  end
end
local dir = args.dir or "examples/data"
local corners_file = args.dir and dir .. "/corners.csv" or dir .. "/approach.csv"
local name = args.dir and dir:match("([^/]+)/*$") or "approach"

local camera, info = log.read_camera(dir .. "/camera.lua")
assert(camera, info)
local rows = assert(log.read_corners(corners_file))
local n = #rows
local corners = {}
for i = 1, n do corners[i] = rows[i].corners end
local tag_size = info.tag_size
local options = { method = args.method }

-- --solve-only N: solve every row N times and stop, for instruction counters (callgrind): the
-- difference of the counts for N = 1 and N = 0, divided by the rows, is the cost of a solve
if args.solve_only then
  for _ = 1, args.solve_only do
    for i = 1, n do tagpose.solve(corners[i], camera, tag_size, options) end
  end
  return
end

-- one pass over every row; returns CPU seconds
local function pass(opts)
  local t0 = os.clock()
  for i = 1, n do
    tagpose.solve(corners[i], camera, tag_size, opts)
  end
  return os.clock() - t0
end

-- warm up (LuaJIT traces, caches), then the median of the passes
pass(options)
local times = {}
for p = 1, args.passes do times[p] = pass(options) end
table.sort(times)
local median = times[math.floor((#times + 1) / 2)]
-- the same with one pose table reused (options.into): no allocation, so no collector's work
local into_timed = { method = args.method, into = {} }
pass(into_timed)
local times_into = {}
for p = 1, args.passes do times_into[p] = pass(into_timed) end
table.sort(times_into)
local median_into = times_into[math.floor((#times_into + 1) / 2)]

-- bytes per solve with the collector stopped
local function bytes(opts)
  collectgarbage("collect")
  -- (Lua 5.1's full collection shrinks the VM's own buffers; the first solve after it grows
  -- them back, once, which is not the solve's allocation)
  tagpose.solve(corners[1], camera, tag_size, opts)
  collectgarbage("stop")
  local before = collectgarbage("count")
  for i = 1, n do
    tagpose.solve(corners[i], camera, tag_size, opts)
  end
  local after = collectgarbage("count")
  collectgarbage("restart")
  return (after - before) * 1024 / n
end
local fresh = bytes(options)
local into_options = { method = args.method, into = {} }
-- warm-up: the table and its sub-tables come into being (and LuaJIT's traces for this path
-- settle: recording a trace allocates)
for _ = 1, 10 do bytes(into_options) end
local reused = bytes(into_options)

-- iteration counts
local sq, rf, sq_max, rf_max, failed, safeguard = 0, 0, 0, 0, 0, 0
for i = 1, n do
  local pose = tagpose.solve(corners[i], camera, tag_size, options)
  if pose then
    sq = sq + pose.iterations
    if pose.iterations > sq_max then sq_max = pose.iterations end
    -- the report's update did not converge within its steps: the safeguard found the root
    if pose.iterations >= solvequad.REPORT_STEPS then safeguard = safeguard + 1 end
    local k = pose.refine_iterations or 0
    rf = rf + k
    if k > rf_max then rf_max = k end
  else
    failed = failed + 1
  end
end
local ok = n - failed

local vm = rawget(_G, "jit") and rawget(_G, "jit").version or _VERSION
print(("%s | %s | method %s | %d rows | %.2f µs/pose | %.0f B/pose | %.0f B/pose with into"
  .. " (%.2f µs with into) | solveQuad mean %.2f max %d, safeguard on %d rows"
  .. " | refine mean %.2f max %d | %d failed"):format(
  vm, name, args.method or "refined", n, median / n * 1e6, fresh, reused, median_into / n * 1e6,
  sq / ok, sq_max, safeguard, rf / math.max(ok, 1), rf_max, failed))
