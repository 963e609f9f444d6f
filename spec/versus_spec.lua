-- bench/versus.sh names the releases without tags: the CHANGELOG's `bench/versus.sh v0.3.0`
-- runs in a clone that has no tag (the repository has none), a release being the commit that
-- added its rockspec. Needs the git history (pending in a copy without it).
local run = require("support.run")

local has_history = select(2, run.run("git rev-parse -q --verify 559a8b6^{commit} >/dev/null"))
  == 0

-- the _VERSION of src/tagpose/init.lua at a commit
local function version_at(commit)
  local text = run.run("git show " .. run.quote(commit .. ":src/tagpose/init.lua") .. " 2>&1")
  return text:match('_VERSION = "([^"]*)"')
end

describe("bench/versus.sh", function()
  for _, release in ipairs({ "0.2.0", "0.3.0" }) do
    it("resolves v" .. release .. " to the commit of the release", function()
      if not has_history then return pending("no git history") end
      local out, status = run.run("bench/versus.sh --resolve v" .. release .. " 2>/dev/null")
      assert.equal(0, status, out)
      local commit = out:match("^(%x+)\n$")
      assert.is_truthy(commit, out)
      assert.equal("tagpose " .. release, version_at(commit))
      local added = run.run("git log --diff-filter=A --format=%H -- rockspec/tagpose-" .. release
        .. "-1.rockspec | tail -n 1")
      assert.equal(added, out)
    end)
  end

  it("times a solve against v0.3.0, as the CHANGELOG's command does", function()
    if not has_history then return pending("no git history") end
    -- (on the first 500 rows of its data set, bench/dev/noise_0.5)
    local dir = run.tmpdir()
    run.write(dir .. "/camera.lua", run.read("bench/dev/noise_0.5/camera.lua"))
    local rows = {}
    for line in io.lines("bench/dev/noise_0.5/corners.csv") do
      rows[#rows + 1] = line
      if #rows > 500 then break end
    end
    run.write(dir .. "/corners.csv", table.concat(rows, "\n") .. "\n")
    local out, status = run.run("bench/versus.sh v0.3.0 plain lua5.4 1 " .. run.quote(dir)
      .. " 2>&1")
    run.run("rm -r " .. run.quote(dir))
    assert.equal(0, status, out)
    assert.is_truthy(out:find("this checkout / v0.3.0 = [%d.]+ %(median of 1 pairs"), out)
  end)

  it("refuses a revision that names nothing, with status 2", function()
    if not has_history then return pending("no git history") end
    local out, status = run.run("bench/versus.sh --resolve v9.9.9 2>&1")
    assert.equal(2, status, out)
    assert.is_truthy(out:find("v9.9.9 is neither a revision git names nor a release", 1, true),
      out)
  end)
end)
