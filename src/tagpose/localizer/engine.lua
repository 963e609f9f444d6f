--- The localizer's engine: its state, each feed's processing in time order (a late one rolled
-- back and replayed), and a camera frame turned into the robot's pose (`tagpose.localizer`
-- documents what it does; this is how).
-- @module tagpose.localizer.engine

local fit = require("tagpose.localizer.fit")
local frame = require("tagpose.localizer.frame")
local filter = require("tagpose.localizer.filter")
local results = require("tagpose.localizer.result")
local mapcheck = require("tagpose.localizer.mapcheck")
local bias = require("tagpose.localizer.bias")
local camera_mod = require("tagpose.core.camera")
local args = require("tagpose.core.args")

local sqrt, cos, sin, rad = math.sqrt, math.cos, math.sin, math.rad
local wrap = fit.wrap
local result, with_yaw = results.result, results.with_yaw

local M = {}


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

--- A new state.
-- @treturn table
function M.new_state()
  return {
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
end

local function copy_state(s)
  local c = {}
  for k, v in pairs(s) do c[k] = v end
  if s.filter then c.filter = s.filter:copy() end
  -- (the tag statistics are replaced, never changed in place, entry by entry; the bias sums
  -- are replaced whole)
  local st = {}
  for k, v in pairs(s.tag_stats) do st[k] = v end
  c.tag_stats = st
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
  -- (the frames' own noise through the filter's gains, and the mounts' and map's bias)
  local P, NS = f.Pw, f.n
  local cov = {}
  for i = 1, 36 do cov[i] = 0 end
  local function set(i, j, v) cov[(i - 1) * 6 + j], cov[(j - 1) * 6 + i] = v, v end
  -- (the heading's share of the mounts' errors is the filter's: each camera's heading error is
  -- a state of it)
  local b11, b12, b22 = bias.covariance(s.bias, self.ncameras, self.tags.ids)
  local h1, h2, h3 = f:heading_cov()
  set(1, 1, P[1] + b11); set(1, 2, P[2] + b12); set(2, 2, P[NS + 2] + b22)
  set(1, 6, h1); set(2, 6, h2); set(6, 6, h3 + o.gyro_sigma ^ 2)
  set(3, 3, o.floor_sigma ^ 2 + 1e-12)
  set(4, 4, o.tilt_sigma ^ 2 + 1e-12); set(5, 5, o.tilt_sigma ^ 2 + 1e-12)
  local res = result(t, name, with_yaw(r, yaw), { f.x + dx, f.y + dy, 0 }, cov, used, rejected)
  res.gyro_offset = f.c
  return res
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
    if o.map_check then mapcheck.add(self.checks, t, name, obs, sol.pose.r, sol.pose.t, sigma) end
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
    local W = sol.noise
    local Pw = { W[1], W[2], -W[6], W[7], W[8], -W[12], -W[31], -W[32], W[36] }
    f = filter.new(sol.pose.t[1] - dx, sol.pose.t[2] - dy, g - yaw, P, self.ncameras,
      o.mount_angle_sigma, Pw)
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
    local W = sol.noise
    local Rw = { W[1], W[2], W[6], W[7], W[8], W[12], W[31], W[32], W[36] + o.gyro_sigma ^ 2 }
    accepted = f:update(cam.index, sol.pose.t[1], sol.pose.t[2], fit.yaw(sol.pose.r), R, g, dx,
      dy, sol.kept >= 2, Rw)
    if accepted then
      -- the mounts' and the map's share of the estimate (a bias the filter cannot average
      -- away): the frames' sensitivities to each error averaged as the frames weigh in the
      -- estimate (by their information, forgetting with `BIAS_MEMORY`), so that a bias the
      -- frames share stays whole and one that turns with the view averages out
      bias.update(s, self.ncameras, self.tags.ids, cam.index, sol.sens, 1 / (C[1] + C[8]),
        M.BIAS_MEMORY)
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
    mapcheck.add(self.checks, t, name, obs, with_yaw(sol.pose.r, yaw + f.beta[cam.index]),
      { f.x + ex, f.y + ey, 0 }, sigma)
  end
  local res = estimate(self, t, name, g, accepted and sol.pose.r or nil,
    accepted and sol.used or {}, rejected)
  res.accepted = accepted
  return res
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


M.copy_state, M.heading, M.observations, M.sigma_of, M.estimate, M.feed = copy_state, heading,
  observations, sigma_of, estimate, feed
M.run_odometry, M.run_gyro, M.run_frame = run_odometry, run_gyro, run_frame

return M
