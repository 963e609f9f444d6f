-- The rockspecs' module maps are kept in step with src/: the library rock carries every module
-- but the tools, the tools rock carries src/tagpose/tools/ and the commands (bin/).
local lfs = require("lfs")

local compat = require("tagpose.core.compat")

local function load_rockspec(path)
  local env = {}
  local f = assert(io.open(path, "r"))
  local chunk = assert(compat.load_text(f:read("*a"), "=" .. path, env))
  f:close()
  chunk()
  return env
end

-- module name -> path of every .lua file under dir, split by whether it is a tool
local function source_modules(dir, prefix, library, tools)
  for name in lfs.dir(dir) do
    local path = dir .. "/" .. name
    if name ~= "." and name ~= ".." then
      if lfs.attributes(path, "mode") == "directory" then
        source_modules(path, prefix .. name .. ".", library, tools)
      elseif name:match("%.lua$") then
        local module = (prefix .. name:gsub("%.lua$", "")):gsub("%.init$", "")
        local into = module:match("^tagpose%.tools%.") and tools or library
        into[module] = path:gsub("^%./", "")
      end
    end
  end
end

local library, tools = {}, {}
source_modules("src", "", library, tools)

-- every command in bin/, installed under its own name
local commands = {}
for name in lfs.dir("bin") do
  if name ~= "." and name ~= ".." then commands[name] = "bin/" .. name end
end

describe("rockspec", function()
  for name in lfs.dir("rockspec") do
    local path = "rockspec/" .. name
    -- a release's rockspec describes its tag's tree, not this one: only the scm rockspecs
    -- follow src/
    local scm = name:match("%-scm%-%d+%.rockspec$")
    if name:match("^tagpose%-tools%-.*%.rockspec$") and scm then
      it(path .. " lists exactly the tools and installs the commands of bin/", function()
        local spec = load_rockspec(path)
        assert.equal("3.0", spec.rockspec_format)
        assert.equal("tagpose-tools", spec.package)
        assert.same({ "lua >= 5.1", "tagpose == scm" }, spec.dependencies)
        assert.same(tools, spec.build.modules)
        assert.same(commands, spec.build.install.bin)
      end)
    elseif name:match("%.rockspec$") and scm then
      it(path .. " lists exactly the library's modules, no tools", function()
        local spec = load_rockspec(path)
        assert.equal("3.0", spec.rockspec_format)
        assert.equal("tagpose", spec.package)
        assert.equal("builtin", spec.build.type)
        assert.same({ "lua >= 5.1" }, spec.dependencies)
        assert.same(library, spec.build.modules)
      end)
    end
  end

  for name in lfs.dir("rockspec") do
    local version = name:match("^tagpose%-[%a%-]*(%d+%.%d+%.%d+)%-%d+%.rockspec$")
    if version then
      it("rockspec/" .. name .. " builds the tag v" .. version .. " of the same package", function()
        local spec = load_rockspec("rockspec/" .. name)
        assert.equal("3.0", spec.rockspec_format)
        assert.equal(name:match("^(tagpose[%a%-]-)%-%d"), spec.package)
        assert.equal("v" .. version, spec.source.tag)
        assert.equal("builtin", spec.build.type)
      end)
    end
  end

  -- The tools are tested with the library of the same commit only, so a release of the tools
  -- depends on exactly the same version of the library. The releases up to 0.3.0 are as they
  -- were published (0.2.0: any tagpose; 0.3.0: >= 0.3.0, < 0.4): a published rockspec is not
  -- edited.
  local PINNED_SINCE = { 0, 4, 0 }
  local function pinned_from(v)
    for i = 1, 3 do
      if v[i] ~= PINNED_SINCE[i] then return v[i] > PINNED_SINCE[i] end
    end
    return true
  end
  for name in lfs.dir("rockspec") do
    local version = name:match("^tagpose%-tools%-(%d+%.%d+%.%d+)%-%d+%.rockspec$")
    local v = {}
    for n in (version or ""):gmatch("%d+") do v[#v + 1] = tonumber(n) end
    if version and pinned_from(v) then
      it("rockspec/" .. name .. " depends on tagpose == " .. version .. " exactly", function()
        local spec = load_rockspec("rockspec/" .. name)
        assert.same({ "lua >= 5.1", "tagpose == " .. version }, spec.dependencies)
      end)
    end
  end

  it("exists for scm, for the library and the tools", function()
    assert.is_truthy(io.open("rockspec/tagpose-scm-1.rockspec"))
    assert.is_truthy(io.open("rockspec/tagpose-tools-scm-1.rockspec"))
  end)
end)
