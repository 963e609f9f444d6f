-- The commands docs/replay.md, docs/tracking.md (its replay) and docs/layouts.md show, run as
-- shown (with the Lua running the specs, the measurements' logs made smaller), their output
-- compared with the page's. (`bench/bounds.lua all` takes minutes, most of them calibrating
-- boards: its parts are the generators the memory and layout specs run.)
local run = require("support.run")

local function tmp(name)
  local base = os.tmpname() -- created: take its unique name only
  os.remove(base)
  return base .. "-" .. name
end

-- the `$ lua5.4 ...` lines of a page's code blocks, each with the line the page shows after it
local function shown(page)
  local text = run.read(page)
  local out = {}
  for block in text:gmatch("```\n(.-)```") do
    local command, output = block:match("^%s*%$ (lua5%.4 [^\n]+)\n%s*([^\n]*)")
    if command then out[#out + 1] = { command = command, output = output } end
  end
  return out
end

-- every command line of a page's code blocks (a line ending in \ joined with the next), in
-- order; each block's text after its command lines is `output`
local function commands(page)
  local out = {}
  for block in run.read(page):gmatch("```[a-z]*\n(.-)```") do
    block = block:gsub("\\\n%s*", "")
    for line in block:gmatch("[^\n]+") do
      local c = line:match("^(lua5%.4 .*)") or line:match("^(luajit .*)")
        or line:match("^(/usr/bin/time .*)")
      if c then out[#out + 1] = c end
    end
  end
  return out
end

-- the code block that follows the one holding `command`
local function output_after(page, command)
  local text = run.read(page):gsub("\\\n%s*", "")
  local at = assert(text:find(command, 1, true), command)
  local block = text:match("```\n(.-)```", text:find("```", at, true) + 3)
  return block
end

-- run a page's command with the spec's Lua, paths under /tmp moved to dir, and the
-- substitutions given (plain text); its output and status
local function execute(command, dir, subs)
  for from, to in pairs(subs or {}) do
    command = command:gsub(from:gsub("%p", "%%%0"), (to:gsub("%%", "%%%%")))
  end
  local words = {}
  for w in command:gmatch("%S+") do
    if w == "lua5.4" or w == "luajit" then w = run.lua() end
    words[#words + 1] = run.quote((w:gsub("^/tmp/", dir .. "/")))
  end
  if words[1] == "'/usr/bin/time'" then
    table.remove(words, 1)
    table.remove(words, 1) -- its -v
  end
  return run.run(table.concat(words, " ") .. " 2>&1")
end

describe("docs/replay.md", function()
  local PAGE = "docs/replay.md"
  local APPROACH = "lua5.4 bin/tagpose-replay examples/data/approach.csv --track --out "
    .. "poses.csv --svg plot.svg --compare examples/data/approach_truth.csv"
  local SMOOTH = "lua5.4 bin/tagpose-replay bench/dev/sequences/corners.csv --smooth --compare "
    .. "bench/dev/sequences/truth.csv"
  local MEASURED = {
    "lua5.4 bench/make_long_log.lua /tmp/long 200000",
    "/usr/bin/time -v lua5.4 bin/tagpose-replay /tmp/long/corners.csv --track",
    "/usr/bin/time -v lua5.4 bin/tagpose-replay /tmp/long/corners.csv --track --svg "
      .. "/tmp/long/plot.svg --out /tmp/long/poses.csv",
    "/usr/bin/time -v lua5.4 bin/tagpose-replay /tmp/long/corners.csv --smooth --svg "
      .. "/tmp/long/plot.svg --out /tmp/long/poses.csv",
    "lua5.4 bench/make_long_log.lua /tmp/same 200000 2 --same-id",
    "/usr/bin/time -v lua5.4 bin/tagpose-replay /tmp/same/corners.csv --smooth --svg "
      .. "/tmp/same/plot.svg",
  }
  local BOUNDS = "lua5.4 bench/bounds.lua all /tmp/bounds"

  it("shows no command that is not run here", function()
    local known = { [APPROACH] = true, [SMOOTH] = true, [BOUNDS] = true }
    for _, c in ipairs(MEASURED) do known[c] = true end
    for _, c in ipairs(shown(PAGE)) do known[c.command] = true end
    local listed = commands(PAGE)
    assert.is_true(#listed >= 9)
    for _, c in ipairs(listed) do assert.is_true(known[c] ~= nil, c) end
  end)

  it("shows what tagpose-replay says when an output is one of its inputs", function()
    local list = shown(PAGE)
    assert.is_true(#list >= 1)
    for _, c in ipairs(list) do
      local before = run.read("examples/data/approach.csv")
      local text, status = run.run(c.command:gsub("^lua5%.4", run.quote(run.lua())) .. " 2>&1")
      assert.equal(2, status, text)
      assert.equal(c.output, text:match("^[^\n]*"))
      assert.equal(before, run.read("examples/data/approach.csv"))
    end
  end)

  it("shows the replay of the bundled approach as it prints it", function()
    local out, svg = tmp("poses.csv"), tmp("plot.svg")
    local subs = { ["poses.csv"] = out, ["plot.svg"] = svg }
    local text, status = execute(APPROACH, "/tmp", subs)
    os.remove(out)
    os.remove(svg)
    assert.equal(0, status, text)
    local expected = output_after(PAGE, APPROACH):gsub("wrote poses%.csv", "wrote " .. out)
      :gsub("wrote plot%.svg", "wrote " .. svg)
    assert.equal(expected, text)
  end)

  it("shows the smoothed replay of the dev sequences as it prints it", function()
    local text, status = execute(SMOOTH, "/tmp")
    assert.equal(0, status, text)
    local expected = output_after(PAGE, SMOOTH)
    for line in expected:gmatch("[^\n]+") do
      assert.truthy(text:find(line, 1, true), line .. "\nnot in\n" .. text)
    end
  end)

  it("runs the measurements' commands (on logs of 2000 rows)", function()
    local dir = tmp("long")
    assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
    for _, c in ipairs(MEASURED) do
      local text, status = execute(c, dir, { ["200000"] = "2000" })
      assert.equal(0, status, c .. "\n" .. text)
    end
    local poses = run.read(dir .. "/long/poses.csv")
    run.run("rm -r " .. run.quote(dir))
    assert.equal(2001, select(2, poses:gsub("\n", "")))
  end)
end)

describe("docs/tracking.md", function()
  local HELDOUT = "luajit bench/replay_heldout.lua /tmp/held"

  it("runs the held-out replay's command (two small draws)", function()
    local page = run.read("docs/tracking.md")
    assert.truthy(page:find("\n" .. HELDOUT .. "\n", 1, true))
    local dir = tmp("held")
    local text, status = execute(HELDOUT .. " 1 2 40", dir)
    run.run("rm -rf " .. run.quote(dir))
    assert.equal(0, status, text)
    -- the dev set's figures as the page's table has them
    assert.matches("dev/sequences%s+2000%s+8 %(0%.40 %%%)%s+6 %(0%.30 %%%)", text)
    assert.truthy(page:find("| dev `sequences` | 2000 | 8 (0.40 %) | 6 (0.30 %) |", 1, true))
    assert.matches("pooled, draws and dev set%s+%d+", text)
  end)
end)

describe("docs/layouts.md", function()
  it("names a bench command that calibrates a board and compares it with the layout before",
    function()
      assert.truthy(run.read("docs/layouts.md"):find("`lua5.4 bench/bounds.lua board N`", 1, true))
      local text, status = run.script("bench/bounds.lua", "board", "3", "4")
      assert.equal(0, status, text)
      assert.matches("^board 3x3 over 4 frames %(%d+ detections%): calibrated in [%d.]+ s", text)
    end)
end)
