-- The workload bench/versus.sh times: every row of a data set solved by the tagpose found in
-- SRC_DIR (this checkout's `src`, or another revision's), PASSES times, reading what MODE says
-- of each pose; prints the CPU seconds of the solves. The rows are read with this checkout's
-- reader (tagpose.tools.log) before SRC_DIR's tagpose is loaded, so both sides solve the same
-- numbers.
--
--   lua5.4 bench/versus.lua SRC_DIR plain|read|alternative|tracker [DATASET_DIR] [PASSES]
--
-- plain: nothing read; read: `confidence` and `covariance[1][1]`; alternative: `alternative`;
-- tracker: every row fed to one tracker, one detection a frame (a sequences set, by default
-- bench/dev/sequences: frame = sequence * 1000 + k, the tag's id the sequence, k/30 s its time).
-- Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local log = require("tagpose.tools.log")

local src, mode, passes = arg[1], arg[2], tonumber(arg[4] or 6)
local dir = arg[3] or (mode == "tracker" and "bench/dev/sequences" or "bench/dev/noise_0.5")
if not src or (mode ~= "plain" and mode ~= "read" and mode ~= "alternative"
    and mode ~= "tracker") or not passes then
  io.stderr:write("usage: lua bench/versus.lua SRC_DIR plain|read|alternative|tracker"
    .. " [DATASET_DIR] [PASSES]\n")
  os.exit(2)
end
local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
local rows = assert(log.read_corners(dir .. "/corners.csv"))
local corners = {}
for i = 1, #rows do corners[i] = rows[i].corners end
local size = info.tag_size

-- forget this checkout's modules: SRC_DIR's tagpose is loaded afresh
for name in pairs(package.loaded) do
  if name:match("^tagpose") then package.loaded[name] = nil end
end
package.path = src .. "/?.lua;" .. src .. "/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local solve = tagpose.solve

if mode == "tracker" then
  local frames, times = {}, {}
  for i = 1, #rows do
    local f = rows[i].frame
    frames[i] = { { id = math.floor(f / 1000), corners = corners[i] } }
    times[i] = (f % 1000) / 30
  end
  local t0 = os.clock()
  for p = 1, passes do
    local tr = tagpose.tracker.new(camera, size)
    for i = 1, #frames do tr:update(frames[i], p * 1e4 + times[i]) end
  end
  print(("%.4f"):format(os.clock() - t0))
  return
end

local t0 = os.clock()
for _ = 1, passes do
  for i = 1, #corners do
    local pose = solve(corners[i], camera, size)
    if pose and mode == "read" then
      local _, _ = pose.confidence, pose.covariance[1][1]
    elseif pose and mode == "alternative" then
      local _ = pose.alternative
    end
  end
end
print(("%.4f"):format(os.clock() - t0))
