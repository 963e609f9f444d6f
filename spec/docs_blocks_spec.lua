-- The examples of docs/blocks.md and of docs/layouts.md's calibrated cube, run as written:
-- examples/block_frame.lua prints what the page shows, and the Lua examples of a cube of its
-- own run in a folder holding the layout bin/tagpose-calibrate wrote from a glued cube's log
-- (spec/support/blocks.lua), on a frame of three copies of that cube, and find the copies.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local blocks_support = require("support.blocks")
local run = require("support.run")
local docs = require("support.docs")

local camera = blocks_support.camera

local ROOT = run.run("pwd"):gsub("%s+$", "")

local dir = run.tmpdir("cube2")

-- A glued cube's calibration log, its nominal layout and camera, calibrated by the command the
-- pages name; a frame of three copies of the cube (its detections in a Lua data file) and
-- their true poses.
local rng = geometry.rng(31)
local nominal, truth = blocks_support.glued_cube(rng)
local function num(v) return ("%.17g"):format(v) end
do
  local lines = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
  for f, dets in ipairs(blocks_support.calibration_log(truth, camera, rng, 40, 0.3)) do
    for _, d in ipairs(dets) do
      local row = { f, d.id }
      for _, c in ipairs(d.corners) do row[#row + 1] = num(c[1]) .. "," .. num(c[2]) end
      lines[#lines + 1] = table.concat(row, ",")
    end
  end
  run.write(dir .. "/corners.csv", table.concat(lines, "\n") .. "\n")
  run.write(dir .. "/camera.lua", ("return { fx = %s, fy = %s, cx = %s, cy = %s }\n"):format(
    num(camera.fx), num(camera.fy), num(camera.cx), num(camera.cy)))
  assert(tagpose.layout.write(dir .. "/nominal.lua", nominal))
end
local detections, poses = blocks_support.copies(truth, camera, geometry.rng(32), 3, 0.1)
do
  local lines = { "return {" }
  for _, d in ipairs(detections) do
    local c = d.corners
    lines[#lines + 1] = ("  { id = %d, corners = { { %s, %s }, { %s, %s }, { %s, %s }, "
      .. "{ %s, %s } } },"):format(d.id, num(c[1][1]), num(c[1][2]), num(c[2][1]), num(c[2][2]),
      num(c[3][1]), num(c[3][2]), num(c[4][1]), num(c[4][2]))
  end
  lines[#lines + 1] = "}"
  run.write(dir .. "/detections.lua", table.concat(lines, "\n") .. "\n")
end

-- the layout the command writes, for the examples to read (as calibrated.yaml and
-- cube2/calibrated.yaml)
local calibrate_output, calibrate_status = run.script("bin/tagpose-calibrate",
  dir .. "/corners.csv", "--layout", dir .. "/nominal.lua", "--out", dir .. "/calibrated.yaml")
if calibrate_status == 0 then
  run.write(dir .. "/cube2/calibrated.yaml", run.read(dir .. "/calibrated.yaml"))
end

local PRELUDE = ([[
local tagpose = require("tagpose")
local camera = { fx = %s, fy = %s, cx = %s, cy = %s }
local detections = dofile("detections.lua")
local _ = tagpose, camera, detections
]]):format(num(camera.fx), num(camera.fy), num(camera.cx), num(camera.cy))

-- run a Lua example after the prelude, in the folder; its output
local function run_example(code, name)
  local paths = ROOT .. "/src/?.lua;" .. ROOT .. "/src/?/init.lua;"
  local path = run.write(dir .. "/" .. name, "package.path = " .. ("%q"):format(paths)
    .. " .. package.path\n" .. PRELUDE .. "\ndo\n" .. code .. "\nend\n")
  local out, status = run.run("cd " .. run.quote(dir) .. " && " .. run.quote(run.lua()) .. " "
    .. run.quote(path) .. " 2>&1")
  assert.equal(0, status, out)
  return out
end

-- the distance from a centre to the nearest true copy's
local function off(x, y, z)
  local best = math.huge
  for _, p in ipairs(poses) do
    best = math.min(best, math.sqrt((x - p.t[1]) ^ 2 + (y - p.t[2]) ^ 2 + (z - p.t[3]) ^ 2))
  end
  return best
end

describe("docs/blocks.md", function()
  local text = run.read("docs/blocks.md")

  it("shows what examples/block_frame.lua prints", function()
    local shown
    for _, b in ipairs(docs.fenced(text)) do
      if b.lang == "" and b.text:match("^block 1: ") then shown = b.text end
    end
    local out, status = run.script("examples/block_frame.lua")
    assert.equal(0, status, out)
    assert.equal(shown, out)
  end)

  describe("a cube of its own", function()
    local part = docs.section(text, "**A cube of its own", "\n**How.**")

    it("is calibrated by the command the pages show", function()
      assert.equal(0, calibrate_status, calibrate_output)
      assert.matches("wrote .*calibrated%.yaml", calibrate_output)
    end)

    local examples = 0
    for i, b in ipairs(docs.fenced(part)) do
      if b.lang == "lua" then
        examples = examples + 1
        it("runs its example " .. i .. " (line " .. b.line .. ")", function()
          local out = run_example(b.text, "blocks_" .. i .. ".lua")
          local found = 0
          for x, y, z in out:gmatch("centre %(([-%d.]+), ([-%d.]+), ([-%d.]+)%) m") do
            found = found + 1
            local d = off(tonumber(x), tonumber(y), tonumber(z))
            assert.is_true(d < 0.003, ("a block %.1f mm from every copy"):format(1000 * d))
          end
          -- the calibrated cube's example finds the three copies
          if b.text:find("calibrated.yaml", 1, true) then assert.equal(3, found, out) end
        end)
      end
    end
    it("has two examples", function() assert.equal(2, examples) end)
  end)
end)

describe("docs/layouts.md, a calibrated cube back into tagpose.block.solve", function()
  local part = docs.section(run.read("docs/layouts.md"),
    "### A calibrated cube back into `tagpose.block.solve`", "\n## ")
  local examples = 0
  for i, b in ipairs(docs.fenced(part)) do
    if b.lang == "lua" then
      examples = examples + 1
      it("runs its example and finds the cubes", function()
        local out = run_example(b.text, "layouts_cube_" .. i .. ".lua")
        local n, z = out:match("^(%d+) cubes; the first at z = ([%d.]+) m\n$")
        assert.equal("3", n, out)
        -- the first block is the nearest copy
        local nearest = math.huge
        for _, p in ipairs(poses) do
          nearest = math.min(nearest, p.t[1] ^ 2 + p.t[2] ^ 2 + p.t[3] ^ 2)
        end
        for _, p in ipairs(poses) do
          if p.t[1] ^ 2 + p.t[2] ^ 2 + p.t[3] ^ 2 == nearest then
            assert.near(p.t[3], tonumber(z), 0.003)
          end
        end
      end)
    end
  end
  it("has an example", function() assert.equal(1, examples) end)
end)
