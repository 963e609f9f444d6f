-- One frame of the lab robot's camera: four tags (all id 0) on three blocks, two of them on one
-- block. Prints each block's pose.
--
--   lua5.4 examples/block_frame.lua

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")

-- the robot's camera (pixels), tags 24 mm on 55 mm cubes (metres)
local camera = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 }
local detections = {
  { id = 0, corners = { { 129.14, 187.80 }, { 153.07, 205.35 }, { 176.59, 185.62 },
    { 152.16, 170.76 } } },
  { id = 0, corners = { { 216.57, 211.13 }, { 232.41, 194.30 }, { 235.61, 173.70 },
    { 219.28, 190.37 } } },
  { id = 0, corners = { { 180.60, 152.28 }, { 204.59, 165.48 }, { 221.41, 150.96 },
    { 197.72, 139.47 } } },
  { id = 0, corners = { { 50.76, 65.57 }, { 65.58, 62.89 }, { 62.15, 48.41 },
    { 47.21, 51.64 } } },
}

-- up = "auto": the block seen with two faces shows which way is up; it decides the pose of
-- the blocks seen with one face
local blocks, err = tagpose.block.solve(detections, camera, 0.024, 0.055, { up = "auto" })
if not blocks then error(err) end
for _, b in ipairs(blocks) do
  local p, q = b.position, b.quaternion
  print(("block %d: %d face(s) (tags %s), centre (%.4f, %.4f, %.4f) m, "
    .. "q (%.3f, %.3f, %.3f, %.3f), %.2f px"):format(b.id, b.faces, table.concat(b.tags, ", "),
    p.x, p.y, p.z, q.w, q.x, q.y, q.z, b.error))
end
