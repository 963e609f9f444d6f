-- The commands' --camera takes what tagpose.calibration.read takes, and their texts say so: a Lua
-- camera file, ROS YAML, OpenCV FileStorage YAML, XML or JSON, a Kalibr camchain (its cam0). The
-- lists of the usage texts and of the docs left out XML, JSON and Kalibr.
local run = require("support.run")

local CALIBRATIONS = "spec/fixtures/calibration/"

-- the text of a file from `from` to the default's "beside" (the log, LOG.csv) that ends it
local function passage(path, from)
  local text = run.read(path)
  local a = assert(text:find(from, 1, true), path .. ": " .. from)
  local b = assert(text:find("beside", a, true), path .. ": no default after " .. from)
  return text:sub(a, b)
end

describe("--camera", function()
  local texts = {
    { "src/tagpose/tools/replay/init.lua", "-- --camera" },
    { "src/tagpose/tools/calibrate.lua", "-- --camera" },
    { "docs/replay.md", "| `--camera FILE`" },
    { "docs/layouts.md", "The camera file is anything" },
  }
  for _, t in ipairs(texts) do
    it("is described in " .. t[1] .. " with every format tagpose.calibration reads", function()
      local text = passage(t[1], t[2])
      for _, word in ipairs({ "Lua", "ROS", "OpenCV", "YAML", "XML", "JSON", "Kalibr" }) do
        assert.is_truthy(text:find(word, 1, true), t[1] .. " has no " .. word .. ":\n" .. text)
      end
    end)
  end

  local files = { "opencv_tutorial.xml", "opencv_tutorial.json", "kalibr_camchain.yaml" }
  -- (the calibration log's first 300 rows: reading the camera is what is checked, not the
  -- calibration, and the whole log takes 0.4 s a run)
  local log = os.tmpname()
  do
    local lines = {}
    for line in io.lines("bench/dev/layout_cube/calib/corners.csv") do
      lines[#lines + 1] = line
      if #lines > 300 then break end
    end
    run.write(log, table.concat(lines, "\n") .. "\n")
  end
  for _, file in ipairs(files) do
    it("of tagpose-replay reads " .. file, function()
      local out, status = run.script("bin/tagpose-replay", "examples/data/approach.csv",
        "--camera", CALIBRATIONS .. file, "--tag-size", "0.024")
      assert.equal(0, status, out)
      assert.is_truthy(out:find("median reprojection error", 1, true), out)
    end)

    it("of tagpose-calibrate reads " .. file, function()
      local out, status = run.script("bin/tagpose-calibrate", log, "--layout",
        "bench/dev/layout_cube/nominal_layout.csv", "--camera", CALIBRATIONS .. file)
      assert.equal(0, status, out)
      assert.is_truthy(out:find("residual rms", 1, true), out)
    end)
  end
end)
