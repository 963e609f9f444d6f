-- A pose writer whose target fails keeps memory bounded: the rows written after the failure
-- are dropped, not queued for a flush that never comes (a replay of a long log onto a full
-- disk used to hold every later line in memory), and close reports the failure.
local log = require("tagpose.tools.log")

-- a target whose every write fails, as a full disk's does
local function failing_target()
  local target = { writes = 0 }
  function target.write()
    target.writes = target.writes + 1
    return nil, "No space left on device"
  end
  return target
end

local POSE = { position = { x = 0.125, y = -0.25, z = 1.5 },
  quaternion = { w = 0.5, x = 0.5, y = -0.5, z = 0.5 }, error = 0.03125, iterations = 3 }

local function heap_kib()
  collectgarbage("collect")
  collectgarbage("collect")
  return collectgarbage("count")
end

describe("tagpose.tools.log", function()
  describe("pose_writer()", function()
    it("holds no more than a flush's worth of rows once its target has failed", function()
      local target = failing_target()
      local writer = assert(log.pose_writer(target))
      for frame = 1, 2000 do writer:write(frame, 7, POSE) end
      local before = heap_kib()
      for frame = 2001, 20000 do writer:write(frame, 7, POSE) end
      local growth = heap_kib() - before
      -- the 18000 lines queued (about 90 bytes each of heap) would be about 1600 KiB
      assert.is_true(growth < 512, ("the heap grew by %.0f KiB"):format(growth))
      assert.same({ nil, "log: No space left on device" }, { writer:close() })
      assert.equal(1, target.writes)
    end)
  end)
end)
