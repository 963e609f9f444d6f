-- The shape of a robot controller step with tagpose: take the camera system's tag list as the
-- robot's Lua API hands it out, track every tag (tagpose.tracker: each physical tag's pose
-- from step to step, tags sharing an id told apart by where they are) and return the poses
-- and the blocks (tagpose.block, tracked from step to step).
--
--   lua5.4 examples/controller.lua [LOG.csv] [--camera CAMERA.lua] [--every N] [--fps F]
--
-- Standalone, it plays a recorded frame sequence (default: the bundled approach,
-- examples/data/approach.csv with examples/data/camera.lua) through the controller, one step
-- per frame (F frames per second, default 30), each frame's rows shaped as a camera system's
-- list, and prints the poses of every N-th step (default 20) and a summary.
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
--     for _, seen in ipairs(ctl:step(robot.camera_system.tags, robot.system.time)) do
--       -- a robot acts on a pose it can trust: the right branch of the planar ambiguity
--       -- with probability confidence (the tracker's posterior, calibrated)
--       if seen.pose and seen.pose.confidence >= 0.9 then
--         local p = seen.pose.position -- the tag's centre in the camera frame, metres
--         -- ... steer towards p, or log it
--       end
--     end
--   end
--   function reset() ctl:reset() end
--
-- The tag list: tags[i].id and tags[i].corners[j].x / .y (pixels, j = 1..4 in the detector's
-- order, see README "Conventions"); other fields (center, ...) are ignored. A malformed entry
-- (not a table, no id, a NaN id, corners that are not four points) never stops the robot: it
-- is skipped, and its entry in the result says why.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")

local M = {}
M.__index = M

--- Time between steps (s) when step() is not given the time.
M.STEP_TIME = 1 / 30

--- A controller for one camera.
-- camera: {fx =, fy =, cx =, cy =} (pixels, optionally distortion); tag_size: the side of the
-- tags' black square (poses come out in its unit), or {[id] = size, default = size}. options
-- (all optional): method ("refined" or "seed"), max_gap (seconds a tag may go unseen and keep
-- its track, default tagpose.tracker.MAX_GAP), block_size (side of the cubes carrying the
-- tags, for tagpose.block, default 0.055), block_ids (the ids of the tags on blocks, an array;
-- default all: other tags, such as wall markers, are not grouped into blocks).
function M.new(camera, tag_size, options)
  options = options or {}
  local problem = tagpose.camera.check(camera)
  if problem then error("bad argument #1 to 'new' (" .. problem .. ")", 2) end
  if type(tag_size) ~= "table" and not (type(tag_size) == "number" and tag_size > 0
    and tag_size < math.huge) then
    error("bad argument #2 to 'new' (positive number expected, got " .. tostring(tag_size)
      .. ")", 2)
  end
  local block_ids = nil
  if options.block_ids ~= nil then
    if type(options.block_ids) ~= "table" then
      error("bad argument #3 to 'new' (options.block_ids: array of ids expected)", 2)
    end
    block_ids = {}
    for _, id in ipairs(options.block_ids) do block_ids[id] = true end
  end
  local block_tag = type(tag_size) == "table" and tag_size.default or tag_size
  return setmetatable({
    tracker = tagpose.tracker.new(camera, tag_size, { method = options.method,
      max_gap = options.max_gap }),
    camera = camera,
    block_size = options.block_size or 0.055,
    block_tag = block_tag,
    block_ids = block_ids,
    count = 0, -- steps so far
    blocks = {}, -- the last step's blocks (never nil: block ids keep counting)
  }, M)
end

--- Forget every track and block (the robot was moved, or the experiment restarts). Track
-- and block ids keep counting: an id is never given to two tags.
function M:reset()
  self.tracker:reset()
  self.count = 0
  self.blocks = { next_id = self.blocks.next_id }
end

--- One control step: track every tag of the camera system's list.
-- time: the step's time in seconds (default: STEP_TIME after the last step).
-- Returns an array in the list's order of {index =, id =, track = <the physical tag's track
-- id>, pose = <tagpose.solve result or nil>, reason = <why not, or nil>, tracked = <true when
-- the tag's track continued from an earlier step>}, and the blocks (tagpose.block, each block's
-- `tags` indices into the list; an empty array when there are none).
function M:step(tags, time)
  self.count = self.count + 1
  if time == nil then time = (self.time or 0) + M.STEP_TIME end
  self.time = time
  if type(tags) ~= "table" then tags = {} end
  local seen = self.tracker:update(tags, time)
  local dets, index = {}, {}
  for i = 1, #seen do
    local s = seen[i]
    s.tracked = s.pose ~= nil and s.new == false
    -- only the well-formed detections of tags on blocks form blocks
    if s.track and (self.block_ids == nil or self.block_ids[s.id]) then
      dets[#dets + 1] = tags[i]
      index[#dets] = i
    end
  end
  local blocks = nil
  if #dets > 0 and self.block_tag then
    local ok, result = pcall(tagpose.block.solve, dets, self.camera, self.block_tag,
      self.block_size, { previous = self.blocks })
    if ok then blocks = result end
  end
  if blocks then
    for _, b in ipairs(blocks) do
      for k, t in ipairs(b.tags) do b.tags[k] = index[t] end
    end
  else
    -- no block this step: the next block still takes a new id
    blocks = { next_id = self.blocks.next_id }
  end
  self.blocks = blocks
  return seen, blocks
end

-- Standalone: play a corner log through the controller, frame by frame.
local function main(argv)
  local log = require("tagpose.tools.log")
  local path, camera_path, every, fps = nil, nil, 20, 30
  local i = 1
  while i <= #argv do
    local a = argv[i]
    if a == "--camera" then
      i = i + 1
      camera_path = argv[i]
    elseif a == "--every" then
      i = i + 1
      every = tonumber(argv[i])
    elseif a == "--fps" then
      i = i + 1
      fps = tonumber(argv[i])
    elseif a:sub(1, 2) == "--" or path then
      io.stderr:write("usage: lua examples/controller.lua [LOG.csv] [--camera CAMERA.lua]"
        .. " [--every N] [--fps F]\n")
      os.exit(2)
    else
      path = a
    end
    i = i + 1
  end
  path = path or "examples/data/approach.csv"
  camera_path = camera_path or (path:match("^(.*)/[^/]*$") or ".") .. "/camera.lua"
  if not (every and every >= 1) then every = 20 end
  if not (fps and fps > 0) then fps = 30 end
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
  local poses, failed, tracked, last_track = 0, 0, 0, 0
  print(("%s: %d detections in %d frames, one step per frame"):format(path, #rows, #order))
  for k, frame in ipairs(order) do
    local seen, blocks = ctl:step(frames[frame], frame / fps)
    local parts = {}
    for _, s in ipairs(seen) do
      if s.pose then
        poses = poses + 1
        if s.tracked then tracked = tracked + 1 end
        if s.track > last_track then last_track = s.track end
        local p = s.pose.position
        parts[#parts + 1] = ("tag %s track %d (%.3f, %.3f, %.3f) m %.2f px conf %.2f"):format(
          tostring(s.id), s.track, p.x, p.y, p.z, s.pose.error, s.pose.confidence)
      else
        failed = failed + 1
        parts[#parts + 1] = ("tag %s: %s"):format(tostring(s.id), s.reason)
      end
    end
    parts[#parts + 1] = #blocks .. " block(s)"
    if (k - 1) % every == 0 or k == #order then
      print(("step %3d, frame %s: %s"):format(ctl.count, tostring(frame),
        table.concat(parts, "; ")))
    end
  end
  print(("%d steps, %d poses (%d continuing a track), %d failed, %d tracks"):format(ctl.count,
    poses, tracked, failed, last_track))
end

if arg and arg[0] and arg[0]:match("controller%.lua$") then main(arg) end

return M
