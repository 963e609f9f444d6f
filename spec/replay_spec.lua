-- bin/tagpose-replay end to end, run with the Lua that runs the specs; and the bundled data.
local log = require("tagpose.tools.log")
local run = require("support.run")

local sqrt = math.sqrt

local LOG = "examples/data/approach.csv"
local TRUTH = "examples/data/approach_truth.csv"

local function tmp(name)
  local base = os.tmpname() -- created: take its unique name only
  os.remove(base)
  return base .. "-" .. name
end

-- a corner log with one row of every kind (the comments say which)
local MIXED = table.concat({
  "# recorded on the robot",
  "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,score",
  "1,7,280,280,360,280,360,200,280,200,0.9", -- line 3: solved
  "",
  "2,7,1,2,3", -- line 5: malformed, too few fields
  "4,7,10,10,20,20,30,30,40,40,0.5", -- line 6: fails, collinear
  "5,7,280,280,360,280,360,abc,280,200,1", -- line 7: malformed, not a number
  "6,8,1e999,280,360,280,360,200,280,200,1", -- line 8: fails, not finite
  "7,7,282,280,362,280,362,200,282,200,1", -- line 9: solved
}, "\n") .. "\n"
local CAMERA = "return { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, tag_size = 0.024 }\n"

-- position and rotation differences (m, deg) of the rows of two pose logs, row by row
local function differences(a, b)
  local dt, dr = {}, {}
  for i = 1, #a do
    local p, q = a[i].pose, b[i].pose
    local pp, qp = p.position, q.position
    dt[i] = sqrt((pp.x - qp.x) ^ 2 + (pp.y - qp.y) ^ 2 + (pp.z - qp.z) ^ 2)
    local u, v = p.quaternion, q.quaternion
    local dot = math.abs(u.w * v.w + u.x * v.x + u.y * v.y + u.z * v.z)
    dr[i] = math.deg(2 * math.acos(math.min(1, dot)))
  end
  table.sort(dt)
  table.sort(dr)
  return dt, dr
end

describe("bin/tagpose-replay", function()
  it("replays the bundled approach: a pose per row, in order, near the truth", function()
    local out, svg = tmp("poses.csv"), tmp("plot.svg")
    local text, status = run.script("bin/tagpose-replay", LOG, "--track", "--out", out,
      "--svg", svg, "--compare", TRUTH)
    local rows = assert(log.read_corners(LOG))
    local poses, problems = log.read_poses(out)
    local figure = run.read(svg)
    os.remove(out)
    os.remove(svg)
    assert.equal(0, status, text)
    assert.same({}, problems)
    assert.equal(#rows, #poses)
    for i = 1, #rows do
      assert.same({ rows[i].frame, rows[i].tag }, { poses[i].frame, poses[i].tag }, "row " .. i)
    end
    -- the summary
    assert.truthy(text:find("rows       " .. #rows .. " (2 tags: 1, 2; frames 0 to 199)", 1,
      true), text)
    assert.truthy(text:find("failed     0\n", 1, true), text)
    assert.truthy(text:find("malformed  0\n", 1, true), text)
    assert.truthy(text:find("median reprojection error 0%.%d+ px, median solveQuad iterations"),
      text)
    assert.truthy(text:find("vs " .. TRUTH .. ": " .. #rows .. " rows matched", 1, true), text)
    -- within the noise of 0.25 px on tags of 10 to 75 px: a few mm, a few degrees
    local truth = assert(log.read_poses(TRUTH))
    local dt, dr = differences(poses, truth)
    local mt, mr = dt[math.floor(#dt / 2)], dr[math.floor(#dr / 2)]
    assert.is_true(mt < 0.004, "median position error " .. mt)
    assert.is_true(mr < 4, "median rotation error " .. mr)
    -- the last, near frames: within a millimetre
    assert.is_true(sqrt((poses[#poses].pose.position.z - truth[#truth].pose.position.z) ^ 2)
      < 0.001)
    -- the figure: valid, 7 panels of 2 tags x 2 logs and the confidence strip of the 2 tags
    assert.is_true(run.xmllint(figure))
    assert.truthy(figure:find('data-panels="8" data-series="30"', 1, true))
  end)

  it("tracks each tag with tagpose.tracker with --track or --max-gap", function()
    local truth = assert(log.read_poses(TRUTH))
    -- the 95th percentile of the rotation error, and the summary
    local function p95(...)
      local out = tmp("poses.csv")
      local text, status = run.script("bin/tagpose-replay", LOG, "--out", out, ...)
      local poses = assert(log.read_poses(out))
      os.remove(out)
      assert.equal(0, status, text)
      local _, dr = differences(poses, truth)
      return dr[math.floor(0.95 * #dr)], text
    end
    local untracked, text = p95()
    assert.truthy(text:find("method refined, each row solved alone", 1, true), text)
    local tracked
    tracked, text = p95("--track")
    assert.truthy(text:find("tracked by tagpose.tracker (a track ends unseen for more than 0.5"
      .. " s)", 1, true), text)
    -- far, small tags flip between the two solutions of the planar ambiguity: tracking
    -- keeps most of them on the right one
    assert.is_true(tracked < 0.5 * untracked, ("p95 %.3g deg tracked, %.3g untracked")
      :format(tracked, untracked))
    local gap
    gap, text = p95("--max-gap", "0.1s")
    assert.truthy(text:find("unseen for more than 0.1 s", 1, true), text)
    assert.is_true(gap < 0.5 * untracked)
  end)

  it("keeps failed rows with empty pose fields and reports every bad line", function()
    local dir = tmp("dir")
    assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
    local corners = run.write(dir .. "/corners.csv", MIXED)
    run.write(dir .. "/camera.lua", CAMERA)
    local text, status = run.script("bin/tagpose-replay", corners, "--out", "-")
    run.run("rm -r " .. run.quote(dir))
    assert.equal(0, status, text)
    -- the pose log (on stdout): the four readable rows, in order
    local csv = {}
    for line in text:gmatch("[^\n]+") do
      if line:match("^frame,") or line:match("^%d+,%d+,") then csv[#csv + 1] = line end
    end
    assert.equal("frame,tag,x,y,z,qw,qx,qy,qz,error,iterations,confidence,sx,sy,sz,srx,sry,srz",
      csv[1])
    assert.equal(5, #csv)
    assert.truthy(csv[2]:match("^1,7,[%d.e-]+,"))
    assert.equal("4,7,,,,,,,,,,,,,,,,", csv[3])
    assert.equal("6,8,,,,,,,,,,,,,,,,", csv[4])
    assert.truthy(csv[5]:match("^7,7,[%d.e-]+,"))
    -- the summary (on stderr)
    for _, expected in ipairs({
      "rows       4 (2 tags: 7, 8; frames 1 to 7)",
      "solved     2",
      "failed     2",
      "  line 6 (frame 4, tag 7): square: corners are collinear",
      "  line 8 (frame 6, tag 8): tagpose: corner 1 is not finite",
      "malformed  2 (skipped, not in the pose log)",
      "  line 5: 5 fields, header has 11",
      "  line 7: column v3 is not a number",
    }) do
      assert.truthy(text:find(expected, 1, true), "expected " .. expected .. " in\n" .. text)
    end
  end)

  it("takes the tag size from --tag-size over the camera file's", function()
    local out = tmp("poses.csv")
    local _, status = run.script("bin/tagpose-replay", LOG, "--tag-size", "0.048", "--out",
      out, "--method", "seed")
    local big = assert(log.read_poses(out))
    run.script("bin/tagpose-replay", LOG, "--camera", "examples/data/camera.lua", "--out", out,
      "--method", "seed")
    local small = assert(log.read_poses(out))
    os.remove(out)
    assert.equal(0, status)
    assert.near(2 * small[1].pose.position.z, big[1].pose.position.z, 1e-9)
  end)

  it("draws roll, pitch and yaw with --rpy", function()
    local svg = tmp("plot.svg")
    local text, status = run.script("bin/tagpose-replay", LOG, "--svg", svg, "--rpy")
    local figure = run.read(svg)
    os.remove(svg)
    assert.equal(0, status, text)
    assert.truthy(text:find("wrote " .. svg .. " (7 panels, 14 series: 2 tags x 1 log)", 1,
      true), text)
    assert.is_true(run.xmllint(figure))
    assert.truthy(figure:find('id="panel-yaw"', 1, true))
  end)

  it("refuses bad command lines and unreadable files with a message", function()
    local text, status = run.script("bin/tagpose-replay")
    assert.equal(2, status)
    assert.truthy(text:find("^usage: "), text)
    text, status = run.script("bin/tagpose-replay", LOG, "--bogus")
    assert.equal(2, status)
    assert.truthy(text:find("replay: unknown option --bogus", 1, true), text)
    -- a missing log is named as such before its camera file is looked for
    text, status = run.script("bin/tagpose-replay", "/nonexistent/corners.csv")
    assert.equal(1, status)
    assert.truthy(text:find("replay: log: /nonexistent/corners.csv", 1, true), text)
    local dir = tmp("nocamera")
    run.run("mkdir " .. run.quote(dir))
    run.write(dir .. "/corners.csv", MIXED)
    text, status = run.script("bin/tagpose-replay", dir .. "/corners.csv")
    run.run("rm -r " .. run.quote(dir))
    assert.equal(2, status)
    assert.truthy(text:find("no camera file", 1, true), text)
    text, status = run.script("bin/tagpose-replay", "/nonexistent/corners.csv", "--camera",
      "examples/data/camera.lua")
    assert.equal(1, status)
    assert.truthy(text:find("replay: log: /nonexistent/corners.csv", 1, true), text)
    text, status = run.script("bin/tagpose-replay", LOG, "--compare", "/nonexistent/truth.csv")
    assert.equal(1, status)
    assert.truthy(text:find("/nonexistent/truth.csv", 1, true), text)
  end)
end)

describe("bin/tagpose-replay on the inputs users have", function()
  local geometry = require("support.geometry")

  -- a corner log of known poses through a camera: rows {frame, tag, size} -> text and truth
  local function scene(camera, rows, seed)
    local rng = geometry.rng(seed)
    local lines, truth = { "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4" }, {}
    for _, row in ipairs(rows) do
      local r, t = geometry.random_pose(rng, camera, row[3], { width = 80, max_tilt = 0.7,
        u = rng.uniform(200, 440), v = rng.uniform(150, 330) })
      local c = assert(geometry.project(camera, r, t, row[3]))
      lines[#lines + 1] = ("%d,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g"):format(row[1],
        row[2], c[1][1], c[1][2], c[2][1], c[2][2], c[3][1], c[3][2], c[4][1], c[4][2])
      truth[#truth + 1] = t
    end
    return table.concat(lines, "\n") .. "\n", truth
  end

  local function replay_poses(...)
    local out = tmp("poses.csv")
    local text, status = run.script("bin/tagpose-replay", "--out", out, ...)
    local poses = status == 0 and assert(log.read_poses(out)) or nil
    os.remove(out)
    return poses, text, status
  end

  it("reads ROS camera_calibration YAML with --camera, its lens used", function()
    local camera = { fx = 615.925860, fy = 617.133667, cx = 320.578442, cy = 240.213862,
      distortion = { k1 = 0.111906, k2 = -0.173451, p1 = 0.002114, p2 = 0.000813, k3 = 0 } }
    local text, truth = scene(camera, { { 1, 3, 0.05 }, { 2, 3, 0.05 }, { 3, 4, 0.05 } }, 21)
    local path = run.write(tmp("corners.csv"), text)
    local poses, summary, status = replay_poses(path, "--camera",
      "spec/fixtures/calibration/ost.yaml", "--tag-size", "0.05")
    os.remove(path)
    assert.equal(0, status, summary)
    assert.truthy(summary:find("camera spec/fixtures/calibration/ost.yaml (ros): fx 615.926", 1,
      true), summary)
    assert.truthy(summary:find("Brown-Conrady lens k1 0.111906", 1, true), summary)
    for i, t in ipairs(truth) do
      assert.vector_near({ x = t[1], y = t[2], z = t[3] }, poses[i].pose.position, 1e-6)
    end
  end)

  it("takes per-id tag sizes from a Lua camera file, and OpenCV's distortion array", function()
    local camera = { fx = 700, fy = 700, cx = 319.5, cy = 239.5,
      distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0 } }
    local text, truth = scene(camera, { { 1, 3, 0.05 }, { 1, 7, 0.1 }, { 2, 3, 0.05 },
      { 2, 9, 0.1 }, { 3, 5, 0.02 } }, 22)
    local dir = tmp("dir")
    assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
    local path = run.write(dir .. "/corners.csv", text)
    run.write(dir .. "/camera.lua", "return { fx = 700, fy = 700, cx = 319.5, cy = 239.5,\n"
      .. "  distortion = { -0.28, 0.07, 5e-4, -3e-4, 0 },\n"
      .. "  tag_size = { [3] = 0.05, [5] = 0.02, default = 0.1 } }\n")
    local poses, summary, status = replay_poses(path)
    run.run("rm -r " .. run.quote(dir))
    assert.equal(0, status, summary)
    assert.truthy(summary:find("tag size 0.1 (default), 0.05 (tag 3), 0.02 (tag 5) m", 1, true),
      summary)
    assert.equal(5, #poses)
    for i, t in ipairs(truth) do
      assert.vector_near({ x = t[1], y = t[2], z = t[3] }, poses[i].pose.position, 1e-6)
    end
  end)

  it("refuses a camera file that would run: it never hangs", function()
    for _, body in ipairs({ "while true do end", "return { fx = string.rep('x', 2^31) }",
      "local t = {} for i = 1, 1e12 do t[i] = i end return t" }) do
      local cam = run.write(tmp("camera.lua"), body)
      local text, status = run.script("bin/tagpose-replay", LOG, "--camera", cam)
      os.remove(cam)
      assert.equal(1, status, text)
      assert.truthy(text:find("^replay: calibration: " .. cam:gsub("%p", "%%%0") .. ":1: "), text)
    end
  end)

  it("keeps tags that share an id apart: the same poses as with their own ids", function()
    -- the bundled approach with both tags relabelled 0
    local lines = {}
    for line in run.read(LOG):gmatch("[^\n]+") do
      if line:match("^%d") then line = line:gsub("^(%d+),%d+,", "%1,0,") end
      lines[#lines + 1] = line
    end
    local same = run.write(tmp("same.csv"), table.concat(lines, "\n") .. "\n")
    local svg = tmp("same.svg")
    local camera = "examples/data/camera.lua"
    local poses, text, status = replay_poses(same, "--camera", camera, "--track", "--svg", svg)
    local figure = run.read(svg)
    os.remove(same)
    os.remove(svg)
    assert.equal(0, status, text)
    assert.truthy(text:find("repeated   354 rows share their frame and tag with another row"
      .. " (tag 0, up to 2 in a frame; first at line 5): kept apart as tracks by image position",
      1, true), text)
    assert.truthy(text:find("(8 panels, 16 series: 2 tracks of 1 tag x 1 log)", 1, true), text)
    assert.truthy(figure:find(">tag 0 #2<", 1, true))
    -- tracking fed each tag its own previous pose: the poses of the log with distinct ids
    local own = assert(replay_poses(LOG, "--track"))
    assert.equal(#own, #poses)
    for i = 1, #own do assert.same(own[i].pose, poses[i].pose, "row " .. i) end
  end)

  it("names the log in the title and the tag size's unit on the axes", function()
    local svg = tmp("plot.svg")
    local text, status = run.script("bin/tagpose-replay", LOG, "--tag-size", "24mm", "--svg",
      svg, "--out", "-")
    local figure = run.read(svg)
    os.remove(svg)
    assert.equal(0, status, text)
    assert.truthy(figure:find(">replay of data/approach.csv<", 1, true))
    assert.truthy(figure:find(">x (mm)<", 1, true))
    assert.truthy(text:find("tag size 24 mm", 1, true), text)
    -- poses in mm: the first row's depth, against the metres of the camera file's size
    local mm = text:match("\n0,1,[^,]+,[^,]+,([^,]+),")
    local m = assert(replay_poses(LOG))[1].pose.position.z
    assert.near(1000 * m, tonumber(mm), 1e-9 * 1000 * m)
    text = run.script("bin/tagpose-replay", LOG, "--tag-size", "24parsecs")
    assert.truthy(text:find("--tag-size: positive number (with an optional unit m, cm, mm, in, ft)"
      .. " expected, got 24parsecs", 1, true), text)
  end)

  it("reports nan in the tag column and a glued row, and goes on", function()
    local path = run.write(tmp("corners.csv"), "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n"
      .. "1,nan,280,280,360,280,360,200,280,200\n"
      .. "2,7,280,280,360,280,360,200,280,200.0000"
      .. "3,7,280,280,360,280,360,200,280,200\n"
      .. "4,7,280,280,360,280,360,200,280,200\n")
    local poses, text, status = replay_poses(path, "--camera", "examples/data/camera.lua")
    os.remove(path)
    assert.equal(0, status, text)
    assert.truthy(text:find("  line 2: column tag is not finite (nan)", 1, true), text)
    assert.truthy(text:find("  line 3: 19 fields, header has 10", 1, true), text)
    assert.equal(1, #poses)
    assert.equal(4, poses[1].frame)
  end)

  it("reads, solves and writes row by row: memory does not grow with the log", function()
    local peaks = {}
    for _, rows in ipairs({ 500, 2000 }) do
      local dir = tmp("long" .. rows)
      assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
      assert.equal(0, select(2, run.script("bench/make_long_log.lua", dir, rows)))
      local out, status = run.run(run.quote(run.lua()) .. " spec/support/peak_heap.lua "
        .. run.quote(dir .. "/corners.csv") .. " --track --out " .. run.quote(dir .. "/p.csv")
        .. " 2>&1 >/dev/null")
      run.run("rm -r " .. run.quote(dir))
      assert.equal(0, status, out)
      local kib, solves = out:match("peak heap (%d+) KiB over (%d+) solves")
      assert.equal(rows, tonumber(solves), out)
      peaks[#peaks + 1] = tonumber(kib)
    end
    -- reading the whole log first costs several KiB a row (5 MB more here)
    assert.is_true(peaks[2] < peaks[1] + 2048, ("peak heap %d KiB for 500 rows, %d KiB for"
      .. " 2000"):format(peaks[1], peaks[2]))
  end)

  it("keeps its memory bounded however many distinct tag ids a log holds", function()
    local peaks = {}
    for _, rows in ipairs({ 1000, 5000 }) do
      local dir = tmp("ids" .. rows)
      assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
      assert.equal(0, select(2, run.script("bench/bounds.lua", "ids", dir, rows, 10)))
      -- the bound on the plot's lines lowered to 100, so that both logs are well past it
      local out, status = run.run(run.quote(run.lua()) .. " -e 'package.path = \"./src/?.lua;"
        .. "./src/?/init.lua;\" .. package.path; require(\"tagpose.tools.replay.slots\")"
        .. ".MAX = 100' spec/support/peak_heap.lua " .. run.quote(dir .. "/corners.csv")
        .. " --track --svg " .. run.quote(dir .. "/p.svg") .. " --compare "
        .. run.quote(dir .. "/truth.csv") .. " 2>&1 >/dev/null")
      run.run("rm -r " .. run.quote(dir))
      assert.equal(0, status, out)
      peaks[#peaks + 1] = tonumber(out:match("peak heap (%d+) KiB"))
    end
    -- each id's track, its filter's state and its plot line kept cost several KiB an id; the
    -- tracker drops the tracks of ended ids (max_gap), the plot's lines are swept out
    assert.is_true(peaks[2] < peaks[1] + 3072, ("peak heap %d KiB for 1000 ids, %d KiB for"
      .. " 5000"):format(peaks[1], peaks[2]))
  end)

  it("solves and writes every row of a frame of 300 distinct ids", function()
    local dir = tmp("frame")
    assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
    assert.equal(0, select(2, run.script("bench/bounds.lua", "ids", dir, 300, 300)))
    local out, status = run.script("bin/tagpose-replay", dir .. "/corners.csv", "--track",
      "--out", dir .. "/p.csv", "--svg", dir .. "/p.svg")
    local poses = log.read_poses(dir .. "/p.csv")
    run.run("rm -r " .. run.quote(dir))
    assert.equal(0, status, out)
    assert.matches("solved     300\n", out)
    assert.equal(300, #poses)
    -- the figure keeps its bounded series (plot.MAX_SERIES), and says what it left out
    assert.matches("points of tracks past the first 256 not drawn", out)
  end)
end)

describe("examples/data", function()
  it("is what make_approach.lua makes", function()
    local dir = tmp("data")
    assert.equal(0, select(2, run.run("mkdir " .. run.quote(dir))))
    local text, status = run.script("examples/data/make_approach.lua", dir)
    assert.equal(0, status, text)
    for _, name in ipairs({ "camera.lua", "approach.csv", "approach_truth.csv" }) do
      assert.equal(run.read("examples/data/" .. name), run.read(dir .. "/" .. name), name)
    end
    run.run("rm -r " .. run.quote(dir))
  end)
end)
