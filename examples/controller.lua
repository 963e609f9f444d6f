-- The shape of a robot controller step with tagpose: take the camera system's tag list as the
-- robot's Lua API hands it out, solve every tag, keep each tag's tracking state from step to
-- step, and return the poses and the blocks (tagpose.block, tracked from step to step).
--
--   lua5.4 examples/controller.lua [LOG.csv] [--camera CAMERA.lua] [--every N]
--
-- Standalone, it plays a recorded frame sequence (default: the bundled approach,
-- examples/data/approach.csv with examples/data/camera.lua) through the controller, one step
-- per frame, each frame's rows shaped as a camera system's list, and prints the poses of every
-- N-th step (default 20) and a summary.
--
-- On the robot, the controller's global entry points (ARGoS calls init, step, reset, destroy)
-- wrap it; with tagpose and this file on package.path:
--
--   local controller = require("controller")
--   local ctl
--   function init()
--     ctl = controller.new({ fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 }, 0.024)
--   end
--   function step()
--     for _, seen in ipairs(ctl:step(robot.camera_system.tags)) do
--       if seen.pose then
--         local p = seen.pose.position -- the tag's centre in the camera frame, metres
--         -- ... steer towards p, or log it
--       end
--     end
--   end
--   function reset() ctl:reset() end
--
-- The tag list: tags[i].id and tags[i].corners[j].x / .y (pixels, j = 1..4 in the detector's
-- order, see README "Conventions"); other fields (center, ...) are ignored.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")

local floor, min = math.floor, math.min

local M = {}
M.__index = M

--- A controller for one camera.
-- camera: {fx =, fy =, cx =, cy =} (pixels, optionally distortion); tag_size: the side of the
-- tags' black square (poses come out in its unit). options (all optional): method ("refined"
-- or "seed"), max_gap (steps a tag may go unseen and keep its track, default 1: only the
-- previous step's pose is a prior), block_size (side of the cubes carrying the tags, for
-- tagpose.block, default 0.055).
function M.new(camera, tag_size, options)
  local problem = tagpose.camera.check(camera)
  if problem then error("bad argument #1 to 'new' (" .. problem .. ")", 2) end
  if not (type(tag_size) == "number" and tag_size > 0 and tag_size < math.huge) then
    error("bad argument #2 to 'new' (positive number expected, got " .. tostring(tag_size)
      .. ")", 2)
  end
  options = options or {}
  return setmetatable({
    camera = camera,
    tag_size = tag_size,
    method = options.method,
    max_gap = options.max_gap or 1,
    block_size = options.block_size or 0.055,
    count = 0, -- steps so far
    tracks = {}, -- tag id -> list of {pose =, step =, u =, v =}
    blocks = nil, -- the last step's blocks, for tagpose.block's tracking
  }, M)
end

--- Forget every track (the robot was moved, or the experiment restarts).
function M:reset()
  self.count, self.tracks, self.blocks = 0, {}, nil
end

local function centre(corners)
  local u, v = 0, 0
  for j = 1, 4 do
    local c = corners[j]
    u, v = u + (c.x or c[1]), v + (c.y or c[2])
  end
  return u / 4, v / 4
end

-- the track of this id that the detection at (u, v) continues: the nearest one in the image
-- not taken yet this step (several tags may share an id, as on the faces of a block)
local function match(list, u, v, taken)
  local best, best_d = nil, math.huge
  for k = 1, #list do
    local t = list[k]
    if not taken[t] then
      local d = (t.u - u) ^ 2 + (t.v - v) ^ 2
      if d < best_d then best, best_d = t, d end
    end
  end
  return best
end

--- One control step: solve every tag of the camera system's list.
-- Returns an array in the list's order of {id =, pose = <tagpose.solve result or nil>,
-- reason = <why not, or nil>, tracked = <true when the tag's previous pose was the prior>},
-- and the blocks (tagpose.block; nil where the library has none).
function M:step(tags)
  tags = tags or {}
  self.count = self.count + 1
  local now, seen, taken = self.count, {}, {}
  local options = { method = self.method }
  for i = 1, #tags do
    local tag = tags[i]
    local id, corners = tag.id, tag.corners
    local result = { id = id }
    local ok, u, v = pcall(centre, corners)
    if not ok then
      result.reason = "controller: tag " .. i .. " has no four corners {x =, y =}"
    else
      local list = self.tracks[id] or {}
      self.tracks[id] = list
      local track = match(list, u, v, taken)
      options.prior = track and now - track.step <= self.max_gap and track.pose or nil
      result.tracked = options.prior ~= nil
      -- a malformed detection must not stop the robot: solve's misuse errors become reasons
      local solved, pose, reason = pcall(tagpose.solve, corners, self.camera, self.tag_size,
        options)
      if not solved then pose, reason = nil, tostring(pose) end
      result.pose, result.reason = pose, reason
      if pose then
        if not track then
          track = {}
          list[#list + 1] = track
        end
        track.pose, track.step, track.u, track.v = pose, now, u, v
        taken[track] = true
      end
    end
    seen[i] = result
  end
  -- forget the tracks that are too old to be a prior
  for id, list in pairs(self.tracks) do
    for k = #list, 1, -1 do
      if now - list[k].step >= self.max_gap then table.remove(list, k) end
    end
    if #list == 0 then self.tracks[id] = nil end
  end
  local blocks = nil
  if tagpose.block then
    blocks = tagpose.block.solve(tags, self.camera, self.tag_size, self.block_size,
      { previous = self.blocks })
    self.blocks = blocks
  end
  return seen, blocks
end

-- Standalone: play a corner log through the controller, frame by frame.
local function main(argv)
  local log = require("tagpose.tools.log")
  local path, camera_path, every = nil, nil, 20
  local i = 1
  while i <= #argv do
    local a = argv[i]
    if a == "--camera" then
      i = i + 1
      camera_path = argv[i]
    elseif a == "--every" then
      i = i + 1
      every = tonumber(argv[i])
    elseif a:sub(1, 2) == "--" or path then
      io.stderr:write("usage: lua examples/controller.lua [LOG.csv] [--camera CAMERA.lua]"
        .. " [--every N]\n")
      os.exit(2)
    else
      path = a
    end
    i = i + 1
  end
  path = path or "examples/data/approach.csv"
  camera_path = camera_path or (path:match("^(.*)/[^/]*$") or ".") .. "/camera.lua"
  if not (every and every >= 1) then every = 20 end
  local camera, info = log.read_camera(camera_path)
  if not camera then error(info) end
  local rows, problems = log.read_corners(path)
  if not rows then error(problems) end
  for _, p in ipairs(problems) do
    io.stderr:write(("%s line %d: %s (skipped)\n"):format(path, p.line, p.reason))
  end
  -- the frames, as the camera system would have handed them out
  local frames, order = {}, {}
  for _, row in ipairs(rows) do
    local list = frames[row.frame]
    if not list then
      list = {}
      frames[row.frame] = list
      order[#order + 1] = row.frame
    end
    local c = row.corners
    list[#list + 1] = { id = row.tag, corners = { { x = c[1][1], y = c[1][2] },
      { x = c[2][1], y = c[2][2] }, { x = c[3][1], y = c[3][2] }, { x = c[4][1], y = c[4][2] } } }
  end
  table.sort(order)
  local ctl = M.new(camera, info.tag_size)
  local poses, failed, tracked = 0, 0, 0
  print(("%s: %d detections in %d frames, one step per frame"):format(path, #rows, #order))
  for k, frame in ipairs(order) do
    -- a frame without detections is a step too (its tracks age)
    local skipped = k > 1 and frame - order[k - 1] - 1 or 0
    if skipped >= 1 and floor(skipped) == skipped then
      for _ = 1, min(skipped, 1000) do ctl:step({}) end
    end
    local seen, blocks = ctl:step(frames[frame])
    local parts = {}
    for _, s in ipairs(seen) do
      if s.pose then
        poses = poses + 1
        if s.tracked then tracked = tracked + 1 end
        local p = s.pose.position
        parts[#parts + 1] = ("tag %s (%.3f, %.3f, %.3f) m %.2f px"):format(tostring(s.id), p.x,
          p.y, p.z, s.pose.error)
      else
        failed = failed + 1
        parts[#parts + 1] = ("tag %s: %s"):format(tostring(s.id), s.reason)
      end
    end
    if blocks then parts[#parts + 1] = #blocks .. " block(s)" end
    if (k - 1) % every == 0 or k == #order then
      print(("step %3d, frame %s: %s"):format(ctl.count, tostring(frame),
        table.concat(parts, "; ")))
    end
  end
  print(("%d steps, %d poses (%d with the previous step's pose as prior), %d failed"):format(
    ctl.count, poses, tracked, failed))
end

if arg and arg[0] and arg[0]:match("controller%.lua$") then main(arg) end

return M
