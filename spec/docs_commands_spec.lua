-- The commands docs/replay.md and docs/layouts.md show of what the tools refuse, run as shown
-- (with the Lua running the specs), their output compared with the page's. (The measurements'
-- command, `bench/bounds.lua all`, takes minutes: its parts are the generators the memory and
-- layout specs run.)
local run = require("support.run")

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

describe("docs/replay.md", function()
  it("shows what tagpose-replay says when an output is one of its inputs", function()
    local commands = shown("docs/replay.md")
    assert.is_true(#commands >= 1)
    for _, c in ipairs(commands) do
      local before = run.read("examples/data/approach.csv")
      local text, status = run.run(c.command:gsub("^lua5%.4", run.quote(run.lua())) .. " 2>&1")
      assert.equal(2, status, text)
      assert.equal(c.output, text:match("^[^\n]*"))
      assert.equal(before, run.read("examples/data/approach.csv"))
    end
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
