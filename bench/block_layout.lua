-- Blocks of a calibrated cube: calibrate a glued cube's nominal layout from DIR/calib (as
-- bench/score_layout.lua does), then solve DIR/test's frames with tagpose.block.solve given the
-- nominal, the calibrated and the true layout as options.layout, beside tagpose.layout.solve
-- given the same layouts.
--
--   lua5.4 bench/block_layout.lua DIR
--
-- DIR is a data set drawn like bench/dev/layout_cube (bench/make_layout.lua): camera.lua,
-- nominal_layout.csv, truth_layout.csv, calib/corners.csv, test/corners.csv and
-- test/truth_tags.csv. Printed per layout and solver: the test centres (the camera-frame centre
-- of every tag of the cube, seen or not, predicted from the pose of each test frame with the
-- layout solved with, against truth_tags.csv: median and 95th percentile, mm), the frames
-- given a pose, and the time per frame (os.clock, this VM). A block.solve frame whose tags
-- make more than one block is scored by its block of the most tags.

local root = arg and arg[0] and arg[0]:match("^(.-)/?bench/[^/]*$")
root = (root == nil or root == "") and "." or root
package.path = root .. "/src/?.lua;" .. root .. "/src/?/init.lua;" .. package.path

local tagpose = require("tagpose")
local set = dofile((arg[0]:match("^(.*)/[^/]*$") or ".") .. "/layout_set.lua")

local check, quantile = set.check, set.quantile

local dir = arg[1]
if not dir then
  io.stderr:write("usage: lua bench/block_layout.lua DIR\n")
  os.exit(2)
end

local camera = set.camera(dir .. "/camera.lua")
local nominal = check(tagpose.layout.read(dir .. "/nominal_layout.csv"))
local truth = check(tagpose.layout.read(dir .. "/truth_layout.csv"))

local test_frames, test_ids = set.frames_of(dir .. "/test/corners.csv")
local truth_by = set.truth_by(dir .. "/test/truth_tags.csv")

-- the pose a solver gives a frame: the body of layout.solve, the block of the most tags of
-- block.solve
local SOLVERS = {
  { "block.solve", function(dets, layout)
    local blocks = tagpose.block.solve(dets, camera, nil, nil, { layout = layout })
    local best = nil
    for _, b in ipairs(blocks or {}) do
      if not best or b.faces > best.faces then best = b end
    end
    return best
  end },
  { "layout.solve", function(dets, layout) return tagpose.layout.solve(dets, camera, layout) end },
}

-- test centre errors: median, p95 (mm), frames given a pose, µs per frame
local function score(solve, layout)
  local poses = {}
  local t0 = os.clock()
  for k, dets in ipairs(test_frames) do poses[k] = solve(dets, layout) or false end
  local per = (os.clock() - t0) / #test_frames
  local errs, solved = set.centre_errors(poses, layout, truth_by, test_ids)
  return quantile(errs, 0.5), quantile(errs, 0.95), solved, 1e6 * per
end

local calibrated = check(tagpose.layout.calibrate(set.frames_of(dir .. "/calib/corners.csv"),
  camera, nominal))

print(("%s: %d test frames (%s)"):format(dir, #test_frames,
  _VERSION .. (rawget(_G, "jit") and " " .. rawget(_G, "jit").version or "")))
print("| layout | solver | test centres median mm | p95 mm | frames solved | µs per frame |")
print("|---|---|---:|---:|---:|---:|")
for _, item in ipairs({ { "nominal", nominal }, { "calibrated", calibrated },
  { "true", truth } }) do
  for _, solver in ipairs(SOLVERS) do
    local med, p95, solved, us = score(solver[2], item[2])
    print(("| %s | %s | %.2f | %.2f | %d | %.0f |"):format(item[1], solver[1], med, p95, solved,
      us))
  end
end
