--- Where the robot is: its pose on a map of tags, from one or more cameras on it, with the
-- priors a robot has (the floor, gravity, a gyro whose offset nobody reset, odometry that can
-- jump), the tags that disagree left out, and a covariance for the robot's pose.
--
--     local loc = tagpose.localizer.new(field, cameras)  -- a layout; cameras by name
--     loc:odometry(t, x, y, yaw)       -- the dead-reckoned pose, as WPILib's odometry gives it
--     loc:gyro(t, yaw)                 -- the gyro's heading (radians, any offset)
--     local est = loc:update("front", detections, capture_time)
--     est.position.x, est.yaw, est.sigma.x, est.covariance[1][1], est.tags, est.rejected
--
-- Frames: the map's (the field's: z up); the robot's (ROS: x forward, y left, z up, origin on
-- the floor under the robot); each camera's optical frame. A camera is a calibration
-- (`tagpose.solve`'s camera) with `mount = {position = {x, y, z}, quaternion = {w, x, y, z}}`,
-- camera → robot, metres. Corners are in the detector's order c1..c4, as for `tagpose.solve`
-- (`options.order = "opencv"` for OpenCV's). Times are seconds.
--
-- Each camera frame is solved alone (`tagpose.localizer.frame`): every map tag it saw, the floor
-- (`floor_sigma`) and gravity (`tilt_sigma`) as priors, a tag that disagrees with the rest left
-- out and listed with the reason. In the default mode the frames then correct a filter on the
-- robot's position and the gyro's offset (`tagpose.localizer.filter`) that odometry moves
-- between frames; with `mode = "single"` each frame is the answer, the gyro's heading a prior
-- whose offset is learnt from the frames before it. Data may arrive late and out of order
-- within `history` seconds: each result is as if everything had arrived in time order, and never
-- depends on data stamped after its time.
-- @module tagpose.localizer


local frame = require("tagpose.localizer.frame")
local model = require("tagpose.rigid.model")
local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")
local inputs = require("tagpose.localizer.options")
local engine = require("tagpose.localizer.engine")
local results = require("tagpose.localizer.result")
local mapcheck = require("tagpose.localizer.mapcheck")

local huge, exp = math.huge, math.exp
local is_finite, describe = compat.is_finite, args.describe
local read_camera, read_options, read_map, check_time = inputs.read_camera, inputs.read_options,
  inputs.read_map, inputs.check_time
local feed, result = engine.feed, results.result
local sigma_of, observations, estimate, heading = engine.sigma_of, engine.observations,
  engine.estimate, engine.heading
local run_odometry, run_gyro, run_frame = engine.run_odometry, engine.run_gyro, engine.run_frame

local M = {}

--- The options and their defaults (`tagpose.localizer.options`).
M.DEFAULTS = inputs.DEFAULTS
--- `localize` reports the other minimum when its χ² is within this of the best's.
M.ALTERNATIVE_GATE = 20

local Localizer = {}
Localizer.__index = Localizer

-- A frame's detections: a list (a single detection passed for it said so), at the caller's line.
local function check_detections(detections, n, fname)
  if type(detections) ~= "table" then
    args.raise(n, fname, "detections: table expected, got " .. type(detections), 3)
  end
  if detections.corners ~= nil then args.raise(n, fname, args.ONE_DETECTION, 3) end
end

--- A localizer on a map.
-- @tparam table map a layout `{tags = {[id] = {size =, position =, quaternion =}}}` in the
--   field's frame (`tagpose.layout.read` of a WPILib field, an apriltag_ros bundle, ...)
-- @tparam table cameras `{[name] = camera with mount}` (other non-table keys, such as a camera
--   file's `tag_size`, are ignored)
-- @tparam[opt] table options see `DEFAULTS`
-- @treturn table the localizer
-- @raise `bad argument` for a map, camera or option that is wrong
function M.new(map, cameras, options)
  local tags = read_map(map, 3)
  if type(cameras) ~= "table" then
    args.raise(2, "new", "cameras table {[name] = camera} expected, got " .. type(cameras), 2)
  end
  local cams, names = {}, {}
  for name, c in pairs(cameras) do
    if type(c) == "table" then names[#names + 1] = name end
  end
  table.sort(names, function(a, b) return tostring(a) < tostring(b) end)
  for i, name in ipairs(names) do
    cams[name] = read_camera(name, cameras[name], 4)
    cams[name].index = i
  end
  local count = #names
  if count == 0 then args.raise(2, "new", "no camera in cameras", 2) end
  local o = read_options(options, 3, "new", 3)
  local self = setmetatable({ tags = tags, cameras = cams, ncameras = count, options = o,
    events = {}, -- the events within `history`, in time order
    now = -huge, -- the time of the newest event processed
    warned = {},
    checks = {}, -- the map check's entries by tag id, then frame
  }, Localizer)
  self:reset_state()
  return self
end

--- Forget the estimate (the robot was carried elsewhere); the feeds' samples stay.
function Localizer:reset()
  self:reset_state()
  self.events = {}
end

function Localizer:reset_state()
  self.state = engine.new_state()
end

--- The robot's pose from one camera frame alone, with the floor and gravity as priors and,
-- when given, the heading (a gyro whose offset is known to `yaw_sigma`).
-- @tparam {table,...} detections `{id =, corners =}` each
-- @tparam table camera a calibration with its `mount` (as `new`'s cameras)
-- @tparam table map a layout in the field's frame
-- @tparam[opt] table options `new`'s options (`mode` aside), and `yaw` (radians) with
--   `yaw_sigma` (radians, default `gyro_sigma`)
-- @treturn table|nil as `update`'s result, and `confidence` (the probability that this is the
--   robot's pose rather than the other minimum's, from their χ²: `1 / (1 + exp(−Δχ²/2))`) and
--   `alternative` (the other minimum's result, with the tags it used) where there is one within
--   `ALTERNATIVE_GATE` of χ²; nil and the rejected list when no tag gives a pose
function M.localize(detections, camera, map, options)
  local yaw, yaw_sigma
  if options ~= nil then
    if type(options) ~= "table" then
      args.raise(4, "localize", "options table expected, got " .. type(options), 2)
    end
    local rest = {}
    for k, v in pairs(options) do
      if k == "yaw" then
        yaw = v
      elseif k == "yaw_sigma" then
        yaw_sigma = v
      else
        rest[k] = v
      end
    end
    if yaw ~= nil and not is_finite(yaw) then
      args.raise(4, "localize", "options.yaw: finite number (radians) expected, got "
        .. describe(yaw), 2)
    end
    if yaw_sigma ~= nil and not args.is_positive(yaw_sigma) then
      args.raise(4, "localize", "options.yaw_sigma: positive number (radians) expected, got "
        .. describe(yaw_sigma), 2)
    end
    options = rest
  end
  check_detections(detections, 1, "localize")
  local tags, err = model.read(map)
  if not tags then args.raise(3, "localize", err, 2) end
  local cam = read_camera("camera", camera, 3, 2, "localize")
  cam.index = 1
  local o = read_options(options, 4, "localize", 3)
  local self = setmetatable({ tags = tags, cameras = { camera = cam }, ncameras = 1,
    options = o, events = {}, now = -huge, warned = {}, checks = {} }, Localizer)
  self:reset_state()
  local s = self.state
  local sigma = sigma_of(self)
  s.sigma = sigma
  local pr = { sigma_z = o.floor_sigma > 0 and o.floor_sigma or nil,
    sigma_tilt = o.tilt_sigma > 0 and o.tilt_sigma or nil }
  if yaw then pr.yaw, pr.sigma_yaw = yaw, yaw_sigma or o.gyro_sigma end
  local obs, rejected = observations(self, cam, detections, s)
  if #obs == 0 then return nil, rejected end
  local nuisance = { mount_position = o.mount_position_sigma, mount_angle = o.mount_angle_sigma,
    map_position = o.map_sigma }
  local sol, rej = frame.solve(obs, #obs, pr, sigma, nuisance)
  for _, r in ipairs(sol and sol.rejected or rej or {}) do rejected[#rejected + 1] = r end
  if not sol then return nil, rejected end
  local res = result(nil, nil, sol.pose.r, sol.pose.t, sol.covariance, sol.used, rejected)
  res.confidence = 1
  -- the other minimum: the best fit, from the other starts, of the same tags that lands
  -- elsewhere (more than 5 cm or 2° away)
  local other = frame.other(obs, #obs, sol, pr, sigma, nuisance)
  if other and other.chi2 - sol.chi2 < M.ALTERNATIVE_GATE then
    local d = other.chi2 - sol.chi2
    local p = 1 / (1 + exp(-0.5 * d))
    res.confidence = p
    res.alternative = result(nil, nil, other.pose.r, other.pose.t, other.covariance, other.used,
      {})
    res.alternative.confidence = 1 - p
  end
  return res
end

--- Feed the robot's odometry: its dead-reckoned pose (any frame: it need not start at the
-- field's origin, nor with the gyro's heading).
-- @tparam number time s
-- @tparam number x m
-- @tparam number y m
-- @tparam number yaw radians
function Localizer:odometry(time, x, y, yaw)
  check_time(time, 1, "odometry")
  if not (is_finite(x) and is_finite(y) and is_finite(yaw)) then
    args.raise(2, "odometry", "x, y, yaw: finite numbers expected", 2)
  end
  feed(self, { t = time, x = x, y = y, yaw = yaw, run = run_odometry })
end

--- Feed the gyro's heading (radians; its offset is learnt from the tags).
-- @tparam number time s
-- @tparam number yaw radians
function Localizer:gyro(time, yaw)
  check_time(time, 1, "gyro")
  if not is_finite(yaw) then args.raise(2, "gyro", "finite number (radians) expected, got "
    .. describe(yaw), 2) end
  if (yaw > 7 or yaw < -7) and not self.warned.gyro then
    self.warned.gyro = true
    io.stderr:write("tagpose.localizer: a gyro heading of ", tostring(yaw),
      " is not radians (degrees?)\n")
  end
  feed(self, { t = time, yaw = yaw, run = run_gyro })
end

--- Feed one camera frame: the detections of one camera at its capture time.
-- @tparam string camera a name of `cameras`
-- @tparam {table,...} detections `{id =, corners =}` each (`tagpose.solve`'s corners)
-- @tparam number time the frame's capture time, s
-- @tparam[opt] table mount this frame's mount, `{position =, quaternion =}` (camera → robot),
--   for a camera that moves on the robot (on a lift); default the camera's own
-- @treturn table the robot's pose at that time: `position`, `rotation` (nested, robot → field),
--   `quaternion`, `yaw`, `covariance` (6×6: x, y, z, then a small rotation in the field frame),
--   `sigma = {x, y, yaw}`, `tags` (the ids used), `rejected` (`{id =, why =}`), `gyro_offset`,
--   `accepted` (the frame corrected the estimate); or, before the first frame that places the
--   robot, a table with `rejected` alone
-- @return nil, string when the frame is older than the history kept
function Localizer:update(camera, detections, time, mount)
  if self.cameras[camera] == nil then
    local names = {}
    for k in pairs(self.cameras) do names[#names + 1] = tostring(k) end
    table.sort(names)
    args.raise(1, "update", "unknown camera " .. (type(camera) == "string"
      and ("%q"):format(camera) or describe(camera)) .. " (cameras: "
      .. table.concat(names, ", ") .. ")", 2)
  end
  check_detections(detections, 2, "update")
  check_time(time, 3, "update")
  local cam
  if mount ~= nil then
    -- this frame's mount: the camera's calibration with it (a camera on a lift)
    local c = self.cameras[camera]
    local m = read_camera(camera, { fx = c.fx, fy = c.fy, cx = c.intr.cx, cy = c.intr.cy,
      mount = mount }, 3, 4, "update")
    cam = { name = c.name, intr = c.intr, fx = c.fx, fy = c.fy, index = c.index,
      mount = m.mount }
  end
  return feed(self, { t = time, camera = camera, detections = detections, run = run_frame,
    cam = cam })
end

--- Where each map tag was seen against where the map puts it (with `options.map_check`): for
-- each tag seen in a frame that placed the robot, the move of its centre that explains its
-- corners with the robot where the localizer put it (`tagpose.localizer.mapcheck`), in the
-- field frame, largest first.
-- @treturn {table,...} `{id =, dx =, dy =, dz =, distance =, frames =}` each
function Localizer:map_check()
  return mapcheck.list(self.checks)
end

--- The estimate at a time at or after the newest frame (the filter moved by the odometry).
-- @tparam number time s
-- @treturn table|nil as `update`'s result, without tags
function Localizer:pose(time)
  check_time(time, 1, "pose")
  local s = self.state
  if not s.filter then return nil end
  return estimate(self, time, nil, heading(s, time), nil, {}, {})
end

return M

