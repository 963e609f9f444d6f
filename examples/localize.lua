-- A robot's loop with tagpose.localizer: where the robot is on the 2024 FRC field, from two
-- cameras, wheel odometry and a gyro whose offset nobody reset.
--
--   lua5.4 examples/localize.lua [DIR] [SECONDS]
--
-- DIR is a drive log (default bench/dev/drive_hard: an odometry never reset, a gyro 30° off,
-- mounts 1 cm / 0.5° off their published values, a tag 10 cm from its place on the map,
-- phantom detections, pushes the wheels did not register). The loop feeds each sensor's
-- samples as the robot would get them, in time order, and prints the estimate once a second,
-- then where the map seems wrong.
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local luadata = require("tagpose.formats.luadata")

local dir = arg[1] or "bench/dev/drive_hard"
local seconds = tonumber(arg[2] or "20")

-- the cameras (calibration and mount: camera -> robot) and the field map
local f = assert(io.open(dir .. "/cameras.lua"))
local cameras = assert(luadata.decode(f:read("*a"), "cameras.lua"))
f:close()
local field = assert(tagpose.layout.read(dir .. "/map.json", { size = cameras.tag_size }))

local localizer = tagpose.localizer.new(field, cameras, { map_check = true })

-- The log's rows, as the robot's sensors would hand them out: {time, kind, ...}.
local function numbers(line)
  local out = {}
  for v in line:gmatch("[^,]+") do out[#out + 1] = tonumber(v) or v end
  return out
end
local events = {}
local function read(name, kind)
  local first = true
  for line in io.lines(dir .. "/" .. name) do
    if not first then
      local r = numbers(line)
      if r[1] <= seconds then events[#events + 1] = { kind = kind, row = r, n = #events + 1 } end
    end
    first = false
  end
end
read("odometry.csv", 1)
read("gyro.csv", 2)
read("corners.csv", 3)
-- by time, then kind, then camera, then the order read: a sort with ties would be free to
-- split a camera's frame into pieces, or to order its tags differently from run to run
table.sort(events, function(a, b)
  if a.row[1] ~= b.row[1] then return a.row[1] < b.row[1] end
  if a.kind ~= b.kind then return a.kind < b.kind end
  if a.kind == 3 and a.row[2] ~= b.row[2] then return a.row[2] < b.row[2] end
  return a.n < b.n
end)

-- the robot's loop: each sample as it comes; a camera frame is its detections at one time
local next_print = 1
local i = 1
while i <= #events do
  local e = events[i]
  local t = e.row[1]
  if e.kind == 1 then
    localizer:odometry(t, e.row[2], e.row[3], e.row[4])
    i = i + 1
  elseif e.kind == 2 then
    localizer:gyro(t, e.row[2])
    i = i + 1
  else
    local camera, detections = e.row[2], {}
    while i <= #events and events[i].kind == 3 and events[i].row[1] == t
      and events[i].row[2] == camera do
      local r = events[i].row
      detections[#detections + 1] = { id = r[3], corners = { { r[4], r[5] }, { r[6], r[7] },
        { r[8], r[9] }, { r[10], r[11] } } }
      i = i + 1
    end
    local est = localizer:update(camera, detections, t)
    if est.position and t >= next_print then
      next_print = next_print + 1
      -- what WPILib's addVisionMeasurement takes: the pose, its time and sigma of x, y, yaw
      print(("t %5.2f s  x %6.3f m  y %6.3f m  yaw %7.2f deg  sigma %.3f %.3f m %.2f deg"
        .. "  tags {%s}%s"):format(t, est.position.x, est.position.y, math.deg(est.yaw),
        est.sigma.x, est.sigma.y, math.deg(est.sigma.yaw), table.concat(est.tags, " "),
        #est.rejected > 0 and ("  rejected: " .. est.rejected[1].id .. " ("
          .. est.rejected[1].why .. ")") or ""))
    end
  end
end
print(("gyro offset learnt: %.2f deg"):format(math.deg(localizer:pose(seconds).gyro_offset)))
print("where the map seems wrong (seen - published, field frame):")
for k, c in ipairs(localizer:map_check()) do
  if k > 3 then break end
  print(("  tag %2d: %6.3f %6.3f %6.3f m  (%.3f m, %d frames)"):format(c.id, c.dx, c.dy, c.dz,
    c.distance, c.frames))
end
