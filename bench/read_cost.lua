-- What reading a pose's uncertainty costs, part by part: a data set's rows solved in a loop
-- with nothing read, with `confidence` read, with `covariance` read, with both; then the read
-- alone, on results solved beforehand (the analysis; the analysis and the covariance into new
-- tables; the same into one table reused). The difference between the read in the loop and
-- the read alone is what the interpreter charges for running it between two solves. Prints µs
-- a row, the least of ROUNDS rounds of each.
--
--   lua5.4 bench/read_cost.lua [DATASET_DIR] [ROUNDS]   (default bench/dev/noise_0.5, 5)
--
-- Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local read = require("tagpose.uncertainty.read")

local dir, rounds = arg[1] or "bench/dev/noise_0.5", tonumber(arg[2] or 5)
local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
local rows = assert(log.read_corners(dir .. "/corners.csv"))
local n, size, solve = #rows, info.tag_size, tagpose.solve
local corners = {}
for i = 1, n do corners[i] = rows[i].corners end

-- the results' metatables, for the read alone (the layout `tagpose.uncertainty.read` reads)
local mts = {}
for i = 1, n do
  local p = solve(corners[i], camera, size)
  if p then mts[#mts + 1] = getmetatable(p) end
end
-- a record of what is made on read, as `tagpose.result.pose` makes it
local x = { false, false, 0, 0, 0, 0, 0, 0, 0, 0, false, false, false, 1, 0, 0, 0, 0, 0, 0, 0,
  0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0 }
local out = { { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 },
  { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 } }
local analyse, covariance = read.analyse, read.covariance

local cases = {
  { "solve", n, function()
    for i = 1, n do solve(corners[i], camera, size) end
  end },
  { "solve, confidence", n, function()
    for i = 1, n do
      local p = solve(corners[i], camera, size)
      if p then local _ = p.confidence end
    end
  end },
  { "solve, covariance", n, function()
    for i = 1, n do
      local p = solve(corners[i], camera, size)
      if p then local _ = p.covariance end
    end
  end },
  { "solve, both", n, function()
    for i = 1, n do
      local p = solve(corners[i], camera, size)
      if p then local _, _ = p.confidence, p.covariance end
    end
  end },
  { "analysis alone", #mts, function()
    for i = 1, #mts do analyse(mts[i], x) end
  end },
  { "analysis, covariance (new tables)", #mts, function()
    for i = 1, #mts do
      analyse(mts[i], x)
      covariance(mts[i], x, false, nil)
    end
  end },
  { "analysis, covariance (one table)", #mts, function()
    for i = 1, #mts do
      analyse(mts[i], x)
      covariance(mts[i], x, false, out)
    end
  end },
}

local best = {}
for _ = 1, rounds do
  for k, case in ipairs(cases) do
    collectgarbage()
    local t = os.clock()
    case[3]()
    t = (os.clock() - t) / case[2] * 1e6
    if not best[k] or t < best[k] then best[k] = t end
  end
end
print(("%s, %s (%d rows), the least of %d rounds, µs a row:"):format(_VERSION, dir, n, rounds))
for k, case in ipairs(cases) do print(("  %-36s %6.2f"):format(case[1], best[k])) end
