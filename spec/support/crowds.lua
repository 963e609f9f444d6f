-- Frames of many tags, arranged as adversarially as a detector could, for the block specs and
-- bench/many_tags.lua: n 24 mm tags of id 0 (corner noise 0.3 px) piled at one place
-- (`"pile"`: random poses around one image point), one tag copied n times (`"copies"`), or
-- n small tags spread over the image (`"spread"`), seen by the 320×240 camera `CAMERA`.

local geometry = require("support.geometry")

local M = {}

M.CAMERA = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 }

--- The detections of one such frame.
-- @tparam table rng a `support.geometry` generator
-- @tparam string kind `"pile"`, `"copies"` or `"spread"`
-- @tparam int n how many detections
-- @treturn {table,...} detections `{id = 0, corners = {{u, v}, ...}}`
function M.frame(rng, kind, n)
  local cam = M.CAMERA
  local dets = {}
  local r0, t0 = geometry.random_pose(rng, cam, 0.024, { width = 30, u = 160, v = 120 })
  for i = 1, n do
    local r, t = r0, t0
    if kind == "pile" then
      r, t = geometry.random_pose(rng, cam, 0.024, { width = rng.uniform(20, 40),
        u = 160 + rng.uniform(-5, 5), v = 120 + rng.uniform(-5, 5) })
    elseif kind == "spread" then
      r, t = geometry.random_pose(rng, cam, 0.024, { width = rng.uniform(8, 12),
        u = rng.uniform(10, 310), v = rng.uniform(10, 230) })
    end
    local px = assert(geometry.project(cam, r, t, 0.024))
    for k = 1, 4 do
      px[k][1], px[k][2] = px[k][1] + 0.3 * rng.normal(), px[k][2] + 0.3 * rng.normal()
    end
    dets[i] = { id = 0, corners = px }
  end
  return dets
end

return M
