-- Lua VM instructions a row, by function: what PUC Lua's time follows more closely than
-- machine instructions do (each instruction is a dispatch, an indirect jump the processor
-- predicts poorly once other code has run between two solves). The first N rows of a data set
-- run once to warm up, then once more counted by a debug hook called at every instruction;
-- prints the total a row and the 25 functions that run the most (TOP in the environment:
-- more). The count is exact and the same on every run and machine (on LuaJIT it counts the
-- interpreter's instructions only, not compiled code: use PUC Lua).
--
--   lua5.4 bench/vm_instructions.lua plain|read|tracker [DATASET_DIR] [N]
--
-- plain: `tagpose.solve` alone; read: its `confidence` and `covariance` read; tracker: every
-- row fed to one tracker, one detection a frame (a sequences set: frame = sequence * 1000 + k,
-- the tag's id the sequence, k/30 s its time). DATASET_DIR defaults to bench/dev/sequences, N
-- to 300. Run from the repository root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")

local mode, dir, n = arg[1], arg[2] or "bench/dev/sequences", tonumber(arg[3] or 300)
if (mode ~= "plain" and mode ~= "read" and mode ~= "tracker") or not n then
  io.stderr:write("usage: lua5.4 bench/vm_instructions.lua plain|read|tracker [DATASET_DIR] [N]\n")
  os.exit(2)
end
local camera, info = assert(log.read_camera(dir .. "/camera.lua"))
local rows = assert(log.read_corners(dir .. "/corners.csv"))
n = math.min(n, #rows)
local size = info.tag_size
local tr = tagpose.tracker.new(camera, size)
local frame = { { id = 0, corners = nil } }

local function run(pass)
  for i = 1, n do
    local corners = rows[i].corners
    if mode == "tracker" then
      frame[1].id, frame[1].corners = math.floor(rows[i].frame / 1000), corners
      -- (the second pass later than the first: the same tracks go on)
      tr:update(frame, (rows[i].frame % 1000) / 30 + pass * 100)
    elseif mode == "read" then
      local p = tagpose.solve(corners, camera, size)
      if p then
        local _, _ = p.confidence, p.covariance[1][1]
      end
    else
      tagpose.solve(corners, camera, size)
    end
  end
end

local counts, getinfo = {}, debug.getinfo
local function hook()
  local i = getinfo(2, "Sn")
  local k = i.short_src:match("[^/]*/[^/]*$") .. ":" .. (i.name or "?") .. ":" .. i.linedefined
  counts[k] = (counts[k] or 0) + 1
end
run(1)
debug.sethook(hook, "", 1)
run(2)
debug.sethook()
local list, total = {}, 0
for k, v in pairs(counts) do
  list[#list + 1] = { k, v }
  total = total + v
end
table.sort(list, function(a, b) return a[2] > b[2] or (a[2] == b[2] and a[1] < b[1]) end)
print(("%s, %d rows of %s: %.1f VM instructions a row"):format(mode, n, dir, total / n))
local top = tonumber(os.getenv("TOP") or 25) -- (TOP=80 lua5.4 bench/vm_instructions.lua ...)
for i = 1, math.min(top, #list) do print(("%8.1f %s"):format(list[i][2] / n, list[i][1])) end
