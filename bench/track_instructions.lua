-- The workload whose instructions bench/track_instructions.sh counts: the first N rows of a
-- sequence set, each solved alone (`plain`), solved with its `confidence` and `covariance` read
-- (`read`) or fed to tagpose.tracker, one detection a frame (`tracker`), with nothing else
-- done; N = 0 measures the start-up to subtract. PASSES (plain and read; default 1) solves the
-- rows that many times over: the difference of two counts with the same N is a steady state's
-- (bench/jit_instructions.sh, for LuaJIT once its traces are formed).
--
--   lua5.4 bench/track_instructions.lua plain|read|tracker N [SEQUENCES_DIR [PASSES]]
--
-- SEQUENCES_DIR defaults to bench/dev/sequences (frame = sequence * 1000 + k: a sequence's
-- rows are one track). Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")

local mode, n, dir = arg[1], tonumber(arg[2]), arg[3] or "bench/dev/sequences"
if (mode ~= "plain" and mode ~= "read" and mode ~= "tracker") or not n then
  io.stderr:write("usage: lua bench/track_instructions.lua plain|read|tracker N"
    .. " [SEQUENCES_DIR]\n")
  os.exit(2)
end
local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
local rows = assert(log.read_corners(dir .. "/corners.csv"))
assert(n <= #rows, "the set has " .. #rows .. " rows")
local corners = {}
for i = 1, n do corners[i] = rows[i].corners end
local size = info.tag_size
local passes = tonumber(arg[4]) or 1
if mode == "plain" then
  for _ = 1, passes do
    for i = 1, n do tagpose.solve(corners[i], camera, size) end
  end
elseif mode == "read" then
  for _ = 1, passes do
    for i = 1, n do
      local pose = tagpose.solve(corners[i], camera, size)
      if pose then
        local _, _ = pose.confidence, pose.covariance[1][1]
      end
    end
  end
else
  local tr = tagpose.tracker.new(camera, size)
  local frame = { { id = 0, corners = nil } }
  for i = 1, n do
    frame[1].id, frame[1].corners = math.floor(rows[i].frame / 1000), corners[i]
    tr:update(frame, (rows[i].frame % 1000) / 30)
  end
end
