-- Solve the pose of one AprilTag from its four corners and print it.
--
--   lua5.4 examples/solve.lua
--
-- Run from the repository root (or with tagpose installed by LuaRocks).

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")

-- The lab robot's camera (BuilderBot, 640x480 calibration), in pixels.
local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }
-- The corners the AprilTag detector returned, in its order: c1..c4 = the printed tag's
-- bottom-left, bottom-right, top-right, top-left corner (pixels, pixel centres at integers).
local corners = {
  { 184.3547, 315.4197 },
  { 233.2137, 320.1938 },
  { 239.2579, 271.1957 },
  { 190.5867, 265.5765 },
}
local tag_size = 0.024 -- side of the black square, metres: the pose comes out in metres

-- sigma: the detector's corner noise in pixels, for the pose's covariance and confidence
local pose, err = tagpose.solve(corners, camera, tag_size, { sigma = 0.5 })
if not pose then
  print("no pose: " .. err)
  os.exit(1)
end

local p, q, r = pose.position, pose.quaternion, pose.rotation
print(("position   x = %.4f m  y = %.4f m  z = %.4f m"):format(p.x, p.y, p.z))
print(("quaternion w = %.4f  x = %.4f  y = %.4f  z = %.4f"):format(q.w, q.x, q.y, q.z))
print("rotation (tag -> camera)")
for i = 1, 3 do
  print(("  % .4f  % .4f  % .4f"):format(r[i][1], r[i][2], r[i][3]))
end
print(("reprojection error %.3f px (%d solveQuad iterations, %d refinement steps)"):format(
  pose.error, pose.iterations, pose.refine_iterations))
-- the other pose a square seen in perspective can have (the planar ambiguity), if any
local alt = pose.alternative
if alt then
  local a = alt.quaternion
  print(("alternative: quaternion w = %.4f  x = %.4f  y = %.4f  z = %.4f, error %.3f px"):format(
    a.w, a.x, a.y, a.z, alt.error))
end
-- how far to trust it: the probability that this is the true one of the two, and the standard
-- deviations of the covariance (position in the tag size's unit, rotation in radians)
local c = pose.covariance
print(("confidence %.3f; 1σ: position %.1f %.1f %.1f mm, rotation %.1f %.1f %.1f°"):format(
  pose.confidence, 1000 * math.sqrt(c[1][1]), 1000 * math.sqrt(c[2][2]), 1000 * math.sqrt(c[3][3]),
  math.deg(math.sqrt(c[4][4])), math.deg(math.sqrt(c[5][5])), math.deg(math.sqrt(c[6][6]))))
