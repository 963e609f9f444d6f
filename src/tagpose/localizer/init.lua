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

local fit = require("tagpose.localizer.fit")
local frame = require("tagpose.localizer.frame")
local filter = require("tagpose.localizer.filter")
local model = require("tagpose.layout.model")
local rotation = require("tagpose.core.rotation")
local camera_mod = require("tagpose.core.camera")
local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")

local sqrt, cos, sin, rad, huge, exp = math.sqrt, math.cos, math.sin, math.rad, math.huge,
  math.exp
local wrap = fit.wrap
local is_finite, describe = compat.is_finite, args.describe

local M = {}

--- The options and their defaults.
M.DEFAULTS = {
  mode = "fused", -- or "single"
  sigma = false, -- corner noise, px: false to estimate it from the frames' residuals
  floor_sigma = 0.01, -- the robot's origin above the floor, m
  tilt_sigma = rad(1.0), -- roll and pitch, radians
  gyro_sigma = rad(0.1), -- the gyro's heading noise, radians
  mount_position_sigma = 0.01, -- the mounts as measured, m
  mount_angle_sigma = rad(0.5), -- radians
  map_sigma = 0.01, -- the tags' places, m
  history = 1.0, -- how late data may arrive, s
  order = "detector", -- or "opencv"
  map_check = false, -- true: keep where each tag is seen against the map (`map_check`)
}

local KEYS = {}
for k in pairs(M.DEFAULTS) do KEYS[#KEYS + 1] = k end
table.sort(KEYS)

--- A tag is left out once what it adds to the frames' fits (χ²(8) for a tag where the map says,
-- 8 on average) averages more than this...
M.DISTRUST = 30
--- ... over this many frames at least (an average over the last so many).
M.DISTRUST_FRAMES = 20
--- Weight of the past in the bias a frame's mount and map carry, per frame (0.97: the last
-- ~30 frames, half a second of two cameras).
M.BIAS_MEMORY = 0.97
--- `localize` reports the other minimum when its χ² is within this of the best's.
M.ALTERNATIVE_GATE = 20
--- The gyro's heading is extrapolated by its rate over this many seconds at most.
M.RATE_REACH = 0.1
--- The gyro's rate is taken over this many seconds at least.
M.RATE_BASE = 0.03
--- The RMS size of the error of a left-out tag's place, when single mode answers from such
-- tags alone (m): the size of the moves that make a tag left out.
M.DOUBT = 0.15
--- σ (px) of the corners until the frames' residuals tell.
M.DEFAULT_SIGMA = 0.5

local Localizer = {}
Localizer.__index = Localizer

local CAMERA_KEYS = { "fx", "fy", "cx", "cy", "model", "distortion", "width", "height", "name" }

-- A camera of the `cameras` table: its calibration for `tagpose.solve` and its mount.
local function read_camera(name, c, level, n, fname)
  n, fname = n or 2, fname or "new"
  if type(c) ~= "table" then
    args.raise(n, fname, "cameras." .. tostring(name) .. ": table expected, got " .. type(c),
      level)
  end
  local intr = {}
  for _, k in ipairs(CAMERA_KEYS) do intr[k] = c[k] end
  local ok, err = pcall(camera_mod.check, intr)
  if ok and err ~= nil and err ~= true and type(err) == "string" then ok = false end
  if not ok then
    args.raise(n, fname, "cameras." .. tostring(name) .. ": " .. tostring(err), level)
  end
  local m = c.mount
  if type(m) ~= "table" or type(m.position) ~= "table" or type(m.quaternion) ~= "table" then
    args.raise(n, fname, "cameras." .. tostring(name)
      .. ".mount: {position = {x, y, z}, quaternion = {w, x, y, z}} expected (camera → robot, m)",
      level)
  end
  local p, q = m.position, m.quaternion
  if not (is_finite(p.x) and is_finite(p.y) and is_finite(p.z)) then
    args.raise(n, fname, "cameras." .. tostring(name) .. ".mount.position: finite x, y, z expected",
      level)
  end
  local w, x, y, z = q.w, q.x, q.y, q.z
  if is_finite(w) and is_finite(x) and is_finite(y) and is_finite(z) then
    w, x, y, z = model.unit_quaternion(w, x, y, z)
  else
    w = nil
  end
  if not w then
    args.raise(n, fname, "cameras." .. tostring(name)
      .. ".mount.quaternion: a finite, non-zero {w, x, y, z} expected", level)
  end
  return { name = name, intr = intr, fx = c.fx, fy = c.fy,
    mount = { r = rotation.from_quaternion(w, x, y, z, {}), t = { p.x, p.y, p.z } } }
end

-- The options, checked, over the defaults.
local function read_options(options, n, fname, level)
  local o = {}
  for k, v in pairs(M.DEFAULTS) do o[k] = v end
  if options == nil then return o end
  if type(options) ~= "table" then
    args.raise(n, fname, "options table expected, got " .. type(options), level)
  end
  local problem = args.unknown_keys(options, KEYS, "options")
  if problem then args.raise(n, fname, problem, level) end
  for k, v in pairs(options) do
    if k == "mode" then
      if v ~= "fused" and v ~= "single" then
        args.raise(n, fname, "options.mode: \"fused\" or \"single\" expected, got " .. describe(v),
          level)
      end
    elseif k == "order" then
      if v ~= "detector" and v ~= "opencv" then
        args.raise(n, fname, "options.order: \"detector\" or \"opencv\" expected, got "
          .. describe(v), level)
      end
    elseif k == "map_check" then
      if type(v) ~= "boolean" then
        args.raise(n, fname, "options.map_check: boolean expected, got " .. describe(v), level)
      end
    elseif k == "sigma" then
      if v ~= false and not args.is_positive(v) then
        args.raise(n, fname, "options.sigma: positive number (px) or false expected, got "
          .. describe(v), level)
      end
    elseif not (is_finite(v) and v >= 0) then
      args.raise(n, fname, "options." .. k .. ": number >= 0 expected, got " .. describe(v), level)
    end
    o[k] = v
  end
  if o.tilt_sigma > 0.5 or o.mount_angle_sigma > 0.5 or o.gyro_sigma > 1 then
    args.raise(n, fname, "options: tilt_sigma, mount_angle_sigma and gyro_sigma are radians "
      .. "(got a value over 0.5: degrees?)", level)
  end
  return o
end

-- The map: a layout (`tagpose.layout.read`'s) read into tags with their corners in the field.
local function read_map(map, level)
  local tags, err = model.read(map)
  if not tags then args.raise(1, "new", err, level) end
  return tags
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
  local s = {
    filter = false, -- the fused filter, once a frame started it
    offset = false, -- single mode: the offset's estimate and variance
    offset_var = 0,
    odo = false, -- the last odometry sample {t, x, y, yaw}
    odo_v = false, -- its body-frame velocity {vx, vy}
    gyro = false, -- the last gyro sample {t, unwrapped, raw}
    gyro_rate = 0,
    last_time = false, -- the filter's time (the last odometry sample's, or frame's)
    sse = 0, dof = 0, -- the residuals' sums, for σ
    tag_stats = {}, -- by tag id: {mean of what it adds to a fit's χ², frames}
    distrust = {}, -- by tag id: why it is left out
  }
  self.state = s
end

local function copy_state(s)
  local c = {}
  for k, v in pairs(s) do c[k] = v end
  if s.filter then c.filter = s.filter:copy() end
  -- (the tag statistics are replaced, never changed in place, entry by entry)
  local st = {}
  for k, v in pairs(s.tag_stats) do st[k] = v end
  c.tag_stats = st
  if s.bias then
    local b = {}
    for k, v in pairs(s.bias) do b[k] = { v[1], v[2], v[3], v[4] } end
    c.bias = b
  end
  return c
end

-- The gyro's heading at time t (extrapolated from the last sample by its rate), unwrapped;
-- false before any gyro sample (the odometry's heading stands in).
local function heading(s, t)
  local g = s.gyro
  if g then
    -- (extrapolated by its rate over `RATE_REACH` at most: a gyro that stopped is not spun on)
    local dt = t - g[1]
    if dt > M.RATE_REACH then dt = M.RATE_REACH end
    return g[2] + s.gyro_rate * dt
  end
  local o = s.odo
  if o then return o[4] end
  return false
end

local function process_gyro(self, t, yaw)
  local s = self.state
  local g = s.gyro
  if g then
    local u = g[2] + wrap(yaw - g[3])
    s.gyro = { t, u, yaw }
    -- the rate over `RATE_BASE` seconds at least: two samples' noise over 10 ms would add more
    -- to a heading extrapolated by it than the rate's own change
    local b = s.gyro_base
    local dt = t - b[1]
    if dt >= M.RATE_BASE then
      s.gyro_rate = (u - b[2]) / dt
      s.gyro_base = { t, u }
    end
  else
    s.gyro = { t, yaw, yaw }
    s.gyro_base = { t, yaw }
  end
end

local function process_odometry(self, t, x, y, yaw)
  local s = self.state
  local o = s.odo
  s.odo = { t, x, y, yaw }
  if not o then return end
  local dt = t - o[1]
  if not (dt > 0) then return end
  local dx, dy = x - o[2], y - o[3]
  local psi = o[4] + 0.5 * wrap(yaw - o[4])
  local c, si = cos(psi), sin(psi)
  local bx, by = c * dx + si * dy, -si * dx + c * dy
  s.odo_v = { bx / dt, by / dt }
  local f = s.filter
  if f then
    local g = heading(s, t - 0.5 * dt)
    -- (with no gyro the odometry's own heading stands in: its offset is as unknown)
    if not s.gyro then g = psi end
    f:step(bx, by, g, dt)
    s.last_time = t
  end
end

local lazy_tagpose -- tagpose itself (required here: it requires this module on demand)

-- The observations of a frame's detections of map tags, and the detections that are not.
local function observations(self, cam, detections, s, pr)
  local obs, rejected = {}, {}
  local tagpose = lazy_tagpose or require("tagpose")
  lazy_tagpose = tagpose
  local opencv = self.options.order == "opencv"
  local px = {}
  for i = 1, #detections do
    local d = detections[i]
    local tag = self.tags[d.id]
    if not tag then
      rejected[#rejected + 1] = { id = d.id, why = "not on the map" }
    else
      local ok = args.read_corners(d.corners, px, opencv)
      local xy = {}
      if ok == true then
        for k = 1, 4 do
          local x, y = camera_mod.normalise(cam.intr, px[2 * k - 1], px[2 * k])
          if not x then ok = false end
          xy[2 * k - 1], xy[2 * k] = x, y
        end
      end
      local pose = ok == true and tagpose.solve(d.corners, cam.intr, tag.size,
        { order = opencv and "opencv" or nil, sigma = s.sigma })
      if pose then
        obs[#obs + 1] = { id = d.id, tag = tag, mount = cam.mount, xy = xy, fx = cam.fx,
          fy = cam.fy, starts = frame.starts(tag, cam.mount, pose), camera_pose = pose }
      else
        rejected[#rejected + 1] = { id = d.id, why = "its corners give no pose" }
      end
    end
  end
  return obs, rejected, pr
end

-- A nested 6×6 from a flat one.
local function nested(c)
  local out = {}
  for i = 1, 6 do
    out[i] = { c[(i - 1) * 6 + 1], c[(i - 1) * 6 + 2], c[(i - 1) * 6 + 3], c[(i - 1) * 6 + 4],
      c[(i - 1) * 6 + 5], c[(i - 1) * 6 + 6] }
  end
  return out
end

-- The result table of a pose (r flat robot → field, t) and a flat covariance.
local function result(time, cam, r, t, cov, used, rejected)
  local q = {}
  q.w, q.x, q.y, q.z = rotation.to_quaternion(r)
  local C = nested(cov)
  return {
    time = time, camera = cam,
    position = { x = t[1], y = t[2], z = t[3] },
    rotation = rotation.to_nested(r, {}),
    quaternion = q,
    yaw = fit.yaw(r),
    covariance = C,
    sigma = { x = sqrt(C[1][1]), y = sqrt(C[2][2]), yaw = sqrt(C[6][6]) },
    tags = used, rejected = rejected,
  }
end

-- A rotation of heading yaw with the roll and pitch of r (or none).
local function with_yaw(r, yaw)
  -- R = Rz(yaw − yaw(r)) · r keeps r's tilt
  local d = yaw - (r and fit.yaw(r) or 0)
  local c, s = cos(d), sin(d)
  if not r then return { c, -s, 0, s, c, 0, 0, 0, 1 } end
  return { c * r[1] - s * r[4], c * r[2] - s * r[5], c * r[3] - s * r[6],
    s * r[1] + c * r[4], s * r[2] + c * r[5], s * r[3] + c * r[6], r[7], r[8], r[9] }
end

-- The odometry's motion from the filter's time to t, in the field (heading yaw): its last
-- velocity times the gap.
local function ahead(s, t, yaw)
  local v, o = s.odo_v, s.odo
  if not (v and o) then return 0, 0 end
  local dt = t - o[1]
  if dt <= 0 then return 0, 0 end
  local c, si = cos(yaw), sin(yaw)
  if s.filter then dt = dt * (1 + s.filter.k) end
  return (c * v[1] - si * v[2]) * dt, (si * v[1] + c * v[2]) * dt
end

-- σ of the corners: the option, or the frames' residuals pooled with the default.
local function sigma_of(self)
  local o = self.options
  if o.sigma then return o.sigma end
  local s = self.state
  local d = M.DEFAULT_SIGMA
  return sqrt((8 * d * d + s.sse) / (8 + s.dof))
end

-- The fused estimate at time t (gyro reading g): the filter moved by the odometry since its
-- time, the roll and pitch of r (or none), and its covariance: the filter's, the bias the
-- frames' mounts and map carry (`Σ_c (w_c / W)²` times camera c's mean, the cameras' mounts
-- being independent), the priors' σ for z, roll and pitch.
local function estimate(self, t, name, g, r, used, rejected)
  local s, o = self.state, self.options
  local f = s.filter
  local yaw = g - f.c
  local dx, dy = ahead(s, t, yaw)
  local P, NS = f.P, f.n
  local cov = {}
  for i = 1, 36 do cov[i] = 0 end
  local function set(i, j, v) cov[(i - 1) * 6 + j], cov[(j - 1) * 6 + i] = v, v end
  local b11, b12, b22, wt = 0, 0, 0, 0
  local bias = s.bias or {}
  for c = 1, self.ncameras do
    if bias[c] then wt = wt + bias[c][4] end
  end
  if wt > 0 then
    for c = 1, self.ncameras do
      local e = bias[c]
      if e then
        local k = e[4] / (wt * wt)
        b11, b12, b22 = b11 + k * e[1], b12 + k * e[2], b22 + k * e[3]
      end
    end
  end
  local h1, h2, h3 = f:heading_cov()
  set(1, 1, P[1] + b11); set(1, 2, P[2] + b12); set(2, 2, P[NS + 2] + b22)
  set(1, 6, h1); set(2, 6, h2); set(6, 6, h3 + o.gyro_sigma ^ 2)
  set(3, 3, o.floor_sigma ^ 2 + 1e-12)
  set(4, 4, o.tilt_sigma ^ 2 + 1e-12); set(5, 5, o.tilt_sigma ^ 2 + 1e-12)
  local res = result(t, name, with_yaw(r, yaw), { f.x + dx, f.y + dy, 0 }, cov, used, rejected)
  res.gyro_offset = f.c
  return res
end

-- The map check: each tag seen in a frame that placed the robot, the move of its centre that
-- explains its corners in that frame with the robot at the estimate (`fit.tag_normal`), with
-- its information; kept by tag, frame time and camera (a frame replayed after late data
-- replaces its own entry).
local function check_tags(self, time, camera, obs, r, t, sigma)
  local ch = self.checks
  for _, ob in ipairs(obs) do
    local A, b = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }, { 0, 0, 0 }
    if fit.tag_normal(ob, r, t[1], t[2], t[3], sigma, A, b) then
      local Ai = fit.invert(A, 3, {})
      if Ai then
        local e = ch[ob.id] or {}
        ch[ob.id] = e
        e[("%.9g %s"):format(time, tostring(camera))] = { time = time,
          -(Ai[1] * b[1] + Ai[2] * b[2] + Ai[3] * b[3]),
          -(Ai[4] * b[1] + Ai[5] * b[2] + Ai[6] * b[3]),
          -(Ai[7] * b[1] + Ai[8] * b[2] + Ai[9] * b[3]), A }
      end
    end
  end
end

local function process_frame(self, name, detections, t, moved)
  local s = self.state
  local o = self.options
  local cam = moved or self.cameras[name]
  local sigma = sigma_of(self)
  s.sigma = sigma
  local pr = { sigma_z = o.floor_sigma > 0 and o.floor_sigma or nil,
    sigma_tilt = o.tilt_sigma > 0 and o.tilt_sigma or nil }
  local g = heading(s, t)
  local f = s.filter
  local start
  if o.mode == "single" then
    if s.offset and g then
      pr.yaw = g - s.offset
      pr.sigma_yaw = sqrt(s.offset_var + o.gyro_sigma ^ 2)
    end
  elseif f then
    if s.last_time then f:walk(0, s.odo ~= false) end
    if not s.odo then
      f:walk(t - (s.last_time or t), false)
      s.last_time = t
    end
    local yaw = g - f.c
    local dx, dy = ahead(s, t, yaw)
    start = { r = with_yaw(nil, yaw), t = { f.x + dx, f.y + dy, 0 } }
  end
  local obs, rejected = observations(self, cam, detections, s)
  local nuisance = { mount_position = o.mount_position_sigma, mount_angle = o.mount_angle_sigma,
    map_position = o.map_sigma }
  local sol, rej = nil, {}
  local doubtful = false
  if #obs > 0 then
    sol, rej = frame.solve(obs, #obs, pr, sigma, nuisance, start, s.distrust)
    if not sol and pr.yaw and #obs >= 2 then
      -- single mode: tags enough to tell the heading without the gyro; when the heading the
      -- offset learnt so far gives is what they refuse, the offset is learnt again from them
      local free = { sigma_z = pr.sigma_z, sigma_tilt = pr.sigma_tilt }
      local sol2, rej2 = frame.solve(obs, #obs, free, sigma, nuisance, start, s.distrust)
      if sol2 and sol2.kept >= 2 then
        sol, rej, s.offset = sol2, rej2, false
      end
    end
    if not sol and o.mode == "single" and next(s.distrust) then
      -- single mode, only tags left out in view: answered from them all the same, their place
      -- as uncertain as `DOUBT` (the size of the moves that make a tag left out)
      doubtful = true
      for _, ob in ipairs(obs) do
        if s.distrust[ob.id] then ob.map_sigma = M.DOUBT end
      end
      sol, rej = frame.solve(obs, #obs, pr, sigma, nuisance, start)
      if sol then sol.loo = {} end
    end
  end
  if sol then
    -- what each tag adds to the fits of the frames it is in with two others, averaged: a tag
    -- the map puts elsewhere than it is adds more, frame after frame, and is then left out
    local st, changed = s.tag_stats, false
    for id, d in pairs(sol.loo) do
      local e = st[id]
      local m, k = e and e[1] or 0, e and e[2] or 0
      k = k + 1
      local w = k < M.DISTRUST_FRAMES and 1 / k or 1 / M.DISTRUST_FRAMES
      st[id] = { m + w * (d - m), k }
      changed = true
    end
    if changed then
      local distrust = {}
      for id, e in pairs(st) do
        if e[2] >= M.DISTRUST_FRAMES and e[1] > M.DISTRUST then
          distrust[id] = ("its place on the map disagrees with the other tags (%.0f on average "
            .. "over %d frames)"):format(e[1], e[2])
        end
      end
      s.distrust = distrust
    end
  end
  for _, r in ipairs(sol and sol.rejected or rej or {}) do rejected[#rejected + 1] = r end
  if sol and not o.sigma then
    -- the residuals' share of σ: the pixel part of χ² (priors aside, roughly), forgetting slowly
    local k = sol.kept
    if k >= 2 then
      s.sse = 0.995 * s.sse + sol.chi2 * sigma * sigma
      s.dof = 0.995 * s.dof + 8 * k - 6
    end
  end
  if o.mode == "single" then
    if not sol then return nil, rejected end
    local C = sol.covariance
    local yaw = fit.yaw(sol.pose.r)
    if g and not doubtful then
      local var = C[36] + o.gyro_sigma ^ 2
      if not s.offset then
        if sol.kept >= 2 or C[36] < rad(2) ^ 2 then s.offset, s.offset_var = g - yaw, var end
      else
        s.offset, s.offset_var = g - yaw, C[36]
      end
    end
    if o.map_check then check_tags(self, t, name, obs, sol.pose.r, sol.pose.t, sigma) end
    local res = result(t, name, sol.pose.r, sol.pose.t, C, sol.used, rejected)
    res.gyro_offset, res.accepted = s.offset or nil, true
    if doubtful then
      res.warning = "only tags whose place on the map is in doubt: their places taken as "
        .. M.DOUBT .. " m uncertain"
    end
    return res
  end
  -- fused
  if not f then
    if not sol or not g then return nil, rejected end
    local C = sol.covariance
    if not (sol.kept >= 2 or (C[1] + C[8]) < 0.3 ^ 2) then return nil, rejected end
    local yaw = fit.yaw(sol.pose.r)
    local dx, dy = ahead(s, t, yaw)
    local P = { C[1], C[2], -C[6], C[7], C[8], -C[12], -C[31], -C[32], C[36] }
    f = filter.new(sol.pose.t[1] - dx, sol.pose.t[2] - dy, g - yaw, P, self.ncameras,
      o.mount_angle_sigma)
    s.filter = f
    s.last_time = s.odo and s.odo[1] or t
  end
  local yaw0 = g - f.c
  local dx, dy = ahead(s, t, yaw0)
  local accepted = false
  if sol then
    local C = sol.covariance
    -- (the heading is compared with the gyro's: its noise adds to the frame's)
    local R = { C[1], C[2], C[6], C[7], C[8], C[12], C[31], C[32], C[36] + o.gyro_sigma ^ 2 }
    accepted = f:update(cam.index, sol.pose.t[1], sol.pose.t[2], fit.yaw(sol.pose.r), R, g, dx,
      dy, sol.kept >= 2)
    if accepted then
      -- the mount's and map's share of the frames' position (a bias the filter cannot average
      -- away), per camera (their mounts' errors are independent), weighted as the frames weigh
      -- in the estimate: by their information, forgetting with `BIAS_MEMORY`
      local W = sol.noise
      local w = 1 / (C[1] + C[8])
      local all = s.bias or {}
      local a = M.BIAS_MEMORY
      for _, e in pairs(all) do
        e[1], e[2], e[3], e[4] = a * e[1], a * e[2], a * e[3], a * e[4]
      end
      local b = all[cam.index] or { 0, 0, 0, 0 }
      b[1], b[2], b[3], b[4] = b[1] + w * (C[1] - W[1]), b[2] + w * (C[2] - W[2]),
        b[3] + w * (C[8] - W[8]), b[4] + w
      all[cam.index] = b
      s.bias = all
    else
      for _, id in ipairs(sol.used) do
        rejected[#rejected + 1] = { id = id, why = "the frame disagrees with the estimate" }
      end
    end
  end
  if accepted and o.map_check then
    local yaw = g - f.c
    local ex, ey = ahead(s, t, yaw)
    -- (the camera's heading error as the filter has it: its frames are seen through it)
    check_tags(self, t, name, obs, with_yaw(sol.pose.r, yaw + f.beta[cam.index]),
      { f.x + ex, f.y + ey, 0 }, sigma)
  end
  local res = estimate(self, t, name, g, accepted and sol.pose.r or nil,
    accepted and sol.used or {}, rejected)
  res.accepted = accepted
  return res
end

-- Feeds are checked at the facade.
local function check_time(t, n, fname)
  if not is_finite(t) then
    args.raise(n, fname, "time: finite number (s) expected, got " .. describe(t), 3)
  end
end

-- Insert an event in time order; process it now, or roll back and replay when it is late.
local function feed(self, ev)
  local evs = self.events
  local t = ev.t
  if t >= self.now then
    evs[#evs + 1] = ev
    ev.before = copy_state(self.state)
    self.now = t
    local res = ev.run(self, ev)
    -- drop what is older than the history
    local keep = t - self.options.history
    local first = 1
    while first < #evs and evs[first].t < keep do first = first + 1 end
    if first > 1 then
      local n = #evs
      for i = first, n do evs[i - first + 1] = evs[i] end
      for i = n - first + 2, n do evs[i] = nil end
    end
    return res
  end
  -- late: the first event after it, its state before, replayed in order
  local i = #evs
  while i >= 1 and evs[i].t > t do i = i - 1 end
  if i == 0 and #evs > 0 and evs[1].t > t then
    return nil, "older than the history kept (" .. self.options.history .. " s)"
  end
  table.insert(evs, i + 1, ev)
  self.state = copy_state(evs[i + 1 + 1] and evs[i + 2].before or self.state)
  local res
  for k = i + 1, #evs do
    local e = evs[k]
    e.before = copy_state(self.state)
    local r = e.run(self, e)
    if e == ev then res = r end
  end
  return res
end

local function run_odometry(self, e) process_odometry(self, e.t, e.x, e.y, e.yaw) end
local function run_gyro(self, e) process_gyro(self, e.t, e.yaw) end
local function run_frame(self, e)
  local res, rejected = process_frame(self, e.camera, e.detections, e.t, e.cam)
  if not res then res = { time = e.t, camera = e.camera, rejected = rejected } end
  e.result = res
  return res
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
  if type(detections) ~= "table" then
    args.raise(1, "localize", "detections: table expected, got " .. type(detections), 2)
  end
  if detections.corners ~= nil then
    args.raise(1, "localize", "a list of detections expected, got one detection (pass "
      .. "{detection})", 2)
  end
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
  if type(detections) ~= "table" then
    args.raise(2, "update", "detections: table expected, got " .. type(detections), 2)
  end
  if detections.corners ~= nil then
    args.raise(2, "update", "a list of detections expected, got one detection (pass "
      .. "{detection})", 2)
  end
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
-- corners with the robot where the localizer put it; over the frames, the median of each
-- coordinate, then the frames within 5σ of it (by each frame's own information, a phantom
-- detection's far outside) averaged by their information. Field frame, largest first.
-- @treturn {table,...} `{id =, dx =, dy =, dz =, distance =, frames =}` each
function Localizer:map_check()
  local out = {}
  for id, entries in pairs(self.checks) do
    local list = {}
    for _, e in pairs(entries) do list[#list + 1] = e end
    table.sort(list, function(a, b) return a.time < b.time end)
    local med = {}
    for k = 1, 3 do
      local v = {}
      for i, e in ipairs(list) do v[i] = e[k] end
      table.sort(v)
      local m = #v
      med[k] = m % 2 == 1 and v[(m + 1) / 2] or 0.5 * (v[m / 2] + v[m / 2 + 1])
    end
    local A, b, used = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }, { 0, 0, 0 }, 0
    for _, e in ipairs(list) do
      local W = e[4]
      local d1, d2, d3 = e[1] - med[1], e[2] - med[2], e[3] - med[3]
      local m2 = d1 * (W[1] * d1 + W[2] * d2 + W[3] * d3) + d2 * (W[4] * d1 + W[5] * d2
        + W[6] * d3) + d3 * (W[7] * d1 + W[8] * d2 + W[9] * d3)
      if m2 < 25 then
        for k = 1, 9 do A[k] = A[k] + W[k] end
        for k = 1, 3 do
          b[k] = b[k] + W[3 * k - 2] * e[1] + W[3 * k - 1] * e[2] + W[3 * k] * e[3]
        end
        used = used + 1
      end
    end
    local Ai = used > 0 and fit.invert(A, 3, {})
    if Ai then
      local dx = Ai[1] * b[1] + Ai[2] * b[2] + Ai[3] * b[3]
      local dy = Ai[4] * b[1] + Ai[5] * b[2] + Ai[6] * b[3]
      local dz = Ai[7] * b[1] + Ai[8] * b[2] + Ai[9] * b[3]
      out[#out + 1] = { id = id, dx = dx, dy = dy, dz = dz,
        distance = sqrt(dx * dx + dy * dy + dz * dz), frames = used }
    end
  end
  table.sort(out, function(a, b)
    if a.distance ~= b.distance then return a.distance > b.distance end
    return a.id < b.id
  end)
  return out
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
