-- Speed and memory of tagpose on a data set, for the Lua it runs on: what a robot pays.
--
--   lua5.4 examples/benchmark.lua [DATASET_DIR] [--method refined|seed] [--passes N]
--   lua5.4 examples/benchmark.lua SEQUENCES_DIR --tracker [--passes N]
--   lua5.4 examples/benchmark.lua [DATASET_DIR] --controller [--passes N]
--   lua5.4 examples/benchmark.lua SEQUENCES_DIR --tracker --controller [--passes N]
--   lua5.4 examples/benchmark.lua --require
--   valgrind --tool=callgrind lua5.4 examples/benchmark.lua DATASET_DIR --solve-only N
--
-- DATASET_DIR is a directory in the format of bench/dev (camera.lua, corners.csv); default:
-- the bundled example (examples/data/camera.lua and approach.csv). Prints, as `key value`
-- pairs on one line after the VM's name (bench/speed.sh reads them):
--
--   solve      µs per plain solve (median of the passes after a warm-up pass; a fresh result
--              table each time), `into` the same with one pose table reused (options.into),
--              `read` the same reading pose.confidence and pose.covariance[1][1] of each;
--   bytes      allocated per plain solve with the collector stopped, `bytes_into` with
--              options.into (0 once warm), `bytes_read` reading confidence and covariance;
--   iterations the mean solveQuad iterations, the rows where solveQuad's safeguard found the
--              root (the report's update did not converge), the mean refinement
--              linearisations.
--
-- With --tracker the rows are tracked frame by frame (one detection a frame; in bench/dev's
-- `sequences`, frame = sequence·1000 + k, each sequence a tag and k/30 s its time) and it
-- prints µs per `tracker:update` of one detection, µs per plain solve of the same rows, and
-- their ratio. With --controller each row is a frame of a controller loop: other work first
-- (a ring of recent readings and its mean and spread, a sort with a comparator, a telemetry
-- line, a few fields of a robot record: interpreted code, as a robot's is), then the solve,
-- then (`read`) its confidence and covariance; it prints `work`, µs per frame of that work
-- alone, and `solve` and `read`, µs per frame of the loop less the work: what a solve costs
-- between other code rather than in a hot loop of solves, which is a best case (with --tracker,
-- `tracker:update` and a plain solve so, and their ratio). With --require
-- it prints the modules `require "tagpose"` loads and the heap they hold (KB, after a full
-- collection), then the same after a plain solve, and after reading confidence and covariance.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path

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
    elseif a == "--tracker" or a == "--require" or a == "--controller" then
      args[a:sub(3)] = true
    elseif a:sub(1, 2) == "--" then
      io.stderr:write("unknown option " .. a .. "\n")
      os.exit(2)
    else
      args.dir = a
    end
    i = i + 1
  end
end

local vm = rawget(_G, "jit") and rawget(_G, "jit").version or _VERSION

-- --require: what a robot's `require "tagpose"` costs (before anything else is loaded)
if args["require"] then
  local function count()
    local n = 0
    for name in pairs(package.loaded) do
      if name:match("^tagpose") then n = n + 1 end
    end
    collectgarbage("collect")
    collectgarbage("collect")
    return n, collectgarbage("count")
  end
  local _, base = count()
  local tagpose = require("tagpose")
  local n, heap = count()
  local pose = assert(tagpose.solve({ { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } },
    { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }, 0.024))
  local n2, heap2 = count()
  local _, _ = pose.confidence, pose.covariance
  local n3, heap3 = count()
  print(("%s | require modules %d heap_kb %.0f | after_solve modules %d heap_kb %.0f"
    .. " | after_reading modules %d heap_kb %.0f"):format(vm, n, heap - base, n2, heap2 - base,
    n3, heap3 - base))
  return
end

local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local solvequad = require("tagpose.core.solvequad")

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

-- the median CPU seconds of `passes` calls of f, after one to warm up (LuaJIT's traces)
local function median(f)
  f()
  local times = {}
  for p = 1, args.passes do
    local t0 = os.clock()
    f(p)
    times[p] = os.clock() - t0
  end
  table.sort(times)
  return times[math.floor((#times + 1) / 2)]
end

-- one pass over every row, solving with `opts` (and reading the uncertainty when asked)
local function solve_pass(opts, read)
  return function()
    local solve = tagpose.solve
    for i = 1, n do
      local pose = solve(corners[i], camera, tag_size, opts)
      if read and pose then
        local _, _ = pose.confidence, pose.covariance[1][1]
      end
    end
  end
end

-- a robot's other work between two frames (see the header); the same every run
local robot = { ring = {}, head = 0, mean = 0, spread = 0, speed = 0, heading = 0, line = "" }
local scratch = {}
local function descending(a, b) return a > b end
local function work(k)
  local ring = robot.ring
  robot.head = robot.head % 32 + 1
  ring[robot.head] = (k * 7919) % 1000 / 1000
  local sum, sq, m = 0, 0, #ring
  for j = 1, m do
    local v = ring[j]
    sum, sq = sum + v, sq + v * v
  end
  robot.mean = sum / m
  robot.spread = math.sqrt(math.max(sq / m - robot.mean * robot.mean, 0))
  for j = 1, 16 do scratch[j] = ring[(robot.head + j) % m + 1] end
  table.sort(scratch, descending)
  if robot.mean > 0.5 then
    robot.speed = robot.speed + 0.1 * (scratch[1] - robot.speed)
  else
    robot.heading = robot.heading - 0.1 * (scratch[16] - robot.heading)
  end
  robot.line = string.format("%d %.3f %.3f %.2f %.2f", k, robot.mean, robot.spread,
    robot.speed, robot.heading)
end

if args.tracker then
  -- one detection a frame; a sequence's frames are a track (ids and times from the frame)
  local frames = {}
  for i = 1, n do
    local f = rows[i].frame
    frames[i] = { { id = math.floor(f / 1000), corners = corners[i] } }
  end
  local tracked = median(function(p)
    local tr = tagpose.tracker.new(camera, tag_size)
    for i = 1, n do tr:update(frames[i], (p or 0) * 1e4 + (rows[i].frame % 1000) / 30) end
  end)
  local plain = median(solve_pass({}))
  if not args.controller then
    print(("%s | %s | tracker %d rows | update %.2f | solve %.2f | ratio %.2f"):format(vm, name,
      n, tracked / n * 1e6, plain / n * 1e6, tracked / plain))
    return
  end
  -- the same, each frame after the controller's other work (less the work timed alone)
  local t_work = median(function()
    for i = 1, n do work(i) end
  end)
  tracked = median(function(p)
    local tr = tagpose.tracker.new(camera, tag_size)
    for i = 1, n do
      work(i)
      tr:update(frames[i], (p or 0) * 1e4 + (rows[i].frame % 1000) / 30)
    end
  end) - t_work
  plain = median(function()
    local solve = tagpose.solve
    for i = 1, n do
      work(i)
      solve(corners[i], camera, tag_size)
    end
  end) - t_work
  print(("%s | %s | tracker %d rows, controller loop | work %.2f | update %.2f | solve %.2f"
    .. " | ratio %.2f"):format(vm, name, n, t_work / n * 1e6, tracked / n * 1e6, plain / n * 1e6,
    tracked / plain))
  return
end

if args.controller then
  local function loop(solving, read)
    return function()
      local solve = tagpose.solve
      for i = 1, n do
        work(i)
        if solving then
          local pose = solve(corners[i], camera, tag_size, options)
          if read and pose then
            local _, _ = pose.confidence, pose.covariance[1][1]
          end
        end
      end
    end
  end
  local t_work = median(loop(false))
  local t_solve = median(loop(true)) - t_work
  local t_both = median(loop(true, true)) - t_work
  print(("%s | %s | controller %d rows | work %.2f | solve %.2f | read %.2f"):format(vm, name, n,
    t_work / n * 1e6, t_solve / n * 1e6, t_both / n * 1e6))
  return
end

local t_plain = median(solve_pass(options))
local into_options = { method = args.method, into = {} }
local t_into = median(solve_pass(into_options))
local t_read = median(solve_pass(options, true))

-- bytes per solve with the collector stopped
local function bytes(opts, read)
  local pass = solve_pass(opts, read)
  collectgarbage("collect")
  -- (Lua 5.1's full collection shrinks the VM's own buffers; the first solve after it grows
  -- them back, once, which is not the solve's allocation)
  tagpose.solve(corners[1], camera, tag_size, opts)
  collectgarbage("stop")
  local before = collectgarbage("count")
  pass()
  local after = collectgarbage("count")
  collectgarbage("restart")
  return (after - before) * 1024 / n
end
local fresh = bytes(options)
local read = bytes(options, true)
-- warm-up: the table and its sub-tables come into being (and LuaJIT's traces for this path
-- settle: recording a trace allocates)
local reuse = { method = args.method, into = {} }
for _ = 1, 10 do bytes(reuse) end
local reused = bytes(reuse)

-- iteration counts
local sq, rf, failed, safeguard = 0, 0, 0, 0
for i = 1, n do
  local pose = tagpose.solve(corners[i], camera, tag_size, options)
  if pose then
    sq = sq + pose.iterations
    rf = rf + (pose.refine_iterations or 0)
    -- the report's update did not converge within its steps: the safeguard found the root
    if pose.iterations >= solvequad.REPORT_STEPS then safeguard = safeguard + 1 end
  else
    failed = failed + 1
  end
end
local ok = math.max(n - failed, 1)

print(("%s | %s | method %s | %d rows | solve %.2f | into %.2f | read %.2f | bytes %.0f"
  .. " | bytes_into %.0f | bytes_read %.0f | solveQuad %.2f, safeguard on %d rows | refine %.2f"
  .. " | failed %d"):format(vm, name, args.method or "refined", n, t_plain / n * 1e6,
  t_into / n * 1e6, t_read / n * 1e6, fresh, reused, read, sq / ok, safeguard, rf / ok, failed))
