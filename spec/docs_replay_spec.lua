-- #docs: what docs/replay.md and docs/tracking.md show the replay command printing is what it
-- prints (spec/docs_commands_spec.lua runs every command the pages show; this compares the
-- outputs they show).
local run = require("support.run")

local function tmp(name)
  local base = os.tmpname() -- created: take its unique name only
  os.remove(base)
  return base .. "-" .. name
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

describe("#docs docs/replay.md", function()
  local PAGE = "docs/replay.md"
  local APPROACH = "lua5.4 bin/tagpose-replay examples/data/approach.csv --track --out "
    .. "poses.csv --svg plot.svg --compare examples/data/approach_truth.csv"
  local SMOOTH = "lua5.4 bin/tagpose-replay bench/dev/sequences/corners.csv --smooth --compare "
    .. "bench/dev/sequences/truth.csv"
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
end)

describe("#docs docs/tracking.md", function()
  local HELDOUT = "luajit bench/replay_heldout.lua /tmp/held"

  it("runs the held-out replay's command (two small draws)", function()
    local page = run.read("docs/tracking.md")
    assert.truthy(page:find("\n" .. HELDOUT .. "\n", 1, true))
    local dir = tmp("held")
    local text, status = execute(HELDOUT .. " 1 2 40", dir)
    run.run("rm -rf " .. run.quote(dir))
    assert.equal(0, status, text)
    -- the dev set's figures (the whole set, whatever the draws' size) as the page's table has
    -- them
    local tracked, smoothed = text:match("dev/sequences%s+2000%s+(%d+ %([%d.]+ %%%))%s+"
      .. "(%d+ %([%d.]+ %%%))")
    assert.is_truthy(tracked, text)
    local row = "| dev `sequences` | 2000 | " .. tracked .. " | " .. smoothed .. " |"
    assert.truthy(page:find(row, 1, true), row .. " not in docs/tracking.md")
    assert.matches("pooled, draws and dev set%s+%d+", text)
  end)
end)
