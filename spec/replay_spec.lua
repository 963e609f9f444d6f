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
    -- the figure: valid, 7 panels of 2 tags x 2 logs
    assert.is_true(run.xmllint(figure))
    assert.truthy(figure:find('data-panels="7" data-series="28"', 1, true))
  end)

  it("tracks each tag from its previous frame with --track or --max-gap", function()
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
    assert.truthy(text:find("method refined, no tracking", 1, true), text)
    local tracked
    tracked, text = p95("--track")
    assert.truthy(text:find("tracking each tag from its pose up to 1 frame before", 1, true),
      text)
    -- far, small tags flip between the two solutions of the planar ambiguity: tracking
    -- keeps most of them on the right one
    assert.is_true(tracked < 0.5 * untracked, ("p95 %.3g deg tracked, %.3g untracked")
      :format(tracked, untracked))
    local gap
    gap, text = p95("--max-gap", "3")
    assert.truthy(text:find("up to 3 frames before", 1, true), text)
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
    assert.equal("frame,tag,x,y,z,qw,qx,qy,qz,error,iterations", csv[1])
    assert.equal(5, #csv)
    assert.truthy(csv[2]:match("^1,7,[%d.e-]+,"))
    assert.equal("4,7,,,,,,,,,", csv[3])
    assert.equal("6,8,,,,,,,,,", csv[4])
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
    assert.truthy(text:find("wrote " .. svg .. " (6 panels, 12 series: 2 tags x 1 log)", 1,
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
    text, status = run.script("bin/tagpose-replay", "/nonexistent/corners.csv")
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
