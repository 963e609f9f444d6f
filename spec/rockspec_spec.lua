-- The rockspecs' module maps are kept in step with src/.
local lfs = require("lfs")

local compat = require("tagpose.compat")

local function load_rockspec(path)
  local env = {}
  local f = assert(io.open(path, "r"))
  local chunk = assert(compat.load_text(f:read("*a"), "=" .. path, env))
  f:close()
  chunk()
  return env
end

local function source_modules(dir, prefix, out)
  for name in lfs.dir(dir) do
    local path = dir .. "/" .. name
    if name ~= "." and name ~= ".." then
      if lfs.attributes(path, "mode") == "directory" then
        source_modules(path, prefix .. name .. ".", out)
      elseif name:match("%.lua$") then
        local module = prefix .. name:gsub("%.lua$", "")
        out[(module:gsub("%.init$", ""))] = path:gsub("^%./", "")
      end
    end
  end
  return out
end

describe("rockspec", function()
  local rockspecs = {}
  for name in lfs.dir("rockspec") do
    if name:match("%.rockspec$") then rockspecs[#rockspecs + 1] = "rockspec/" .. name end
  end

  it("exists for scm", function()
    assert.is_truthy(io.open("rockspec/tagpose-scm-1.rockspec"))
  end)

  for _, path in ipairs(rockspecs) do
    it(path .. " lists exactly the modules in src/", function()
      local spec = load_rockspec(path)
      assert.equal("3.0", spec.rockspec_format)
      assert.equal("builtin", spec.build.type)
      assert.same({ "lua >= 5.1" }, spec.dependencies)
      assert.same(source_modules("src", "", {}), spec.build.modules)
    end)
  end
end)
