-- The LDoc reference has no broken link: bench/check_links.lua finds a link to a missing page or
-- anchor (checked here on a small hand-made reference), and the reference config.ld builds has
-- none (the topics' GitHub links, `tracking.md#replaying-a-log` and `../src/tagpose/init.lua`,
-- rewritten by config.ld's postprocess_html). The build runs once, with the #docs specs.
local run = require("support.run")

package.path = "./bench/?.lua;" .. package.path
local check_links = require("check_links")

local function write(path, text)
  local f = assert(io.open(path, "w"))
  f:write(text)
  f:close()
end

describe("bench/check_links.lua", function()
  local dir
  before_each(function()
    dir = run.tmpdir("topics")
    os.execute("mkdir -p " .. run.quote(dir .. "/modules"))
    write(dir .. "/index.html", '<a href="topics/a.md.html">a</a> <a href="https://x.org/y">x</a>'
      .. ' <a href="mailto:a@b.c">m</a>')
    write(dir .. "/topics/a.md.html", '<a name="the-tracker"></a><h2>The tracker</h2>'
      .. '<a href="b.md.html#speed">b</a> <a href="#the-tracker">here</a>'
      .. ' <a href="../modules/m.html">m</a> <a href="../index.html">home</a>')
    write(dir .. "/topics/b.md.html", '<h2 id="speed">Speed</h2><a href="a.md.html#">a</a>')
    write(dir .. "/modules/m.html", '<a href="../topics/a.md.html#the-tracker">a</a>')
  end)
  after_each(function()
    os.execute("rm -rf " .. run.quote(dir))
  end)

  it("passes links to pages and anchors that exist, and leaves outside addresses", function()
    local broken, checked = check_links.check(dir)
    assert.are.same({}, broken)
    assert.equal(7, checked)
  end)

  it("names a link to a missing page and one to a missing anchor", function()
    write(dir .. "/topics/c.md.html", '<a href="tracking.md#replaying-a-log">t</a>'
      .. ' <a href="a.md.html#replaying-a-log">a</a> <a href="#nowhere">n</a>')
    local broken = check_links.check(dir)
    assert.are.same({
      "topics/c.md.html: #nowhere (no anchor #nowhere)",
      "topics/c.md.html: a.md.html#replaying-a-log (no anchor #replaying-a-log)",
      "topics/c.md.html: tracking.md#replaying-a-log (no file topics/tracking.md)",
    }, broken)
    local out, status = run.run(run.quote(run.lua()) .. " bench/check_links.lua "
      .. run.quote(dir) .. " 2>&1")
    assert.equal(1, status, out)
    assert.is_truthy(out:find("3 broken links of 10 checked", 1, true), out)
  end)
end)

describe("#docs the LDoc reference", function()
  it("has no broken link", function()
    if select(2, run.run("command -v ldoc >/dev/null 2>&1")) ~= 0 then
      return pending("ldoc is not installed")
    end
    local dir = run.tmpdir()
    local log, status = run.run("ldoc -d " .. run.quote(dir) .. " . 2>&1")
    assert.equal(0, status, log)
    local broken, checked = check_links.check(dir)
    os.execute("rm -rf " .. run.quote(dir))
    assert.are.same({}, broken)
    assert.is_true(checked > 1000, "links checked: " .. checked)
  end)
end)
