-- The README's install and check say what they need: the Lua headers it names are those of the
-- Lua its luarocks commands pick (it paired `--lua-version 5.4` with liblua5.3-dev), and it says
-- that ./test.sh installs Debian packages (apt-get, sudo) and takes minutes.
local run = require("support.run")
local docs = require("support.docs")

describe("README.md", function()
  local text = run.read("README.md")

  it("names the headers of the Lua its luarocks commands pick", function()
    local install = docs.section(text, "## Install")
    local picked = {}
    for v in install:gmatch("luarocks %-%-lua%-version (%d%.%d)") do picked[v] = true end
    assert.is_truthy(next(picked), "no luarocks --lua-version in the install section")
    for v in pairs(picked) do
      assert.is_truthy(install:find("liblua" .. v .. "-dev", 1, true),
        "--lua-version " .. v .. " without liblua" .. v .. "-dev:\n" .. install)
    end
    -- the headers ./test.sh installs for its own luarocks --lua-version 5.4 are the same
    assert.is_truthy(run.read("test.sh"):find("liblua5.4-dev", 1, true))
  end)

  it("says that ./test.sh installs packages and takes minutes", function()
    local check = docs.section(text, "`./test.sh` installs")
    assert.is_truthy(check:find("apt-get", 1, true), check)
    assert.is_truthy(check:find("sudo", 1, true), check)
    assert.is_truthy(check:find("%d+ minutes"), check)
  end)
end)
