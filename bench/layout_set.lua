-- A glued-cube data set as bench/score_layout.lua and bench/block_layout.lua read it (drawn like
-- bench/dev/layout_cube by bench/make_layout.lua: camera.lua, nominal_layout.csv,
-- truth_layout.csv, calib/corners.csv, test/corners.csv, test/truth_tags.csv), and the test
-- centre errors both score with. Loaded with dofile beside the script (its package.path set to
-- the repository's src/ first):
--
--   local set = dofile((arg[0]:match("^(.*)/[^/]*$") or ".") .. "/layout_set.lua")

local log = require("tagpose.tools.log")
local rotation = require("tagpose.core.rotation")

local sqrt, floor = math.sqrt, math.floor

local M = {}

--- v, or (v nil) err on stderr and exit 1.
function M.check(v, err)
  if v == nil then
    io.stderr:write(tostring(err) .. "\n")
    os.exit(1)
  end
  return v
end

local check = M.check

--- The camera of a camera file: its intrinsics, distortion and model only.
function M.camera(path)
  local camera = check(log.read_camera(path))
  return { fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy,
    distortion = camera.distortion, model = camera.model }
end

--- The frames of detections of a corner log, in frame order, and their frame numbers.
function M.frames_of(path)
  local rows = check(log.read_corners(path))
  local by, order = {}, {}
  for _, r in ipairs(rows) do
    if not by[r.frame] then
      by[r.frame] = {}
      order[#order + 1] = r.frame
    end
    local f = by[r.frame]
    f[#f + 1] = { id = r.tag, corners = r.corners }
  end
  table.sort(order)
  local frames = {}
  for i, k in ipairs(order) do frames[i] = by[k] end
  return frames, order
end

--- The p quantile of list (sorted in place; interpolated), NaN for an empty list.
function M.quantile(list, p)
  table.sort(list)
  if #list == 0 then return 0 / 0 end
  local x = p * (#list - 1) + 1
  local lo = floor(x)
  local hi = math.min(lo + 1, #list)
  return list[lo] + (x - lo) * (list[hi] - list[lo])
end

--- The true tag centres of a truth_tags.csv: frame -> tag -> camera-frame position.
function M.truth_by(path)
  local truth_by = {}
  for _, e in ipairs(check(log.read_poses(path))) do
    truth_by[e.frame] = truth_by[e.frame] or {}
    truth_by[e.frame][e.tag] = e.pose.position
  end
  return truth_by
end

--- Test centre errors: the camera-frame centre of every tag of truth_by[ids[k]] predicted from
-- poses[k] (a body or block pose, false when the frame got none) with the layout solved with,
-- against the truth. Returns the errors (mm) and the frames given a pose.
function M.centre_errors(poses, layout, truth_by, ids)
  local errs, solved = {}, 0
  for k, pose in ipairs(poses) do
    if pose then
      solved = solved + 1
      local r, t = rotation.from_nested(pose.rotation), pose.position
      for id, p in pairs(truth_by[ids[k]]) do
        local c = layout.tags[id].position
        local x = r[1] * c.x + r[2] * c.y + r[3] * c.z + t.x
        local y = r[4] * c.x + r[5] * c.y + r[6] * c.z + t.y
        local z = r[7] * c.x + r[8] * c.y + r[9] * c.z + t.z
        errs[#errs + 1] = 1000 * sqrt((x - p.x) ^ 2 + (y - p.y) ^ 2 + (z - p.z) ^ 2)
      end
    end
  end
  return errs, solved
end

return M
