-- The cost of two readers on inputs that used to take them quadratic time: tagpose-replay's
-- --compare on frames of many detections of one tag id (every solved row against every
-- compared row of its id), and the OpenCV XML reader on one long line (the next line end, and
-- the next `&`, looked for from every value).
--
--   lua5.4 bench/tool_costs.lua compare [ROWS [FRAMES]]   (default 1000 rows a frame, 5 frames)
--   lua5.4 bench/tool_costs.lua xml [KB]                  (default a 960 KB line)
--
-- `compare`: ROWS solved rows of tag 0 a frame on a grid 6 cm apart, 2 m away, matched with a
-- pose log of the same rows 1 mm off in another order (the matching tagpose-replay --compare
-- does, read from the log as it reads it); prints the CPU seconds and checks that every row is
-- matched with the one it was made from. `xml`: an OpenCV FileStorage XML whose distortion
-- coefficients are one line of digits (then of `<_>` items) followed by a word, which the
-- reader refuses naming the line; prints the CPU seconds. Both run in this process
-- (os.clock); for counts that do not depend on the machine's load, run them under valgrind
-- --tool=callgrind.
--
-- The whole command, for comparison (its log made by bench/make_long_log.lua):
--
--   lua5.4 bench/make_long_log.lua /tmp/same 5000 1000 --same-id
--   lua5.4 bin/tagpose-replay /tmp/same/corners.csv --out /tmp/same/poses.csv
--   /usr/bin/time -v lua5.4 bin/tagpose-replay /tmp/same/corners.csv --compare /tmp/same/poses.csv
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local compare = require("tagpose.tools.replay.compare")
local calibration = require("tagpose.formats.calibration")

local sqrt, cos, sin, floor = math.sqrt, math.cos, math.sin, math.floor

local mode = arg[1]

-- Park-Miller: the same numbers on every VM
local seed = 26
local function rand(n)
  seed = (16807 * seed) % 2147483647
  return n and seed % n or seed / 2147483647
end

if mode == "compare" then
  local rows, frames = tonumber(arg[2] or 1000), tonumber(arg[3] or 5)
  local path = os.tmpname()
  local f = assert(io.open(path, "w"))
  f:write("frame,tag,x,y,z,qw,qx,qy,qz\n")
  local solved, orders = {}, {}
  for frame = 0, frames - 1 do
    local list, order = {}, {}
    for k = 1, rows do
      local c, r = (k - 1) % 40, floor((k - 1) / 40)
      local a = 0.3 * (rand() - 0.5)
      list[k] = { tag = 0, slot = k, pose = {
        position = { x = 0.06 * (c - 19.5), y = 0.06 * (r - 12), z = 2 + 0.01 * frame },
        quaternion = { w = cos(a / 2), x = 0, y = sin(a / 2), z = 0 } } }
      order[k] = k
    end
    for k = rows, 2, -1 do
      local j = 1 + rand(k)
      order[k], order[j] = order[j], order[k]
    end
    for line = 1, rows do
      local p, q = list[order[line]].pose.position, list[order[line]].pose.quaternion
      local u, v = rand() - 0.5, rand() - 0.5
      local w = sqrt(u * u + v * v)
      f:write(("%d,0,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n"):format(frame,
        p.x + 1e-3 * u / w, p.y + 1e-3 * v / w, p.z, q.w, q.x, q.y, q.z))
    end
    solved[frame], orders[frame] = list, order
  end
  f:close()
  local t = os.clock()
  local c = assert(compare.open(path))
  local wrong = 0
  for frame = 0, frames - 1 do
    c:match(frame, solved[frame])
    for line, e in ipairs(c:take(frame)) do
      if e.partner ~= solved[frame][orders[frame][line]] then wrong = wrong + 1 end
    end
  end
  c:finish()
  local seconds = os.clock() - t
  os.remove(path)
  print(("compare: %d frames of %d rows of one id: %.3f s CPU (%.1f ms a frame), %d rows"
    .. " matched, %d with the wrong row"):format(frames, rows, seconds, 1000 * seconds / frames,
    c.matched, wrong))
elseif mode == "xml" then
  local kb = tonumber(arg[2] or 960)
  -- the line: digits separated by spaces (one text), or each digit an item `<_>N</_>`
  for _, items_line in ipairs({ false, true }) do
    local items, bytes = {}, 0
    while bytes < kb * 1000 do
      local v = tostring(#items % 10)
      items[#items + 1] = items_line and "<_>" .. v .. "</_>" or v
      bytes = bytes + #items[#items] + 1
    end
    local text = table.concat({
      '<?xml version="1.0"?>',
      "<opencv_storage>",
      '<camera_matrix type_id="opencv-matrix"><rows>3</rows><cols>3</cols><dt>d</dt>',
      "<data>600 0 320 0 600 240 0 0 1</data></camera_matrix>",
      '<distortion_coefficients type_id="opencv-matrix"><rows>1</rows><cols>5</cols>'
        .. "<dt>d</dt>",
      "<data>" .. table.concat(items, " ") .. (items_line and "<_>oops</_>" or " oops")
        .. "</data></distortion_coefficients>",
      "</opencv_storage>",
    }, "\n")
    local t = os.clock()
    local camera, err = calibration.decode(text, "long.xml")
    local seconds = os.clock() - t
    assert(camera == nil and err:find("long.xml:6:", 1, true), err)
    print(("xml: one line of %d KB (%d %s): %.3f s CPU, refused on its line (%s)"):format(
      floor(bytes / 1000), #items, items_line and "items <_>N</_>" or "digits", seconds,
      err:sub(1, 60)))
  end
else
  io.stderr:write("usage: lua bench/tool_costs.lua compare [ROWS [FRAMES]] | xml [KB]\n")
  os.exit(2)
end
