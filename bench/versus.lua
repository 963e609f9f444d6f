-- The workload bench/versus.sh times: every row of a data set solved by the tagpose found in
-- SRC_DIR (this checkout's `src`, or another revision's), PASSES times, reading what MODE says
-- of each pose; prints the CPU seconds of the solves. The rows are read with this checkout's
-- reader (tagpose.tools.log) before SRC_DIR's tagpose is loaded, so both sides solve the same
-- numbers.
--
--   lua5.4 bench/versus.lua SRC_DIR plain|read|alternative [DATASET_DIR] [PASSES]
--
-- plain: nothing read; read: `confidence` and `covariance[1][1]`; alternative: `alternative`.
-- Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local log = require("tagpose.tools.log")

local src, mode, dir, passes = arg[1], arg[2], arg[3] or "bench/dev/noise_0.5",
  tonumber(arg[4] or 6)
if not src or (mode ~= "plain" and mode ~= "read" and mode ~= "alternative") or not passes then
  io.stderr:write("usage: lua bench/versus.lua SRC_DIR plain|read|alternative [DATASET_DIR]"
    .. " [PASSES]\n")
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
local solve = require("tagpose").solve

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
