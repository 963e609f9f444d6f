-- A module is read whole: every source file under src/ stays under 450 lines (split one that
-- grows past it by what its parts do, as tracker/associate.lua was split from tracker/init.lua).
local run = require("support.run")

local LIMIT = 450


describe("the sources", function()
  it("are each under " .. LIMIT .. " lines", function()
    local files = run.files("src", "%.lua$")
    table.sort(files)
    assert.is_true(#files > 0)
    for _, path in ipairs(files) do
      local n = 0
      for _ in io.lines(path) do n = n + 1 end
      assert(n < LIMIT, path .. " has " .. n .. " lines")
    end
  end)
end)
