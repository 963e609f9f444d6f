-- A module is read whole: every source file under src/ stays under 450 lines (split one that
-- grows past it by what its parts do, as tracker/associate.lua was split from tracker/init.lua).
local lfs = require("lfs")

local LIMIT = 450

local function lua_files(dir, out)
  for name in lfs.dir(dir) do
    local path = dir .. "/" .. name
    if name ~= "." and name ~= ".." then
      if lfs.attributes(path, "mode") == "directory" then
        lua_files(path, out)
      elseif name:match("%.lua$") then
        out[#out + 1] = path
      end
    end
  end
  return out
end

describe("the sources", function()
  it("are each under " .. LIMIT .. " lines", function()
    local files = lua_files("src", {})
    table.sort(files)
    assert.is_true(#files > 0)
    for _, path in ipairs(files) do
      local n = 0
      for _ in io.lines(path) do n = n + 1 end
      assert(n < LIMIT, path .. " has " .. n .. " lines")
    end
  end)
end)
