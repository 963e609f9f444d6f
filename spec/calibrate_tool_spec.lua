-- bin/tagpose-calibrate end to end, run with the Lua that runs the specs, on a log drawn from
-- geometry: a glued cube circled by a camera.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local run = require("support.run")

local camera = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87, width = 320, height = 240 }
local TAG, BLOCK = 0.0229, 0.0548

local dir = run.tmpdir()

-- a corner log of the glued cube (sessions on three faces) and its camera file
local function write_log(rng, truth)
  layouts.write_log(dir, truth, camera, rng, 20, 0.1)
end

describe("bin/tagpose-calibrate", function()
  local rng = geometry.rng(41)
  local nominal, truth = layouts.cube(rng, TAG, BLOCK, 2, 3, 0.3)
  write_log(rng, truth)

  it("calibrates a cube from its log, says per tag what is off, writes the layout", function()
    local out = dir .. "/calibrated.yaml"
    local text, status = run.script("bin/tagpose-calibrate", dir .. "/corners.csv", "--cube",
      TAG .. "," .. BLOCK, "--out", out)
    assert.equal(0, status, text)
    for id = 0, 5 do
      local n, g = nominal.tags[id], truth.tags[id]
      local off = 1000 * math.sqrt((g.position.x - n.position.x) ^ 2
        + (g.position.y - n.position.y) ^ 2 + (g.position.z - n.position.z) ^ 2)
      local mm = tonumber(text:match("\ntag " .. id .. ": ([%d.]+) mm towards [-+xyz]+, turned"))
      assert.is_number(mm, text)
      assert.near(off, mm, 0.2, "tag " .. id)
    end
    assert.matches("wrote " .. out:gsub("%p", "%%%0"), text)
    local calibrated = assert(tagpose.layout.read(out))
    local d, r = layouts.pair_error(calibrated, truth)
    assert.is_true(d < 5e-4 and r < 1, ("%.3g mm, %.3g deg"):format(1e3 * d, r))
  end)

  it("takes the nominal layout from a file, and says what is wrong with one", function()
    local nominal_path = dir .. "/nominal.lua"
    assert(tagpose.layout.write(nominal_path, nominal))
    local text, status = run.script("bin/tagpose-calibrate", dir .. "/corners.csv", "--layout",
      nominal_path, "--camera", dir .. "/camera.lua", "--reference", "4", "--gauge", "corners")
    assert.equal(0, status, text)
    assert.matches("gauge: tag 4 held fixed", text)
    run.write(dir .. "/bad.csv", "id,size,x,y,z,qw,qx,qy,qz\n0,0.02,0,0,0,1,0,0\n")
    text, status = run.script("bin/tagpose-calibrate", dir .. "/corners.csv", "--layout",
      dir .. "/bad.csv")
    assert.equal(1, status, text)
    assert.matches("bad.csv:2: 8 fields, header has 9", text)
  end)

  it("refuses a bad command line with status 2", function()
    local text, status = run.script("bin/tagpose-calibrate", dir .. "/corners.csv")
    assert.equal(2, status)
    assert.matches("give the nominal layout", text)
    text, status = run.script("bin/tagpose-calibrate", dir .. "/corners.csv", "--cube", "0.05,0.02")
    assert.equal(2, status)
    assert.matches("%-%-cube: TAG_SIZE,BLOCK_SIZE", text)
    text, status = run.script("bin/tagpose-calibrate", "--help")
    assert.equal(0, status)
    assert.matches("^usage: tagpose%-calibrate", text)
  end)

  it("names a missing log before it looks for the camera file beside it", function()
    -- no --camera: camera.lua beside a log that does not exist is not what is wrong
    local text, status = run.script("bin/tagpose-calibrate", "/nonexistent/log.csv", "--cube",
      "0.024,0.055")
    assert.equal(1, status, text)
    assert.truthy(text:find("calibrate: log: /nonexistent/log.csv", 1, true), text)
    assert.falsy(text:find("camera", 1, true), text)
    -- with --camera, the same
    text, status = run.script("bin/tagpose-calibrate", "/nonexistent/log.csv", "--cube",
      "0.024,0.055", "--camera", dir .. "/camera.lua")
    assert.equal(1, status, text)
    assert.truthy(text:find("calibrate: log: /nonexistent/log.csv", 1, true), text)
  end)
end)
