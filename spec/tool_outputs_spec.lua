-- What the commands write: never over what they read (one file under two names counts: ./,
-- symbolic and hard links), checked and opened before anything is read, and every failed
-- write, standard output's included, an exit status other than 0 with a message.
local tagpose = require("tagpose")
local files = require("tagpose.tools.files")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local run = require("support.run")

local dir = run.tmpdir()

local REPLAY, CALIBRATE = "bin/tagpose-replay", "bin/tagpose-calibrate"

-- the inputs of both commands: a replay's log, camera and compared log; a glued cube's log,
-- its nominal layout
local function setup()
  run.write(dir .. "/log.csv", run.read("examples/data/approach.csv"))
  run.write(dir .. "/camera.lua", run.read("examples/data/camera.lua"))
  run.write(dir .. "/truth.csv", run.read("examples/data/approach_truth.csv"))
  local camera = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87, width = 320, height = 240 }
  local rng = geometry.rng(43)
  local nominal, truth = layouts.cube(rng, 0.0229, 0.0548, 2, 3, 0.3)
  local lines = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
  for frame, dets in ipairs(layouts.session(truth, camera, rng, 30, { 0, 0, -1 }, 0.1)) do
    for _, d in ipairs(dets) do
      local row = { frame, d.id }
      for _, c in ipairs(d.corners) do row[#row + 1] = ("%.6f,%.6f"):format(c[1], c[2]) end
      lines[#lines + 1] = table.concat(row, ",")
    end
  end
  os.execute("mkdir -p " .. run.quote(dir .. "/cube"))
  run.write(dir .. "/cube/corners.csv", table.concat(lines, "\n") .. "\n")
  run.write(dir .. "/cube/camera.lua", ("return { fx = %.17g, fy = %.17g, cx = %.17g,"
    .. " cy = %.17g }\n"):format(camera.fx, camera.fy, camera.cx, camera.cy))
  assert(tagpose.layout.write(dir .. "/cube/nominal.csv", nominal))
  run.run("cd " .. run.quote(dir) .. " && ln -sf log.csv link.csv && ln -f log.csv hard.csv"
    .. " && ln -sf ../camera.lua cube/link.lua")
end

local INPUTS = { "log.csv", "camera.lua", "truth.csv", "cube/corners.csv", "cube/camera.lua",
  "cube/nominal.csv" }

local function snapshot()
  local out = {}
  for _, name in ipairs(INPUTS) do out[name] = run.read(dir .. "/" .. name) end
  return out
end

-- a command run in dir: its output (stdout and stderr) and status
local function command(script, args)
  local parts = { "cd", run.quote(dir), "&&", run.quote(run.lua()),
    run.quote(os.getenv("PWD") .. "/" .. script) }
  for a in args:gmatch("%S+") do parts[#parts + 1] = run.quote(a) end
  return run.run(table.concat(parts, " ") .. " 2>&1")
end

describe("tagpose-replay and tagpose-calibrate", function()
  setup()
  local before = snapshot()

  it("refuse an output that is one of their inputs under any name, and touch nothing", function()
    local cases = {
      { REPLAY, "log.csv --out log.csv", "the pose log %(%-%-out%) log.csv is the corner log" },
      { REPLAY, "log.csv --out ./log.csv", "is the corner log log.csv" },
      { REPLAY, "./log.csv --svg log.csv", "the plot %(%-%-svg%) log.csv is the corner log" },
      { REPLAY, "log.csv --out link.csv", "link.csv is the corner log log.csv" },
      { REPLAY, "log.csv --out hard.csv", "hard.csv is the corner log log.csv" },
      { REPLAY, "link.csv --out hard.csv", "hard.csv is the corner log link.csv" },
      { REPLAY, "log.csv --out camera.lua", "is the camera file ./camera.lua" },
      { REPLAY, "log.csv --camera cube/link.lua --svg camera.lua", "is the camera file" },
      { REPLAY, "log.csv --compare truth.csv --out truth.csv", "is the compared log" },
      { REPLAY, "log.csv --compare x.csv truth.csv --svg ./truth.csv", "is the compared log" },
      { REPLAY, "log.csv --out new.csv --svg new.csv", "new.csv is also the plot" },
      { CALIBRATE, "cube/corners.csv --cube 0.0229,0.0548 --out cube/corners.csv",
        "the calibrated layout %(%-%-out%) cube/corners.csv is the corner log" },
      { CALIBRATE, "cube/corners.csv --layout cube/nominal.csv --out cube/./nominal.csv",
        "is the nominal layout" },
      { CALIBRATE, "cube/corners.csv --cube 0.0229,0.0548 --out cube/camera.lua",
        "is the camera file" },
    }
    for _, c in ipairs(cases) do
      local text, status = command(c[1], c[2])
      assert.equal(2, status, c[2] .. ": " .. text)
      assert.matches(c[3], text, 1, false, c[2])
      assert.matches("give another file", text)
      assert.same(before, snapshot(), c[2])
    end
    assert.is_nil(io.open(dir .. "/new.csv"))
  end)

  it("find an output they cannot write before they read anything", function()
    -- the camera file is broken: the output is what they complain of
    run.write(dir .. "/broken.lua", "return {")
    local cases = {
      { REPLAY, "log.csv --camera broken.lua --out missing/p.csv", "missing/p.csv: No such file" },
      { REPLAY, "log.csv --camera broken.lua --svg .", ".: Is a directory" },
      { CALIBRATE, "cube/corners.csv --camera broken.lua --cube 0.0229,0.0548 --out missing/l.csv",
        "missing/l.csv: No such file" },
    }
    for _, c in ipairs(cases) do
      local text, status = command(c[1], c[2])
      assert.equal(1, status, c[2] .. ": " .. text)
      assert.matches(c[3], text, 1, true, c[2])
    end
    local text, status = command(CALIBRATE, "cube/corners.csv --cube 0.0229,0.0548 --out l.txt")
    assert.equal(2, status, text)
    assert.matches("%-%-out: l.txt: %.lua, %.yaml, %.yml or %.csv expected", text)
    assert.same(before, snapshot())
  end)

  it("end with status 1 and say so when standard output cannot be written", function()
    if not io.open("/dev/full", "w") then return end -- Linux, the BSDs
    local cases = { { REPLAY, "log.csv" }, { REPLAY, "log.csv --out -" },
      { REPLAY, "log.csv --out p.csv --svg p.svg" }, { REPLAY, "--help" },
      { CALIBRATE, "cube/corners.csv --layout cube/nominal.csv" }, { CALIBRATE, "--help" } }
    for _, c in ipairs(cases) do
      local parts = { "cd", run.quote(dir), "&&", run.quote(run.lua()),
        run.quote(os.getenv("PWD") .. "/" .. c[1]) }
      for a in c[2]:gmatch("%S+") do parts[#parts + 1] = run.quote(a) end
      local text, status = run.run(table.concat(parts, " ") .. " 2>&1 >/dev/full")
      assert.equal(1, status, c[2] .. ": " .. text)
      assert.matches("standard output: No space left on device", text, 1, true)
    end
  end)
end)

describe("tagpose.tools.files", function()
  describe("clash()", function()
    it("tells one file under two names, without the system's stat too", function()
      run.write(dir .. "/copy.csv", run.read(dir .. "/log.csv"))
      local log = { { name = "the log", path = dir .. "/log.csv" } }
      for _, options in ipairs({ {}, { stat = false } }) do
        for _, name in ipairs({ "log.csv", "./log.csv", "link.csv", "hard.csv", "x/../log.csv" }) do
          local why = files.clash(log, { { name = "--out", path = dir .. "/" .. name } }, options)
          assert.is_string(why, name)
        end
        assert.is_nil(files.clash(log, { { name = "--out", path = dir .. "/other.csv" } }, options))
        assert.is_nil(files.clash(log, { { name = "--out", path = dir .. "/truth.csv" } }, options))
      end
      -- without stat, a copy byte for byte cannot be told from the file: refused, and named so
      assert.is_nil(files.clash(log, { { name = "--out", path = dir .. "/copy.csv" } }))
      assert.matches("or a copy of it", files.clash(log,
        { { name = "--out", path = dir .. "/copy.csv" } }, { stat = false }))
    end)
  end)
end)
