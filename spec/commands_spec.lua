-- The three commands as users expect them (issue 26): one options reader for all
-- (tagpose.tools.command), its help, version, "did you mean" and --opt=value; outputs named as
-- outputs; the corner order; a replay with no pose a failure; sizes with their units; values
-- out of bounds refused. Each command runs with the Lua that runs the specs.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local run = require("support.run")

local LOG = "examples/data/approach.csv"
local COMMANDS = { "bin/tagpose-replay", "bin/tagpose-calibrate", "bin/tagpose-localize" }

local dir = run.tmpdir()

-- a corner log with each row's corners reversed: OpenCV's and ArUco's order
local function reversed(path, out)
  local lines = {}
  for line in io.lines(path) do
    if not line:match("^#") then
      local f = {}
      for field in (line .. ","):gmatch("([^,]*),") do f[#f + 1] = field end
      if f[1] == "frame" then
        lines[#lines + 1] = "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4"
      else
        lines[#lines + 1] = table.concat({ f[1], f[2], f[9], f[10], f[7], f[8], f[5], f[6],
          f[3], f[4] }, ",")
      end
    end
  end
  return run.write(out, table.concat(lines, "\n") .. "\n")
end

-- the glued cube of spec/calibrate_tool_spec.lua, circled by a camera: its log and camera file
local CUBE = dir .. "/cube"
do
  os.execute("mkdir -p " .. run.quote(CUBE))
  local camera = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87, width = 320, height = 240 }
  local rng = geometry.rng(41)
  local _, truth = layouts.cube(rng, 0.0229, 0.0548, 2, 3, 0.3)
  layouts.write_log(CUBE, truth, camera, rng, 20, 0.1)
end

-- the per-tag lines of a calibration's report
local function tag_lines(text)
  local out = {}
  for line in text:gmatch("[^\n]+") do
    if line:match("^tag %d+:") then out[#out + 1] = line end
  end
  return out
end

-- the distance tag `id` moved, in mm, as the report says
local function moved(text, id)
  return tonumber(text:match("\ntag " .. id .. ": ([%d.]+) mm towards"))
end

describe("the commands' options reader", function()
  it("--help explains every option of the usage with its default", function()
    for _, command in ipairs(COMMANDS) do
      local text, status = run.script(command, "--help")
      assert.equal(0, status, text)
      local synopsis = text:match("^(.-)\n\n")
      assert.truthy(synopsis, text)
      local n = 0
      for option in synopsis:gmatch("(%-%-[%a-]+)") do
        n = n + 1
        -- an entry of its own: the option at the start of a line, then what it does
        assert.truthy(text:find("\n  " .. option:gsub("%-", "%%-") .. "[ \n][^\n]*%a", 1),
          command .. " --help: no entry for " .. option .. "\n" .. text)
      end
      assert.is_true(n >= 8, command)
      assert.truthy(text:find("--version", 1, true), text)
    end
    -- (the help's lines wrapped: its words compared)
    local text = run.script("bin/tagpose-replay", "--help"):gsub("%s+", " ")
    assert.truthy(text:find(" %-%-fps F frames per second [^%-]*%(default: 30%) "), text)
    assert.truthy(text:find("(default: refined)", 1, true), text)
    text = run.script("bin/tagpose-calibrate", "--help"):gsub("%s+", " ")
    assert.truthy(text:find("(default: 3)", 1, true), text)
    assert.truthy(text:find("(default: the tag seen most)", 1, true), text)
  end)

  it("--version prints tagpose's version", function()
    for _, command in ipairs(COMMANDS) do
      local text, status = run.script(command, "--version")
      assert.equal(0, status, text)
      assert.equal(command:match("([^/]+)$") .. " (" .. tagpose._VERSION .. ")\n", text)
    end
  end)

  it("names the option meant by a mistyped one", function()
    local text, status = run.script("bin/tagpose-replay", LOG, "--trak")
    assert.equal(2, status)
    assert.truthy(text:find("replay: unknown option --trak (did you mean --track?)", 1, true),
      text)
    text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "0.0229,0.0548", "--refrence", "1")
    assert.equal(2, status)
    assert.truthy(text:find("(did you mean --reference?)", 1, true), text)
    text, status = run.script("bin/tagpose-localize", "c.csv", "--odometri", "o.csv")
    assert.equal(2, status)
    assert.truthy(text:find("(did you mean --odometry?)", 1, true), text)
    text, status = run.script("bin/tagpose-replay", LOG, "--zzzzzz")
    assert.equal(2, status)
    assert.truthy(text:find("replay: unknown option --zzzzzz\n", 1, true), text)
  end)

  it("takes --option=value as --option value", function()
    local text, status = run.script("bin/tagpose-replay", LOG, "--fps=10.5", "--method=seed")
    assert.equal(0, status, text)
    assert.truthy(text:find("time   frame / 10.5 ", 1, true), text)
    assert.truthy(text:find("method seed,", 1, true), text)
    text, status = run.script("bin/tagpose-replay", LOG, "--track=yes")
    assert.equal(2, status)
    assert.truthy(text:find("--track takes no value", 1, true), text)
  end)
end)

describe("the commands' outputs", function()
  it("name a missing --out folder as the output, not as the log", function()
    local missing = dir .. "/no/such/folder/"
    local text, status = run.script("bin/tagpose-replay", LOG, "--out", missing .. "p.csv")
    assert.equal(1, status, text)
    assert.truthy(text:find("replay: the pose log (--out): " .. missing .. "p.csv", 1, true), text)
    assert.falsy(text:find("log:", 1, true), text)
    text, status = run.script("bin/tagpose-replay", LOG, "--svg", missing .. "p.svg")
    assert.equal(1, status, text)
    assert.truthy(text:find("replay: the plot (--svg): " .. missing .. "p.svg", 1, true), text)
    text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "0.0229,0.0548", "--out", missing .. "c.lua")
    assert.equal(1, status, text)
    assert.truthy(text:find("calibrate: the calibrated layout (--out): " .. missing, 1, true),
      text)
    text, status = run.script("bin/tagpose-localize", CUBE .. "/corners.csv", "--map", "m.json",
      "--cameras", "c.lua", "--out", missing .. "p.csv")
    assert.equal(1, status, text)
    assert.truthy(text:find("localize: the poses (--out): " .. missing, 1, true), text)
  end)
end)

describe("tagpose-calibrate --reference", function()
  it("refuses a tag that is not in the layout as a usage error", function()
    local text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "0.0229,0.0548", "--reference", "99")
    assert.equal(2, status, text)
    assert.truthy(text:find("calibrate: --reference 99: no tag 99 in the layout (its tags: 0, 1,"
      .. " 2, 3, 4, 5)", 1, true), text)
    assert.truthy(text:find("\nusage: ", 1, true), text)
  end)
end)

describe("--order opencv", function()
  local flipped = reversed(LOG, dir .. "/flipped.csv")
  run.write(dir .. "/camera.lua", run.read("examples/data/camera.lua"))

  it("replays a log in OpenCV's corner order as the log in the detector's", function()
    local text, status = run.script("bin/tagpose-replay", flipped, "--order", "opencv", "--out",
      "-")
    assert.equal(0, status, text)
    local plain = run.script("bin/tagpose-replay", LOG, "--out", "-")
    local function rows(t)
      local out = {}
      for line in t:gmatch("[^\n]+") do
        if line:match("^%d+,%d+,%-?%d") then out[#out + 1] = line:match("^([^,]*,[^,]*,[^,]*,"
          .. "[^,]*,[^,]*),") end
      end
      return out
    end
    assert.equal(377, #rows(plain))
    assert.same(rows(plain), rows(text))
  end)

  it("calibrates from a log in OpenCV's corner order as from the log in the detector's", function()
    local cube_flipped = dir .. "/cube_flipped"
    os.execute("mkdir -p " .. run.quote(cube_flipped))
    reversed(CUBE .. "/corners.csv", cube_flipped .. "/corners.csv")
    run.write(cube_flipped .. "/camera.lua", run.read(CUBE .. "/camera.lua"))
    -- without --order: the failure says which option reads them
    local text, status = run.script("bin/tagpose-calibrate", cube_flipped .. "/corners.csv",
      "--cube", "0.0229,0.0548")
    assert.equal(1, status, text)
    assert.truthy(text:find("square: corners wind the wrong way round", 1, true), text)
    assert.truthy(text:find("--order opencv)", 1, true), text)
    text, status = run.script("bin/tagpose-calibrate", cube_flipped .. "/corners.csv",
      "--cube", "0.0229,0.0548", "--order", "opencv")
    assert.equal(0, status, text)
    local plain = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "0.0229,0.0548")
    assert.equal(6, #tag_lines(plain), plain)
    assert.same(tag_lines(plain), tag_lines(text))
  end)
end)

describe("tagpose-replay with no pose", function()
  it("fails with the reason on standard error and in every panel", function()
    local flipped = reversed(LOG, dir .. "/flipped.csv")
    run.write(dir .. "/camera.lua", run.read("examples/data/camera.lua"))
    local svg, poses = dir .. "/none.svg", dir .. "/none.csv"
    local text, status = run.script("bin/tagpose-replay", flipped, "--svg", svg, "--out", poses)
    assert.equal(1, status, text)
    assert.truthy(text:find("replay: no pose: no row of " .. flipped .. " was solved; 377 of"
      .. " its 377 rows failed with square: corners wind the wrong way round", 1, true), text)
    assert.truthy(text:find("--order opencv)", 1, true), text)
    assert.falsy(text:find("options.order", 1, true), text)
    local figure = run.read(svg)
    assert.equal(7, run.count(figure, ">no pose: no row of "), figure)
    assert.equal(0, run.count(figure, ">no data<"))
    assert.truthy(run.xmllint(figure))
    -- the pose log keeps every row, with empty pose fields
    assert.equal(378, select(2, run.read(poses):gsub("\n", "")))
  end)
end)

describe("sizes with their units", function()
  it("tagpose-calibrate --cube takes units, as --tag-size does", function()
    local text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "22.9mm,54.8mm", "--out", dir .. "/cube_mm.lua")
    assert.equal(0, status, text)
    local metres = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "0.0229,0.0548")
    assert.same(tag_lines(metres), tag_lines(text))
    -- the layout is in the unit given; --unit converts it
    assert.near(22.9, assert(tagpose.layout.read(dir .. "/cube_mm.lua")).tags[0].size, 1e-12)
    text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "22.9mm,5.48cm", "--unit", "m", "--out", dir .. "/cube_m.lua")
    assert.equal(0, status, text)
    assert.near(0.0229, assert(tagpose.layout.read(dir .. "/cube_m.lua")).tags[0].size, 1e-15)
  end)

  it("tagpose-calibrate refuses millimetres without their unit", function()
    local text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "22.9,54.8")
    assert.equal(2, status, text)
    assert.truthy(text:find("calibrate: --cube 22.9,54.8 has no unit and reads as metres: a tag"
      .. " 22.9 m wide? Give the unit (22.9mm,54.8mm)", 1, true), text)
    assert.falsy(text:find("mm towards", 1, true), text)
    -- in the unit --unit names, they are what they say
    text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
      "22.9,54.8", "--unit", "mm")
    assert.equal(0, status, text)
    assert.near(2.10, moved(text, 0), 0.02)
  end)

  it("tagpose-replay --unit converts a tag size given in another unit", function()
    local text, status = run.script("bin/tagpose-replay", LOG, "--tag-size", "0.024m", "--unit",
      "cm", "--out", "-")
    assert.equal(0, status, text)
    assert.truthy(text:find("tag size 2.4 cm", 1, true), text)
    local metres = run.script("bin/tagpose-replay", LOG, "--tag-size", "0.024m", "--out", "-")
    local z_cm = tonumber(text:match("\n0,1,[^,]+,[^,]+,([^,]+),"))
    local z_m = tonumber(metres:match("\n0,1,[^,]+,[^,]+,([^,]+),"))
    assert.near(100 * z_m, z_cm, 1e-9 * z_cm)
    text, status = run.script("bin/tagpose-replay", LOG, "--tag-size", "0.024m", "--unit",
      "furlong")
    assert.equal(2, status, text)
    assert.truthy(text:find("--unit furlong: the tag size is in m", 1, true), text)
  end)

  it("tagpose-localize --tag-size takes units and refuses millimetres without theirs", function()
    local text, status = run.script("bin/tagpose-localize", "c.csv", "--map", "m.json",
      "--cameras", "c.lua", "--out", dir .. "/p.csv", "--tag-size", "165.1")
    assert.equal(2, status, text)
    assert.truthy(text:find("localize: --tag-size 165.1 has no unit and reads as metres", 1,
      true), text)
    text, status = run.script("bin/tagpose-localize", dir .. "/none.csv", "--map", "m.json",
      "--cameras", "c.lua", "--out", dir .. "/p.csv", "--tag-size", "165.1mm")
    assert.equal(1, status, text) -- read as a size: the missing cameras file is what fails
  end)
end)

describe("values out of bounds", function()
  it("tagpose-replay refuses a --sigma whose covariance overflows", function()
    local text, status = run.script("bin/tagpose-replay", LOG, "--sigma", "1e200", "--out", "-")
    assert.equal(2, status, text)
    assert.truthy(text:find("replay: --sigma: a number from 1e-06 to 1e+06 expected, got 1e200",
      1, true), text)
    assert.falsy(text:find("inf", 1, true), text)
  end)

  it("tagpose-replay refuses a --fps whose times overflow, with no traceback", function()
    local text, status = run.script("bin/tagpose-replay", LOG, "--fps", "1e-320")
    assert.equal(2, status, text)
    assert.truthy(text:find("replay: --fps: a number from 1e-06 to 1e+06 expected, got 1e-320",
      1, true), text)
    assert.falsy(text:find("traceback", 1, true), text)
  end)

  it("tagpose-calibrate --robust 1e10 is the plain least squares, not the nominal layout",
    function()
      local text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
        "0.0229,0.0548", "--robust", "1e10")
      assert.equal(0, status, text)
      local default = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv", "--cube",
        "0.0229,0.0548")
      for id = 0, 5 do
        assert.is_true(moved(default, id) > 0.5, default)
        assert.near(moved(default, id), moved(text, id), 0.05, "tag " .. id .. "\n" .. text)
      end
    end)

  it("tagpose-calibrate refuses a --robust under which every detection is an outlier",
    function()
      for _, k in ipairs({ "1e-10", "0.5", "0" }) do
        local text, status = run.script("bin/tagpose-calibrate", CUBE .. "/corners.csv",
          "--cube", "0.0229,0.0548", "--robust", k)
        assert.equal(2, status, text)
        assert.truthy(text:find("calibrate: --robust: a number of at least 1", 1, true), text)
      end
    end)
end)

describe("tagpose-replay with a tag size in another unit", function()
  it("warns when the tags come out hundreds of metres from the camera", function()
    local far = dir .. "/far"
    os.execute("mkdir -p " .. run.quote(far))
    run.write(far .. "/corners.csv", run.read(LOG))
    -- millimetres in the camera file, read as metres
    run.write(far .. "/camera.lua",
      "return { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, tag_size = 24 }\n")
    local text, status = run.script("bin/tagpose-replay", far .. "/corners.csv")
    assert.equal(0, status, text)
    assert.truthy(text:find("replay: warning: the tags are a median 357.7 m from the camera, with"
      .. " a tag size of 24 m: is the tag size in another unit? (give it with its unit:"
      .. " --tag-size 24mm)", 1, true), text)
    -- in millimetres, or in units of their own, they are where they are
    for _, size in ipairs({ "24mm", "24" }) do
      text = run.script("bin/tagpose-replay", far .. "/corners.csv", "--tag-size", size)
      assert.falsy(text:find("warning", 1, true), text)
    end
  end)
end)
