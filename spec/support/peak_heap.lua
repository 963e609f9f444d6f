-- Run tagpose-replay in this process and print, on standard error, the largest Lua heap
-- (KiB, collectgarbage("count")) seen while it solved: sampled every 64 solves, by wrapping
-- tagpose.solve, which works the same on every VM (a count hook does not run in LuaJIT's
-- compiled code).
--
--   lua spec/support/peak_heap.lua LOG.csv [replay options] >/dev/null
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local solve, calls, peak = tagpose.solve, 0, 0
tagpose.solve = function(...)
  calls = calls + 1
  if calls % 64 == 0 then
    local kb = collectgarbage("count")
    if kb > peak then peak = kb end
  end
  return solve(...)
end
local status = require("tagpose.tools.replay").main(arg)
io.stderr:write(("peak heap %.0f KiB over %d solves\n"):format(peak, calls))
os.exit(status)
