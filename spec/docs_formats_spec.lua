-- The examples of docs/cameras.md and of docs/layouts.md's field maps, run as written: every
-- calibration file shown reads, every Lua example runs (in a folder holding the files it
-- names: the fixtures under those names) and a field map example finds its camera.
local calibration = require("tagpose.formats.calibration")
local tagpose = require("tagpose")
local run = require("support.run")
local docs = require("support.docs")

local ROOT = run.run("pwd")
ROOT = ROOT:gsub("%s+$", "")

-- a folder holding the files the examples name
local dir = run.tmpdir()
for name, fixture in pairs({ ["ost.yaml"] = "spec/fixtures/calibration/ost.yaml",
  ["out_camera_data.xml"] = "spec/fixtures/calibration/opencv_tutorial.xml",
  ["camchain.yaml"] = "spec/fixtures/calibration/kalibr_camchain.yaml",
  ["camera.lua"] = "examples/data/camera.lua",
  ["2024-crescendo.json"] = "spec/fixtures/field/wpilib_field.json" }) do
  run.write(dir .. "/" .. name, run.read(fixture))
end

-- run a Lua example after a prelude, in the folder; its output
local function run_example(prelude, code, name)
  local paths = ROOT .. "/src/?.lua;" .. ROOT .. "/src/?/init.lua;" .. ROOT .. "/spec/?.lua;"
  local path = run.write(dir .. "/" .. name, "package.path = " .. ("%q"):format(paths)
    .. " .. package.path\n" .. prelude .. "\ndo\n" .. code .. "\nend\n")
  local out, status = run.run("cd " .. run.quote(dir) .. " && " .. run.quote(run.lua()) .. " "
    .. run.quote(path) .. " 2>&1")
  assert.equal(0, status, out)
  return out
end

local CAMERA_PRELUDE = [[
local tagpose = require("tagpose")
local corners = { { 184.3547, 315.4197 }, { 233.2137, 320.1938 }, { 239.2579, 271.1957 },
  { 190.5867, 265.5765 } }
local info = { k = { 285.7, 0, 418.2, 0, 286.1, 403.5, 0, 0, 1 },
  d = { -0.0076, 0.0436, -0.0416, 0.0078 }, distortion_model = "equidistant" }
local _ = corners, info
]]

describe("docs/cameras.md", function()
  local text = run.read("docs/cameras.md")
  for i, b in ipairs(docs.fenced(text)) do
    local where = "block " .. i .. " (line " .. b.line .. ", " .. b.lang .. ")"
    if b.lang == "yaml" or b.lang == "xml" or b.lang == "json" then
      it(where .. " is a calibration file that reads", function()
        local camera, info = calibration.decode(b.text, "doc." .. b.lang)
        assert(camera, info)
        assert.is_nil(tagpose.camera.check(camera))
      end)
    elseif b.lang == "lua" and b.text:match("^%-%- the robot's") then
      it(where .. " is a Lua camera file that reads", function()
        assert(calibration.decode(b.text, "camera.lua"))
      end)
    elseif b.lang == "lua" then
      it(where .. " runs", function()
        run_example(CAMERA_PRELUDE, b.text, "cameras_" .. i .. ".lua")
      end)
    end
  end
end)

describe("docs/layouts.md, field maps", function()
  local text = docs.section(run.read("docs/layouts.md"), "## Field maps (WPILib)")
  local found = {}
  for i, b in ipairs(docs.fenced(text)) do
    found[b.lang] = true
    if b.lang == "json" then
      it("the field map shown reads", function()
        local path = run.write(dir .. "/field_" .. i .. ".json", b.text)
        local field = assert(tagpose.layout.read(path, { size = 0.1651 }))
        assert.equal(0.1651, field.tags[7].size)
      end)
    elseif b.lang == "lua" then
      it("the example finds the camera that saw the tags", function()
        -- the detections of the fixture field's tags 1 and 2 by a camera at (3, 4.8, 1),
        -- placed by WPILib's definition of the tags' frames
        local prelude = [[
local layouts = require("support.layouts")
local truth = dofile(]] .. ("%q"):format(ROOT .. "/spec/fixtures/field/truth.lua") .. [[)
local camera = { fx = 910, fy = 910, cx = 639.5, cy = 359.5 }
local rb, tb = layouts.look_at({ 3, 4.8, 1 }, { 0, 4.8, 1.4 }, { 0, 0, 1 })
local detections = {}
for _, id in ipairs({ 1, 2 }) do
  local t, h = truth[id], 0.1651 / 2
  local r = layouts.matrix({ w = t.quaternion[1], x = t.quaternion[2], y = t.quaternion[3],
    z = t.quaternion[4] })
  local px = {}
  for k, c in ipairs({ { 0, -h, -h }, { 0, h, -h }, { 0, h, h }, { 0, -h, h } }) do
    local x, y, z = layouts.apply(r, c[1], c[2], c[3])
    x, y, z = layouts.apply(rb, x + t.position[1], y + t.position[2], z + t.position[3])
    x, y, z = x + tb[1], y + tb[2], z + tb[3]
    px[k] = { camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy }
  end
  detections[#detections + 1] = { id = id, corners = px }
end
]]
        local out = run_example(prelude, b.text, "layouts_" .. i .. ".lua")
        assert.equal("camera at x = 3.000 m, y = 4.800 m, z = 1.000 m\n", out)
      end)
    end
  end
  it("shows a field map and an example", function()
    assert.is_true(found.json and found.lua)
  end)
end)
