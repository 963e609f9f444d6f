--- The localizer's inputs read and checked at its facade: the options over their defaults,
-- each camera's calibration and mount, the map, the feeds' times. Misuse raises `bad argument`
-- at the caller's line.
-- @module tagpose.localizer.options

local model = require("tagpose.rigid.model")
local rotation = require("tagpose.core.rotation")
local camera_mod = require("tagpose.core.camera")
local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")

local rad = math.rad
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
      -- ("apriltag" as every other entry point takes it; "detector" the localizer's first name)
      if v ~= "detector" and v ~= "apriltag" and v ~= "opencv" then
        args.raise(n, fname, "options.order: \"apriltag\" (or \"detector\") or \"opencv\""
          .. " expected, got " .. describe(v), level)
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

-- Feeds are checked at the facade.
local function check_time(t, n, fname)
  if not is_finite(t) then
    args.raise(n, fname, "time: finite number (s) expected, got " .. describe(t), 3)
  end
end


M.read_camera, M.read_options, M.read_map, M.check_time = read_camera, read_options, read_map,
  check_time

return M
