-- tagpose-localize as a user runs it: the development drive log's first 12 s replayed against
-- its truth file (the robot's true pose from the log's generator), the map check finding the
-- tag the hard log's map puts elsewhere, and every refusal: a camera the cameras file lacks,
-- times that go back, a cell that is not a number, a sensor that stopped, an output that is an
-- input. Nothing written when the command fails.
local run = require("support.run")

local sqrt, atan2 = math.sqrt, require("tagpose.core.compat").atan2
local unpack = table.unpack or unpack -- luacheck: ignore

local dir = run.tmpdir()

-- The first `seconds` of a log's CSV (header kept), into the scratch folder.
local function cut(src, name, seconds)
  local lines = {}
  local first = true
  for line in io.lines(src .. "/" .. name) do
    local t = tonumber(line:match("^([^,]*)"))
    if first or (t and t < seconds) then lines[#lines + 1] = line end
    first = false
  end
  return run.write(dir .. "/" .. name, table.concat(lines, "\n") .. "\n")
end

local function copy(src, name)
  return run.write(dir .. "/" .. name, run.read(src .. "/" .. name))
end

local function localize(...)
  return run.script("bin/tagpose-localize", ...)
end

local function rows(path)
  local out, header = {}, nil
  for line in io.lines(path) do
    local f = {}
    for v in (line .. ","):gmatch("([^,]*),") do f[#f + 1] = v end
    if not header then
      header = {}
      for i, h in ipairs(f) do header[h] = i end
    else
      local r = {}
      for h, i in pairs(header) do r[h] = f[i] end
      out[#out + 1] = r
    end
  end
  return out
end

local function yaw_of(r)
  local w, x, y, z = tonumber(r.qw), tonumber(r.qx), tonumber(r.qy), tonumber(r.qz)
  return atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
end

describe("tagpose-localize", function()
  local src = "bench/dev/drive_hard"
  local inputs = {}
  for _, name in ipairs({ "corners.csv", "odometry.csv", "gyro.csv", "truth.csv" }) do
    inputs[name] = cut(src, name, 12)
  end
  inputs["map.json"] = copy(src, "map.json")
  inputs["cameras.lua"] = copy(src, "cameras.lua")
  local function base(out)
    return inputs["corners.csv"], "--map", inputs["map.json"], "--cameras",
      inputs["cameras.lua"], "--odometry", inputs["odometry.csv"], "--gyro", inputs["gyro.csv"],
      "--out", out
  end

  -- the run both cases read (once: the map check changes no pose)
  local poses, check = dir .. "/poses.csv", dir .. "/check.csv"
  local ran
  local function localized()
    if not ran then
      local args = { base(poses) }
      args[#args + 1] = "--map-check"
      args[#args + 1] = check
      ran = { localize(unpack(args)) }
    end
    assert.equal(0, ran[2], ran[1])
  end

  it("places the robot of the hard log within centimetres of the truth, every frame", function()
    localized()
    local truth = {}
    for _, r in ipairs(rows(inputs["truth.csv"])) do truth[r.time] = r end
    local frames = {}
    for _, r in ipairs(rows(inputs["corners.csv"])) do frames[r.time .. r.camera] = true end
    local n_frames = 0
    for _ in pairs(frames) do n_frames = n_frames + 1 end
    local errors, yaw_errors, n = {}, {}, 0
    for _, r in ipairs(rows(poses)) do
      local t = truth[r.time]
      assert.is_truthy(t, "a row at a time the truth has: " .. r.time)
      n = n + 1
      errors[n] = sqrt((tonumber(r.x) - tonumber(t.x)) ^ 2 + (tonumber(r.y) - tonumber(t.y)) ^ 2)
      local d = (yaw_of(r) - yaw_of(t) + math.pi) % (2 * math.pi) - math.pi
      yaw_errors[n] = math.abs(d)
    end
    assert.equal(n_frames, n)
    table.sort(errors)
    table.sort(yaw_errors)
    local median, p95 = errors[math.floor(n / 2)], errors[math.floor(0.95 * n)]
    assert.is_true(median < 0.02 and p95 < 0.06 and errors[n] < 0.5,
      ("median %.4f, p95 %.4f, max %.4f m"):format(median, p95, errors[n]))
    assert.is_true(yaw_errors[math.floor(0.95 * n)] < math.rad(1))
  end)

  -- (the whole log's map check, the moved tag first within 4 cm of its move, is bench/drive.sh's:
  -- bench/map_check.lua; here the first 12 s, the file's form)
  it("writes the map check: every tag seen, largest move first, each with its frames", function()
    localized()
    local c = rows(check)
    local seen = {}
    for _, r in ipairs(rows(inputs["corners.csv"])) do seen[r.tag] = true end
    local n = 0
    for _ in pairs(seen) do n = n + 1 end
    assert.is_true(#c >= n - 1 and #c <= n, #c .. " rows for " .. n .. " tags seen")
    for k, r in ipairs(c) do
      local dx, dy, dz = tonumber(r.dx), tonumber(r.dy), tonumber(r.dz)
      assert.near(sqrt(dx * dx + dy * dy + dz * dz), tonumber(r.distance), 1e-3)
      assert.is_true(tonumber(r.frames) >= 1)
      if k > 1 then assert.is_true(tonumber(r.distance) <= tonumber(c[k - 1].distance)) end
    end
  end)

  local function refused(args, pattern, status)
    local out = args.out
    local text, got = localize(unpack(args))
    assert.equal(status or 1, got, text)
    assert.matches(pattern, text)
    assert.is_nil(io.open(out, "r"), "nothing written at " .. out)
  end

  local function variant(name, edit)
    local lines = {}
    for line in io.lines(inputs[name]) do lines[#lines + 1] = line end
    edit(lines)
    return run.write(dir .. "/bad_" .. name, table.concat(lines, "\n") .. "\n")
  end

  it("refuses a camera the cameras file lacks, naming the file and line", function()
    local bad = variant("corners.csv", function(l) l[5] = l[5]:gsub(",front,", ",side,") end)
    local out = dir .. "/none1.csv"
    refused({ bad, "--map", inputs["map.json"], "--cameras", inputs["cameras.lua"],
      "--out", out, out = out }, "bad_corners%.csv:5: camera \"side\" is not in the cameras file")
  end)

  it("refuses times that go back, and a cell that is not a number", function()
    local back = variant("gyro.csv", function(l) l[10], l[11] = l[11], l[10] end)
    local out = dir .. "/none2.csv"
    refused({ inputs["corners.csv"], "--map", inputs["map.json"], "--cameras",
      inputs["cameras.lua"], "--gyro", back, "--out", out, out = out },
      "bad_gyro%.csv:11: time [%d.]+ goes back")
    local nan = variant("odometry.csv", function(l) l[7] = l[7]:gsub(",[^,]*$", ",nan") end)
    refused({ inputs["corners.csv"], "--map", inputs["map.json"], "--cameras",
      inputs["cameras.lua"], "--odometry", nan, "--out", out, out = out },
      "bad_odometry%.csv:7: yaw: a finite number expected")
  end)

  it("refuses a gyro that stopped for more than --max-gap, and takes it with a larger one",
    function()
      local gap = variant("gyro.csv", function(l)
        for i = #l, 2, -1 do
          local t = tonumber(l[i]:match("^([^,]*)"))
          if t > 5 and t < 6.5 then table.remove(l, i) end
        end
      end)
      local out = dir .. "/none3.csv"
      refused({ inputs["corners.csv"], "--map", inputs["map.json"], "--cameras",
        inputs["cameras.lua"], "--gyro", gap, "--out", out, out = out },
        "bad_gyro%.csv:%d+: a gap of 1%.5 s after time 5")
      -- (the frames of the first 7 s: across the gap)
      local early = variant("corners.csv", function(l)
        for i = #l, 2, -1 do
          if tonumber(l[i]:match("^([^,]*)")) >= 7 then table.remove(l, i) end
        end
      end)
      local text, status = localize(early, "--map", inputs["map.json"], "--cameras",
        inputs["cameras.lua"], "--gyro", gap, "--max-gap", "2", "--out", out)
      assert.equal(0, status, text)
    end)

  it("takes the mounts' and the map's sigmas with their units: the defaults given change no "
    .. "byte, 0 narrows the rows, a bare number is refused", function()
    localized()
    local same, zero = dir .. "/same.csv", dir .. "/zero.csv"
    local function with(out, p, a, m)
      local args = { base(out) }
      for _, v in ipairs({ "--mount-position-sigma", p, "--mount-angle-sigma", a, "--map-sigma",
        m }) do
        args[#args + 1] = v
      end
      local text, status = localize(unpack(args))
      assert.equal(0, status, text)
    end
    with(same, "10mm", "0.5deg", "0.01m")
    assert.equal(run.read(poses), run.read(same))
    with(zero, "0", "0rad", "0")
    local a, b = rows(poses), rows(zero)
    assert.equal(#a, #b)
    local narrower = 0
    for i = 1, #a do
      local sa, sb = tonumber(a[i].sx) ^ 2 + tonumber(a[i].sy) ^ 2,
        tonumber(b[i].sx) ^ 2 + tonumber(b[i].sy) ^ 2
      if sb < 0.9 * sa then narrower = narrower + 1 end
    end
    -- (the sigmas also weigh the frames in the filter, so a row may widen; most narrow)
    assert.is_true(narrower > 0.8 * #a, narrower .. " of " .. #a .. " rows narrower")
    local out = dir .. "/none_sigma.csv"
    local args = { base(out) }
    args[#args + 1], args[#args + 2] = "--mount-angle-sigma", "0.5"
    args.out = out
    refused(args, "%-%-mount%-angle%-sigma: an angle with its unit", 2)
    args[#args - 1], args[#args] = "--map-sigma", "10"
    refused(args, "%-%-map%-sigma: a length with its unit", 2)
  end)

  it("refuses an output that is an input (status 2)", function()
    local text, status = localize(inputs["corners.csv"], "--map", inputs["map.json"],
      "--cameras", inputs["cameras.lua"], "--out", inputs["map.json"])
    assert.equal(2, status, text)
    assert.matches("the map", text, 1, true)
  end)
end)
