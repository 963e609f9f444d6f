-- Frames of many tags, arranged as adversarially as a detector could: hundreds of tags piled at
-- one place (random poses around one image point), one tag copied hundreds of times (with
-- corner noise), and hundreds of small tags spread over the image. Times tagpose.block.solve
-- on each (CPU seconds, median of a few runs), for the VM it runs on.
--
--   lua5.4 bench/many_tags.lua [N ...]        (default 100 250 500 detections)
--
-- Every frame must give a valid answer (each detection in one block or skipped with a reason);
-- the time is a reported figure, not a test.
package.path = "./src/?.lua;./src/?/init.lua;./spec/?.lua;" .. package.path
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local crowds = require("support.crowds")

local cam = crowds.CAMERA
local sizes = {}
for i = 1, #arg do sizes[i] = tonumber(arg[i]) end
if #sizes == 0 then sizes = { 100, 250, 500 } end

local frame = crowds.frame

print(("%s: CPU seconds per frame of tagpose.block.solve (median of 3)"):format(_VERSION
  .. (rawget(_G, "jit") and " (LuaJIT)" or "")))
for _, kind in ipairs({ "pile", "copies", "spread" }) do
  for _, n in ipairs(sizes) do
    local dets = frame(geometry.rng(7), kind, n)
    local times, blocks = {}, nil
    for k = 1, 3 do
      local t0 = os.clock()
      blocks = assert(tagpose.block.solve(dets, cam, 0.024, 0.055))
      times[k] = os.clock() - t0
    end
    table.sort(times)
    local used = #blocks.skipped
    for _, b in ipairs(blocks) do used = used + #b.tags end
    assert(used == n, "every detection in one block or skipped")
    print(("%-7s %4d detections: %.3f s  (%d blocks, %d skipped)"):format(kind, n, times[2],
      #blocks, #blocks.skipped))
  end
end
