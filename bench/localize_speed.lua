-- The localizer's cost per camera frame on a drive log, the files read beforehand: every
-- odometry, gyro and camera event fed in time order, as a robot's loop feeds them.
--
--   lua5.4 bench/localize_speed.lua bench/dev/drive_hard [--single] [--rounds 3]
--
-- Prints the best of the rounds: microseconds per camera frame (the odometry and gyro samples
-- between frames included) and per event, and the frames per second that makes.
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local luadata = require("tagpose.formats.luadata")
local csv = require("tagpose.tools.csv")

local dir = arg[1] or "bench/dev/drive_hard"
local single, rounds = false, 3
for i = 2, #arg do
  if arg[i] == "--single" then single = true end
  if arg[i] == "--rounds" then rounds = tonumber(arg[i + 1]) end
end

local function rows(path)
  local r = assert(csv.reader(path, nil, 4096, 64))
  local out = {}
  while true do
    local f = r:read()
    if not f then break end
    out[#out + 1] = f
  end
  r:close()
  return out
end

local f = assert(io.open(dir .. "/cameras.lua"))
local cameras = assert(luadata.decode(f:read("*a"), "cameras.lua"))
f:close()
local map = assert(tagpose.layout.read(dir .. "/map.json", { size = cameras.tag_size }))
local events = {}
if not single then
  for _, r in ipairs(rows(dir .. "/odometry.csv")) do
    events[#events + 1] = { t = tonumber(r[1]), k = 1, tonumber(r[2]), tonumber(r[3]),
      tonumber(r[4]) }
  end
end
for _, r in ipairs(rows(dir .. "/gyro.csv")) do
  events[#events + 1] = { t = tonumber(r[1]), k = 2, tonumber(r[2]) }
end
local frames, last = 0, nil
for _, r in ipairs(rows(dir .. "/corners.csv")) do
  local t = tonumber(r[1])
  if not (last and last.t == t and last.camera == r[2]) then
    last = { t = t, k = 3, camera = r[2], detections = {} }
    events[#events + 1] = last
    frames = frames + 1
  end
  local c = {}
  for k = 0, 3 do c[k + 1] = { tonumber(r[4 + 2 * k]), tonumber(r[5 + 2 * k]) } end
  last.detections[#last.detections + 1] = { id = tonumber(r[3]), corners = c }
end
table.sort(events, function(a, b)
  if a.t ~= b.t then return a.t < b.t end
  return a.k < b.k
end)

local best = math.huge
for _ = 1, rounds do
  local loc = tagpose.localizer.new(map, cameras, { mode = single and "single" or "fused" })
  collectgarbage()
  local start = os.clock()
  for _, e in ipairs(events) do
    if e.k == 1 then
      loc:odometry(e.t, e[1], e[2], e[3])
    elseif e.k == 2 then
      loc:gyro(e.t, e[1])
    else
      loc:update(e.camera, e.detections, e.t)
    end
  end
  local s = os.clock() - start
  if s < best then best = s end
end
local version = rawget(_G, "jit") and require("jit").version or _VERSION
print(("%s, %s: %d camera frames, %d events in %.3f s (best of %d): %.0f us a frame, "
  .. "%.1f us an event, %.0f frames/s"):format(version, single and "single" or "fused", frames,
  #events, best, rounds, 1e6 * best / frames, 1e6 * best / #events, frames / best))
