-- The bounds on work and memory the tools and the layout files keep, measured: replay's peak
-- memory over logs of many distinct tag ids, a corner log with one stray quote, a layout file
-- far too large to read, and the layout calibration of boards of many tags.
--
--   lua5.4 bench/bounds.lua ids DIR [ROWS [PER_FRAME]]  -- DIR/corners.csv: ROWS detections,
--       PER_FRAME a frame (default 100000, 10), every one a new tag id; DIR/camera.lua;
--       DIR/truth.csv (the poses drawn, for --compare)
--   lua5.4 bench/bounds.lua quote DIR [ROWS]   -- DIR/corners.csv of ROWS rows (default 48800)
--       with a stray quote in the middle; DIR/camera.lua
--   lua5.4 bench/bounds.lua layout FILE [MB]   -- a CSV layout of MB megabytes (default 60)
--   lua5.4 bench/bounds.lua board N [FRAMES]   -- calibrate an N x N board seen in FRAMES
--       frames (default 20) and print the time (os.clock) and, for the boards of
--       bench/reference (10, 14), the largest difference from the layout computed there
--   lua5.4 bench/bounds.lua all DIR            -- all of the above, with each command's peak
--       resident memory and time (GNU /usr/bin/time), as docs/replay.md and docs/layouts.md
--       report them
--
-- The generators are deterministic (Park-Miller): the same files on every Lua. The board is
-- spec/support/board.lua's (ground truth from geometry: 1 mm and 1 deg of glue per tag, a
-- camera 1280x960 at 0.3 + 0.07 N m, 0.2 px of corner noise, seed 7).

package.path = "./src/?.lua;./src/?/init.lua;./spec/?.lua;" .. package.path

local sin, cos, sqrt, log, pi = math.sin, math.cos, math.sqrt, math.log, math.pi

local USAGE = "usage: lua bench/bounds.lua ids DIR [ROWS [PER_FRAME]] | quote DIR [ROWS]"
  .. " | layout FILE [MB] | board N [FRAMES] | all DIR"

local fx, fy, cx, cy, size = 600, 600, 319.5, 239.5, 0.05

local function rng(seed)
  local s = seed
  local function uniform()
    s = (16807 * s) % 2147483647
    return s / 2147483647
  end
  return function() return sqrt(-2 * log(uniform())) * cos(2 * pi * uniform()) end
end

local function write_camera(dir)
  local f = assert(io.open(dir .. "/camera.lua", "w"))
  f:write(("return { fx = %g, fy = %g, cx = %g, cy = %g, width = 640, height = 480,"
    .. " tag_size = %g }\n"):format(fx, fy, cx, cy, size))
  f:close()
end

-- Detection k of a frame: the tag on a 5 x 2 grid, swaying, turned about the vertical axis;
-- its corners (with noise) and its pose (position, quaternion).
local function detection(frame, k, normal)
  local x = -0.25 + 0.5 * ((k % 5) + 0.5) / 5 + 0.02 * sin(frame / 97 + k)
  local y = -0.12 + 0.24 * (math.floor(k / 5) % 2 + 0.5) / 2 + 0.01 * cos(frame / 83 + k)
  local z = 0.8 + 0.2 * sin(frame / 211 + 0.3 * k)
  local a = 0.6 * sin(frame / 151 + k)
  local ca, sa, h = cos(a), sin(a), size / 2
  local parts = {}
  for _, c in ipairs({ { -h, h }, { h, h }, { h, -h }, { -h, -h } }) do
    local px, py, pz = c[1] * ca + x, c[2] + y, -c[1] * sa + z
    parts[#parts + 1] = ("%.4f"):format(fx * px / pz + cx + 0.3 * normal())
    parts[#parts + 1] = ("%.4f"):format(fy * py / pz + cy + 0.3 * normal())
  end
  -- R = Ry(a): q = (cos a/2, 0, sin a/2, 0)
  local pose = ("%.6f,%.6f,%.6f,%.9f,0,%.9f,0"):format(x, y, z, cos(a / 2), sin(a / 2))
  return table.concat(parts, ","), pose
end

local function make_ids(dir, rows, per_frame)
  write_camera(dir)
  local normal = rng(4242)
  local out = assert(io.open(dir .. "/corners.csv", "w"))
  local truth = assert(io.open(dir .. "/truth.csv", "w"))
  out:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
  truth:write("frame,tag,x,y,z,qw,qx,qy,qz\n")
  for i = 0, rows - 1 do
    local frame, k = math.floor(i / per_frame), i % per_frame
    local corners, pose = detection(frame, k, normal)
    -- every row a new id, spread over a wide range of ids
    local id = 1000003 * i % 9000000000000 + 7
    out:write(("%d,%.0f,%s\n"):format(frame, id, corners))
    truth:write(("%d,%.0f,%s\n"):format(frame, id, pose))
  end
  out:close()
  truth:close()
  print(("wrote %s/corners.csv and truth.csv (%d rows, %d distinct ids, %d a frame)"):format(dir,
    rows, rows, per_frame))
end

local function make_quote(dir, rows)
  write_camera(dir)
  local normal = rng(4243)
  local out = assert(io.open(dir .. "/corners.csv", "w"))
  out:write("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n")
  for i = 0, rows - 1 do
    local frame, k = math.floor(i / 10), i % 10
    local corners = detection(frame, k, normal)
    if i == math.floor(rows / 2) then corners = corners:gsub(",", ',"', 1) end
    out:write(("%d,%d,%s\n"):format(frame, k, corners))
  end
  out:close()
  print(("wrote %s/corners.csv (%d rows, one stray quote at line %d)"):format(dir, rows,
    math.floor(rows / 2) + 2))
end

local function make_layout(path, mb)
  local f = assert(io.open(path, "w"))
  f:write("id,size,x,y,z,qw,qx,qy,qz\n")
  local n, bytes = 0, 0
  local lines = {}
  while bytes < mb * 1e6 do
    local line = ("%d,0.03,%.17g,%.17g,0,1,0,0,0"):format(n, 0.04 * (n % 1000), 0.04 * n / 1000)
    lines[#lines + 1] = line
    bytes = bytes + #line + 1
    n = n + 1
    if #lines == 10000 then
      f:write(table.concat(lines, "\n"), "\n")
      lines = {}
    end
  end
  f:write(table.concat(lines, "\n"), "\n")
  f:close()
  print(("wrote %s (%d tags, %.1f MB)"):format(path, n, bytes / 1e6))
end

local function board(n, frames)
  local tagpose = require("tagpose")
  local geometry = require("support.geometry")
  local support = require("support.board")
  local r = geometry.rng(7)
  local nominal, truth = support.layouts(r, n, 0.03, 0.04, 1, 1, 0.2)
  local views = support.views(truth, r, frames, 0.3 + 0.07 * n, 0.2)
  local detections = 0
  for _, f in ipairs(views) do detections = detections + #f end
  local t0 = os.clock()
  local calibrated, report = tagpose.layout.calibrate(views, support.CAMERA, nominal)
  local t = os.clock() - t0
  if not calibrated then error(report) end
  local jit = rawget(_G, "jit")
  local line = ("board %dx%d over %d frames (%d detections): calibrated in %.2f s (%s), %d"
    .. " iterations, rms %.3f px"):format(n, n, #views, detections, t, _VERSION .. (jit and
    " " .. jit.version or ""), report.iterations, report.rms)
  local ref = io.open(("bench/reference/board%d_ff4aaa3.csv"):format(n))
  if ref and frames == 20 then
    ref:close()
    local old = assert(tagpose.layout.read(("bench/reference/board%d_ff4aaa3.csv"):format(n)))
    local dp, dq = 0, 0
    for id, e in pairs(old.tags) do
      local c = calibrated.tags[id]
      for _, k in ipairs({ "x", "y", "z" }) do
        dp = math.max(dp, math.abs(e.position[k] - c.position[k]))
      end
      for _, k in ipairs({ "w", "x", "y", "z" }) do
        dq = math.max(dq, math.abs(e.quaternion[k] - c.quaternion[k]))
      end
    end
    line = line .. ("; vs the result of commit ff4aaa3: positions within %.2g m, quaternions"
      .. " within %.2g"):format(dp, dq)
  end
  print(line)
end

local function sh(command)
  local p = assert(io.popen(command .. " 2>&1"))
  local text = p:read("*a")
  p:close()
  return text
end

-- run a command under GNU time: its peak resident set (MB), user time (s), exit status and
-- the last line it printed
local function measure(command)
  local record = os.tmpname()
  local text = sh("/usr/bin/time -o " .. record .. " -f 'TIME %M %U %x' " .. command)
  local f = assert(io.open(record))
  local kb, user, status = f:read("*a"):match("TIME (%d+) ([%d.]+) (%d+)")
  f:close()
  os.remove(record)
  return tonumber(kb) / 1024, tonumber(user), tonumber(status), text:match("([^\n]*)\n?$")
end

local function all(dir)
  local lua = arg[-1] or "lua5.4"
  local version = sh(lua .. " -v"):gsub("\n.*", "")
  local machine = sh("grep -m1 'model name' /proc/cpuinfo"):gsub(".*: ", ""):gsub("\n", "")
  print(("%s on %s (%s cores)"):format(version, machine, sh("nproc"):gsub("\n", "")))
  sh("mkdir -p " .. dir .. "/ids " .. dir .. "/quote")
  print((sh(lua .. " bench/bounds.lua ids " .. dir .. "/ids 100000 10"):gsub("\n$", "")))
  local corners = dir .. "/ids/corners.csv"
  for _, options in ipairs({ "", "--track", "--svg " .. dir .. "/ids/plot.svg",
    "--compare " .. dir .. "/ids/truth.csv",
    "--track --svg " .. dir .. "/ids/plot.svg --out " .. dir .. "/ids/poses.csv --compare "
      .. dir .. "/ids/truth.csv" }) do
    local mb, user, status = measure(lua .. " bin/tagpose-replay " .. corners .. " " .. options
      .. " >/dev/null")
    print(("replay, 100000 distinct ids %s: peak RSS %.1f MB, user %.1f s, status %d"):format(
      options == "" and "(no options)" or options:gsub(dir .. "/ids/", ""), mb, user, status))
  end
  sh("mkdir -p " .. dir .. "/frame")
  print((sh(lua .. " bench/bounds.lua ids " .. dir .. "/frame 100000 100000"):gsub("\n$", "")))
  local mb, user, status = measure(lua .. " bin/tagpose-replay " .. dir .. "/frame/corners.csv"
    .. " --track --svg " .. dir .. "/frame/plot.svg --out " .. dir .. "/frame/poses.csv"
    .. " >/dev/null")
  print(("replay, 100000 distinct ids in one frame --track --svg --out: peak RSS %.1f MB, user"
    .. " %.1f s, status %d"):format(mb, user, status))
  print((sh(lua .. " bench/bounds.lua quote " .. dir .. "/quote 48800"):gsub("\n$", "")))
  local text = sh(lua .. " bin/tagpose-replay " .. dir .. "/quote/corners.csv")
  print(("replay of the stray quote's log: %s; %s"):format(text:match("rows%s+(%d+)") .. " rows",
    text:match("malformed[^\n]*\n[^\n]*"):gsub("\n%s*", ": ")))
  print((sh(lua .. " bench/bounds.lua layout " .. dir .. "/big.csv 60"):gsub("\n$", "")))
  local last
  mb, user, status, last = measure(lua .. " -e 'package.path=\"./src/?.lua;"
    .. "./src/?/init.lua;\" .. package.path; local t = os.clock(); local _, e ="
    .. " require(\"tagpose\").layout.read(\"" .. dir .. "/big.csv\");"
    .. " print(e, (\"%.3f s\"):format(os.clock() - t))'")
  print(("layout.read of 60 MB: %s (peak RSS %.1f MB, user %.2f s, status %d)"):format(last, mb,
    user, status))
  for _, n in ipairs({ 10, 14 }) do
    print((sh(lua .. " bench/bounds.lua board " .. n):gsub("\n$", "")))
  end
end

local command = arg[1]
if command == "ids" and arg[2] then
  make_ids(arg[2], tonumber(arg[3] or 100000), tonumber(arg[4] or 10))
elseif command == "quote" and arg[2] then
  make_quote(arg[2], tonumber(arg[3] or 48800))
elseif command == "layout" and arg[2] then
  make_layout(arg[2], tonumber(arg[3] or 60))
elseif command == "board" and tonumber(arg[2]) then
  board(tonumber(arg[2]), tonumber(arg[3] or 20))
elseif command == "all" and arg[2] then
  all(arg[2])
else
  io.stderr:write(USAGE, "\n")
  os.exit(2)
end
