-- The commands that docs/uncertainty.md and docs/blocks.md show for the uncertainty without
-- options.sigma, run as they are written (with this spec's Lua for lua5.4 and luajit, and a
-- temporary directory for /tmp), and what they print held to what the pages claim: blocks
-- and layouts measure σ, so their 95 % ellipsoids cover 93-97 % (blocks at σ 0.3 px, a layout
-- at 1 px; spec/block_spec.lua and spec/layout_solve_spec.lua check 0.15 and 1 px).

local run = require("support.run")

local DOCS = { "docs/uncertainty.md", "docs/blocks.md" }

local TABLE = "lua5.4 bench/ellipsoid_table.lua"
local BLOCKS = "lua5.4 bench/make_blocks.lua /tmp/blocks5 600 5 && luajit "
  .. "examples/uncertainty.lua /tmp/blocks5 --default-sigma"
local LAYOUT = "lua5.4 bench/make_layout.lua /tmp/layout3 3 --calib 1 --test 5 --camera wide "
  .. "--sigma 1 && luajit examples/uncertainty.lua /tmp/layout3 --default-sigma"
local TAGS = "lua5.4 bench/make_tags.lua /tmp/n05 noise_0.5 1 && luajit "
  .. "examples/uncertainty.lua /tmp/n05 --default-sigma"

-- does a page show the command (an indented line of its own)?
local function shows(path, command)
  for line in run.read(path):gmatch("[^\n]+") do
    if line == "    " .. command then return true end
  end
  return false
end

-- run a documented command: its output and the status of the first part that failed
local function execute(command, dir)
  local out = {}
  for part in (command .. " && "):gmatch("(.-) && ") do
    local words = {}
    for w in part:gmatch("%S+") do words[#words + 1] = run.quote((w:gsub("^/tmp/", dir .. "/"))) end
    assert(words[1] == "'lua5.4'" or words[1] == "'luajit'", part)
    words[1] = run.quote(run.lua())
    local text, status = run.run(table.concat(words, " ") .. " 2>&1")
    out[#out + 1] = text
    if status ~= 0 then return table.concat(out), status end
  end
  return table.concat(out), 0
end

local function within(value, lo, hi, text)
  assert.is_true(value ~= nil and value >= lo and value <= hi, text)
end

describe("docs: the uncertainty without options.sigma", function()
  local dir

  setup(function()
    dir = run.run("mktemp -d"):gsub("%s+$", "")
  end)

  teardown(function()
    if dir and dir:match("^/tmp/") then run.run("rm -rf " .. run.quote(dir)) end
  end)

  it("shows the commands run here", function()
    for _, c in ipairs({ TABLE, BLOCKS, LAYOUT, TAGS }) do
      assert.is_true(shows(DOCS[1], c), c)
    end
    assert.is_true(shows(DOCS[2], BLOCKS), BLOCKS)
  end)

  it("prints the ellipsoid factors' table", function()
    local text, status = execute(TABLE, dir)
    assert.equal(0, status, text)
    assert.truthy(text:find("local ELLIPSOID = {", 1, true), text)
  end)

  it("covers blocks of two faces or more as claimed, σ 0.3 px not given", function()
    local text, status = execute(BLOCKS, dir)
    assert.equal(0, status, text)
    local centre, pose = text:match("centre inside the 95 %% ellipsoid ([%d.]+) %% %(pose, 6 "
      .. "dof: ([%d.]+) %%%)")
    within(tonumber(centre), 92, 98, text)
    within(tonumber(pose), 92, 98, text)
  end)

  it("covers views of several tags of a layout as claimed, σ 1 px not given", function()
    local text, status = execute(LAYOUT, dir)
    assert.equal(0, status, text)
    within(tonumber(text:match("two tags or more ([%d.]+) %%")), 92, 98, text)
  end)

  it("scores one tag's default path with κ(2)", function()
    local text, status = execute(TAGS, dir)
    assert.equal(0, status, text)
    within(tonumber(text:match("coverage%s+([%d.]+) %%")), 90, 98, text)
  end)
end)
