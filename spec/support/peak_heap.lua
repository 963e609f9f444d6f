-- Run tagpose-replay in this process and print, on standard error, the largest live Lua heap
-- (KiB, collectgarbage("count") after a full collection) seen while it solved: sampled every
-- 64 rows solved, by wrapping tagpose.solve (a replay without --track) and tagpose.tracker's
-- update (with it), which works the same on every VM (a count hook does not run in LuaJIT's
-- compiled code). The live heap, not the heap: what the garbage adds between collections
-- depends on when the collector runs, and its largest sample grows with the samples taken.
--
--   lua spec/support/peak_heap.lua LOG.csv [replay options] >/dev/null
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local Tracker = require("tagpose.tracker").Tracker
local solve, update, calls, peak = tagpose.solve, Tracker.update, 0, 0
local function count(n)
  local before = calls
  calls = calls + n
  if math.floor(calls / 64) > math.floor(before / 64) then
    collectgarbage()
    collectgarbage()
    local kb = collectgarbage("count")
    if kb > peak then peak = kb end
  end
end
tagpose.solve = function(...)
  count(1)
  return solve(...)
end
Tracker.update = function(self, detections, time)
  count(#detections)
  return update(self, detections, time)
end
local status = require("tagpose.tools.replay").main(arg)
io.stderr:write(("peak heap %.0f KiB over %d solves\n"):format(peak, calls))
os.exit(status)
