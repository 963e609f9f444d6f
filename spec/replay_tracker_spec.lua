-- tagpose-replay is a user of tagpose.tracker: its poses are those of a user's own loop over the
-- tracker (bit for bit: the pose logs' lines are compared as text, every number written with
-- 17 digits), its smoothing is the tracker's, and what it says of time is what the tracker
-- warns of. Run with the Lua that runs the specs.
local tagpose = require("tagpose")
local log = require("tagpose.tools.log")
local slots = require("tagpose.tools.replay.slots")
local run = require("support.run")

local function tmp(name)
  local base = os.tmpname() -- created: take its unique name only
  os.remove(base)
  return base .. "-" .. name
end

-- a small synthetic draw of bench/make_sequences.lua: corners.csv (with a time column),
-- truth.csv, camera.lua
local function draw(name, ...)
  local dir = tmp(name)
  local text, status = run.script("bench/make_sequences.lua", dir, ...)
  assert.equal(0, status, text)
  return dir
end

-- a corner log's text with its rows (after the header) rewritten by f(fields) -> fields|nil
local function rewrite(path, out, f)
  local lines = {}
  for line in run.read(path):gmatch("[^\n]+") do
    if #lines == 0 then
      lines[1] = f(nil, line) or line
    else
      local fields = {}
      for v in line:gmatch("[^,]+") do fields[#fields + 1] = v end
      fields = f(fields)
      if fields then lines[#lines + 1] = table.concat(fields, ",") end
    end
  end
  return run.write(out, table.concat(lines, "\n") .. "\n")
end

-- a user's loop: the log's rows fed frame by frame (consecutive rows of one frame) to a
-- tracker with the frame's time (its time column, else frame / fps); the pose-log lines
-- (the smoothed choice with `smooth`), and the poses
local function loop(dir, corners, options)
  options = options or {}
  local camera, info = log.read_camera(dir .. "/camera.lua")
  local rows = assert(log.read_corners(corners))
  local tr = tagpose.tracker.new(camera, info.tag_size, { smooth = options.smooth,
    sigma = options.sigma, max_gap = options.max_gap })
  local poses, i = {}, 1
  while i <= #rows do
    local frame, j = {}, i
    while j <= #rows and rows[j].frame == rows[i].frame do
      frame[#frame + 1] = { id = rows[j].tag, corners = rows[j].corners }
      j = j + 1
    end
    local seen = tr:update(frame, rows[i].time or rows[i].frame / (options.fps or 30))
    for k = 1, #seen do poses[i + k - 1] = seen[k].pose or false end
    i = j
  end
  local choice, confidence
  if options.smooth then choice, confidence = tr:smooth() end
  local lines = {}
  for r, row in ipairs(rows) do
    local pose, conf = poses[r] or nil, nil
    if choice and choice[r] > 0 then
      if choice[r] == 2 then pose = pose.alternative end
      conf = confidence[r]
    end
    lines[r] = log.pose_line(row.frame, row.tag, pose, conf)
  end
  return lines, rows
end

-- tagpose-replay's pose log (its lines after the header) and summary
local function replay(corners, ...)
  local out = tmp("poses.csv")
  local text, status = run.script("bin/tagpose-replay", corners, "--out", out, ...)
  assert.equal(0, status, text)
  local lines = {}
  for line in run.read(out):gmatch("[^\n]+") do lines[#lines + 1] = line end
  os.remove(out)
  table.remove(lines, 1)
  return lines, text
end

local function same_lines(expected, got, what)
  assert.equal(#expected, #got, what)
  for r = 1, #expected do assert.equal(expected[r], got[r], what .. ", row " .. r) end
end

describe("tagpose-replay --track", function()
  local dirs = {}
  setup(function()
    -- three id-0 tags in view at once; jitter and missed frames (gaps in time)
    dirs.crowd = draw("crowd", "3", "61", "--tags", "3", "--frames", "40", "--camera", "random")
    dirs.gaps = draw("gaps", "4", "62", "--frames", "60", "--jitter", "0.3", "--drop", "0.1",
      "--kinds", "far_wobble,orbit,approach,far_hover")
  end)
  teardown(function()
    for _, dir in pairs(dirs) do run.run("rm -r " .. run.quote(dir)) end
  end)

  it("gives a user's loop's poses over tagpose.tracker, bit for bit", function()
    for _, name in ipairs({ "crowd", "gaps" }) do
      local corners = dirs[name] .. "/corners.csv"
      local expected, rows = loop(dirs[name], corners)
      assert.is_true(#rows >= 150, name .. ": " .. #rows .. " rows")
      same_lines(expected, (replay(corners, "--track")), name)
    end
  end)

  it("feeds the frames' times as the log gives them: out of order, and frame / --fps", function()
    -- the gaps log with its sequences 1 and 2 swapped (the time goes back twice), and without
    -- its time column (frame numbers at 10 per second)
    local swapped = dirs.gaps .. "/swapped.csv"
    local rows, head = {}, nil
    rewrite(dirs.gaps .. "/corners.csv", swapped, function(fields, header)
      if header then head = header return nil end
      rows[#rows + 1] = table.concat(fields, ",")
    end)
    table.sort(rows, function(a, b)
      local fa, fb = tonumber(a:match("^[^,]+")), tonumber(b:match("^[^,]+"))
      local sa, sb = math.floor(fa / 1000), math.floor(fb / 1000)
      local ka = sa == 1 and 2 or sa == 2 and 1 or sa
      local kb = sb == 1 and 2 or sb == 2 and 1 or sb
      if ka ~= kb then return ka < kb end
      return fa < fb
    end)
    run.write(swapped, head .. "\n" .. table.concat(rows, "\n") .. "\n")
    local expected = loop(dirs.gaps, swapped)
    local got, text = replay(swapped, "--track")
    same_lines(expected, got, "out of order")
    assert.matches("restarts   %d+ times? the time went back %(first at line %d+%): the tracker"
      .. " ended every track there", text)
    local untimed = rewrite(swapped, dirs.gaps .. "/untimed.csv", function(fields, header)
      if header then return (header:gsub(",time$", "")) end
      fields[#fields] = nil
      return fields
    end)
    expected = loop(dirs.gaps, untimed, { fps = 10 })
    got, text = replay(untimed, "--track", "--fps", "10")
    same_lines(expected, got, "--fps 10")
    assert.truthy(text:find("  time   frame / 10 (frames per second, --fps; the log has no time"
      .. " column)", 1, true), text)
    os.remove(swapped)
    os.remove(untimed)
  end)

  it("smooths as tracker:smooth() does, and takes --sigma and --max-gap to the tracker", function()
    local corners = dirs.gaps .. "/corners.csv"
    local expected = loop(dirs.gaps, corners, { smooth = true, sigma = 0.7, max_gap = 0.2 })
    local got, text = replay(corners, "--smooth", "--sigma", "0.7", "--max-gap", "200ms")
    same_lines(expected, got, "--smooth")
    assert.truthy(text:find("tracked by tagpose.tracker (a track ends unseen for more than"
      .. " 0.2 s), smoothed over the whole log", 1, true), text)
    assert.truthy(text:find("  sigma  0.7 px (--sigma)", 1, true), text)
    local switched = tonumber(text:match("smoothed   (%d+) rows take the other pose"))
    local differ = 0
    for r, line in ipairs(replay(corners, "--track", "--sigma", "0.7", "--max-gap", "0.2s")) do
      if line:match("^[^,]*,[^,]*,[^,]*") ~= got[r]:match("^[^,]*,[^,]*,[^,]*") then
        differ = differ + 1
      end
    end
    assert.equal(differ, switched)
  end)

  it("solves each row alone without --track: tagpose.solve's poses", function()
    local corners = dirs.crowd .. "/corners.csv"
    local camera, info = log.read_camera(dirs.crowd .. "/camera.lua")
    local expected = {}
    for r, row in ipairs(assert(log.read_corners(corners))) do
      expected[r] = log.pose_line(row.frame, row.tag,
        tagpose.solve(row.corners, camera, info.tag_size))
    end
    local got, text = replay(corners)
    same_lines(expected, got, "no --track")
    assert.truthy(text:find("each row solved alone", 1, true), text)
  end)

  it("estimates σ from the log's residuals", function()
    -- the draws' corners carry 0.5 px of noise
    for _, name in ipairs({ "crowd", "gaps" }) do
      local _, text = replay(dirs[name] .. "/corners.csv", "--track")
      local sigma = tonumber(text:match("noise      sigma ([%d.]+) px, from the median"))
      assert.is_true(sigma > 0.42 and sigma < 0.58, name .. ": " .. tostring(sigma))
    end
  end)
end)

describe("tagpose-replay and time", function()
  local dir
  setup(function() dir = draw("time", "2", "63", "--frames", "60", "--kinds", "orbit") end)
  teardown(function() run.run("rm -r " .. run.quote(dir)) end)

  it("points out a time column in milliseconds, and seconds in the frame column", function()
    local ms = rewrite(dir .. "/corners.csv", dir .. "/ms.csv", function(fields)
      if fields then fields[#fields] = ("%.17g"):format(1000 * tonumber(fields[#fields])) end
      return fields
    end)
    local text, status = run.script("bin/tagpose-replay", ms, "--track")
    assert.equal(0, status, text)
    assert.matches("replay: warning: line %d+: the time column steps by 33%.33, steadily, far"
      .. " beyond the tracker's max gap %(0%.5 s%): every frame starts new tracks%. The time"
      .. " column is in seconds: are these milliseconds, or frame numbers%?", text)
    assert.matches("\ntime       %d+ frames step far beyond the max gap at a steady cadence", text)
    -- the frame column holding seconds (and no time column)
    local seconds = rewrite(dir .. "/corners.csv", dir .. "/seconds.csv", function(fields, head)
      if head then return (head:gsub(",time$", "")) end
      fields[1] = table.remove(fields)
      return fields
    end)
    text, status = run.script("bin/tagpose-replay", seconds, "--track")
    assert.equal(0, status, text)
    assert.matches("replay: warning: line 3: frame 0%.03333 is not a whole number: seconds in"
      .. " the frame column%?", text)
    assert.matches("\nframes     %d+ rows have a fractional frame number %(first at line 3%)", text)
    -- frame numbers that count milliseconds
    local counted = rewrite(seconds, dir .. "/counted.csv", function(fields)
      if fields then fields[1] = ("%.0f"):format(1000 * tonumber(fields[1])) end
      return fields
    end)
    text = run.script("bin/tagpose-replay", counted)
    assert.matches("the frame numbers step by 3[34], 1%.1%d* s at 30 frames per second %(%-%-fps%)",
      text)
  end)

  it("names a missing corner log first, and refuses --max-gap without its unit", function()
    local text, status = run.script("bin/tagpose-replay", "/nonexistent/corners.csv", "--track")
    assert.equal(1, status)
    assert.equal("replay: log: /nonexistent/corners.csv: No such file or directory\n", text)
    text, status = run.script("bin/tagpose-replay", dir .. "/corners.csv", "--max-gap", "3")
    assert.equal(2, status)
    assert.truthy(text:find("replay: --max-gap: a time with its unit (0.5s, 500ms) expected,"
      .. " got 3 (a bare number counted frames before; the tracker's gap is in seconds: 3"
      .. " frames at 30 fps are --max-gap 0.1s)", 1, true), text)
    for _, bad in ipairs({ { "--fps", "0" }, { "--sigma", "-1" }, { "--max-gap", "1h" } }) do
      text, status = run.script("bin/tagpose-replay", dir .. "/corners.csv", bad[1], bad[2])
      assert.equal(2, status, text)
    end
  end)
end)

describe("tagpose.tools.replay.slots", function()
  it("keeps a line per tag in view, reused once its track has ended", function()
    local set = slots.new(0.5)
    assert.equal(1, slots.slot(set, 0, 1, 0))
    assert.equal(2, slots.slot(set, 0, 2, 0))
    assert.equal(1, slots.slot(set, 7, 3, 0))
    assert.equal(1, slots.slot(set, 0, 1, 0.4))
    -- track 2 unseen for 0.6 s: ended; track 4 takes its line, track 5 a new one
    assert.equal(2, slots.slot(set, 0, 4, 0.6))
    assert.equal(3, slots.slot(set, 0, 5, 0.6))
    slots.clear(set)
    assert.equal(1, slots.slot(set, 0, 6, 0))
  end)

  it("keeps at most MAX slots however many ids come", function()
    local set = slots.new(0.5)
    for id = 1, 5 * slots.MAX do slots.slot(set, id, id, id / 1e6) end
    -- (a sweep every MAX new slots leaves at most MAX: never more than twice that)
    assert.is_true(set.count <= 2 * slots.MAX, set.count)
    assert.is_true(set.forgotten > 0)
  end)
end)
