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

  it("write through a device, a FIFO or a pipe, in place, and replace none of them", function()
    -- (the devices through links in dir: a command that renamed over them replaces the link)
    local has = select(2, run.run("command -v timeout >/dev/null && command -v mkfifo"
      .. " >/dev/null")) == 0
    if not has then return end
    run.run("cd " .. run.quote(dir) .. " && rm -f null.csv plot.fifo && ln -s /dev/null null.csv"
      .. " && mkfifo plot.fifo")
    -- the pose log into a link to /dev/null, the plot into a FIFO read by cat
    local text, status = run.run("cd " .. run.quote(dir) .. " && { timeout 20 cat plot.fifo"
      .. " > plot.svg & timeout 20 " .. run.quote(run.lua()) .. " "
      .. run.quote(os.getenv("PWD") .. "/" .. REPLAY)
      .. " log.csv --out null.csv --svg plot.fifo 2>&1; wait; }")
    assert.equal(0, status, text)
    assert.matches("wrote null.csv (377 rows)", text, 1, true)
    assert.matches("wrote plot.fifo (", text, 1, true)
    assert.matches("</svg>", run.read(dir .. "/plot.svg"), 1, true)
    local _, kinds = run.run("cd " .. run.quote(dir) .. " && test -L null.csv && test -p plot.fifo")
    assert.equal(0, kinds, "a link or the FIFO replaced by a file")
    -- the pose log into a pipe (/dev/fd/3), the summary apart
    text, status = run.run("cd " .. run.quote(dir) .. " && { timeout 20 " .. run.quote(run.lua())
      .. " " .. run.quote(os.getenv("PWD") .. "/" .. REPLAY) .. " log.csv --out /dev/fd/3"
      .. " 3>&1 >summary.txt 2>&1; } | wc -l")
    assert.equal(0, status, text)
    assert.equal(378, tonumber(text), text)
    -- the calibrated layout into a link to /dev/null
    text, status = command(CALIBRATE, "cube/corners.csv --cube 0.0229,0.0548 --out null.csv")
    assert.equal(0, status, text)
    assert.matches("wrote null.csv", text, 1, true)
    _, kinds = run.run("test -L " .. run.quote(dir .. "/null.csv"))
    assert.equal(0, kinds, "the link replaced by a file")
    -- and the library's layout.write
    run.run("cd " .. run.quote(dir) .. " && ln -sf /dev/null null.lua")
    assert.is_true(tagpose.layout.write(dir .. "/null.lua", assert(tagpose.layout.read(dir
      .. "/cube/nominal.csv"))))
    _, kinds = run.run("test -L " .. run.quote(dir .. "/null.lua"))
    assert.equal(0, kinds, "the link replaced by a file")
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

  it("end by SIGPIPE on a closed pipe, or with status 1 and a message where it is ignored",
    function()
      -- Lua cannot ignore SIGPIPE: a reader that has gone (`| head`) ends a command as it ends
      -- any Unix filter, status 141 in the shell; where SIGPIPE is ignored (`trap '' PIPE`, a
      -- parent that ignores it) the write fails instead, and that is status 1 and a message
      local cases = { { REPLAY, "log.csv" }, { REPLAY, "log.csv --out -" },
        { CALIBRATE, "cube/corners.csv --layout cube/nominal.csv" } }
      local jobs, scripts = {}, {}
      for _, c in ipairs(cases) do
        local parts = { run.quote(run.lua()), run.quote(os.getenv("PWD") .. "/" .. c[1]) }
        for a in c[2]:gmatch("%S+") do parts[#parts + 1] = run.quote(a) end
        for _, ignored in ipairs({ false, true }) do
          local i = #jobs + 1
          jobs[i] = { name = c[2] .. (ignored and " (SIGPIPE ignored)" or ""), ignored = ignored }
          -- the reader (`true`) is gone before the command writes
          local script = (ignored and "trap '' PIPE; " or "") .. "{ sleep 0.2; "
            .. table.concat(parts, " ") .. " 2>err" .. i .. ".txt; echo $? >status" .. i
            .. ".txt; } | true"
          scripts[i] = "sh -c " .. run.quote(script) .. " &"
        end
      end
      -- all at once (their sleeps overlap), each with its own files
      run.run("cd " .. run.quote(dir) .. " && { " .. table.concat(scripts, " ") .. " wait; }")
      for i, job in ipairs(jobs) do
        local status = tonumber(run.read(dir .. "/status" .. i .. ".txt"))
        local said = run.read(dir .. "/err" .. i .. ".txt")
        if job.ignored or status ~= 141 then
          assert.equal(1, status, job.name .. ": " .. said)
          assert.matches(": standard output: Broken pipe\n$", said, 1, false, job.name)
        else
          assert.equal("", said, job.name)
        end
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
