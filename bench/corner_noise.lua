-- The corner noise of corner logs without ground truth, from the residuals of each row's
-- refined solve: 8 coordinates, 6 pose parameters, so a row's squared error sse (px²) is
-- σ² χ²₂ for Gaussian noise of σ per coordinate.
--
--   lua5.4 bench/corner_noise.lua [DIR ...]      (default: every bench/realdata/builderbot-*)
--
-- Prints per log the rows solved and two estimates of σ (px): pooled, sqrt(Σ sse / 2n), and
-- from the median, sqrt(median(sse) / (2 ln 2)) (χ²₂ is exponential: its median is 2 ln 2). On
-- Gaussian noise the two agree; a heavy tail (misdetections, a lens model off at the edges)
-- lifts the pooled one. Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")

local sqrt = math.sqrt

local dirs = {}
for i = 1, #arg do dirs[i] = arg[i] end
if #dirs == 0 then
  local p = io.popen("ls -1d bench/realdata/builderbot-* 2>/dev/null")
  for line in p:lines() do dirs[#dirs + 1] = line end
  p:close()
end

for _, dir in ipairs(dirs) do
  local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
  local size = type(info) == "table" and info.tag_size or 1
  local sum, all = 0, {}
  for _, row in ipairs(assert(log.read_corners(dir .. "/corners.csv"))) do
    local pose = tagpose.solve(row.corners, camera, size)
    if pose then
      local sse = 4 * pose.error ^ 2 -- error: the RMS over the four corners
      sum, all[#all + 1] = sum + sse, sse
    end
  end
  table.sort(all)
  local n = #all
  local median = n > 0 and (n % 2 == 1 and all[(n + 1) / 2] or 0.5 * (all[n / 2] + all[n / 2 + 1]))
    or 0
  print(("%-40s %5d rows  σ pooled %.3f px, from the median %.3f px"):format(dir, n,
    sqrt(sum / math.max(2 * n, 1)), sqrt(median / (2 * math.log(2)))))
end
