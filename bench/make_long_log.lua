-- A long corner log for measuring tagpose-replay's memory and time: TAGS tags (ids 0..TAGS-1,
-- or all id 0 with --same-id) seen in every frame, drifting slowly in front of a 640x480
-- camera, corners with 0.3 px of deterministic noise, until ROWS rows are written.
--
--   lua5.4 bench/make_long_log.lua DIR [ROWS [TAGS]] [--same-id]
--
-- writes DIR/corners.csv and DIR/camera.lua (DIR is made if it does not exist). Then, for
-- instance:
--
--   /usr/bin/time -v lua5.4 bin/tagpose-replay DIR/corners.csv --smooth --svg DIR/plot.svg
--
-- (peak memory: "Maximum resident set size").

local rows, tags, same = 200000, 10, false
local positional = {}
for _, a in ipairs(arg) do
  if a == "--same-id" then same = true else positional[#positional + 1] = a end
end
local dir = positional[1]
rows = tonumber(positional[2] or rows)
tags = tonumber(positional[3] or tags)
if not dir or not rows or not tags then
  io.stderr:write("usage: lua bench/make_long_log.lua DIR [ROWS [TAGS]] [--same-id]\n")
  os.exit(2)
end

local sin, cos, sqrt, log, pi = math.sin, math.cos, math.sqrt, math.log, math.pi
local fx, fy, cx, cy, size = 600, 600, 319.5, 239.5, 0.05

-- the folder, made as `mkdir -p` makes it (the name quoted for the shell)
local quoted = "'" .. dir:gsub("'", "'\\''") .. "'"
local made = os.execute("mkdir -p " .. quoted)
if made ~= true and made ~= 0 then
  io.stderr:write("make_long_log: cannot make the folder " .. dir .. "\n")
  os.exit(1)
end

local f = assert(io.open(dir .. "/camera.lua", "w"))
f:write(("return { fx = %g, fy = %g, cx = %g, cy = %g, width = 640, height = 480,"
  .. " tag_size = %g }\n"):format(fx, fy, cx, cy, size))
f:close()

-- Park-Miller, normal deviates by Box-Muller: the same log on every VM
local seed = 4242
local function uniform()
  seed = (16807 * seed) % 2147483647
  return seed / 2147483647
end
local function normal()
  return sqrt(-2 * log(uniform())) * cos(2 * pi * uniform())
end

local out = assert(io.open(dir .. "/corners.csv", "w"))
out:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
local h = size / 2
local corners = { { -h, h }, { h, h }, { h, -h }, { -h, -h } }
local written, frame = 0, 0
local buffer = {}
while written < rows do
  for k = 0, tags - 1 do
    if written >= rows then break end
    -- tag k on a grid, swaying; a turn about the vertical axis
    local x = -0.25 + 0.5 * ((k % 5) + 0.5) / 5 + 0.02 * sin(frame / 97 + k)
    local y = -0.12 + 0.24 * (math.floor(k / 5) % 2 + 0.5) / 2 + 0.01 * cos(frame / 83 + k)
    local z = 0.8 + 0.2 * sin(frame / 211 + 0.3 * k)
    local a = 0.6 * sin(frame / 151 + k)
    local ca, sa = cos(a), sin(a)
    local parts = { frame, same and 0 or k }
    for i = 1, 4 do
      local X, Y = corners[i][1], corners[i][2]
      -- R = Ry(a): (X ca, Y, -X sa)
      local px, py, pz = X * ca + x, Y + y, -X * sa + z
      parts[#parts + 1] = ("%.4f"):format(fx * px / pz + cx + 0.3 * normal())
      parts[#parts + 1] = ("%.4f"):format(fy * py / pz + cy + 0.3 * normal())
    end
    buffer[#buffer + 1] = table.concat(parts, ",")
    written = written + 1
    if #buffer >= 1000 then
      out:write(table.concat(buffer, "\n"), "\n")
      buffer = {}
    end
  end
  frame = frame + 1
end
if #buffer > 0 then out:write(table.concat(buffer, "\n"), "\n") end
out:close()
print(("wrote %s/corners.csv (%d rows, %d frames) and %s/camera.lua"):format(dir, written, frame,
  dir))
