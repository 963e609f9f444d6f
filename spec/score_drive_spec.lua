-- bench/score_drive.lua on a drive log made by hand: ten truth times, ten camera frames and a
-- pose log whose errors, uncertainties and frames are chosen so that every figure of the table
-- is worked out below from the definitions (numpy's median and linear percentile, the
-- chi-square test, the frames' matching), not taken from the script.
local run = require("support.run")

local score = dofile("bench/score_drive.lua")

local sin, cos, rad, sqrt = math.sin, math.cos, math.rad, math.sqrt

local function num(v)
  return ("%.17g"):format(v)
end

-- the quaternion (w, x, y, z) of yaw, then pitch, then roll (ZYX), degrees
local function quaternion(yaw, pitch, roll)
  local cy, sy = cos(rad(yaw) / 2), sin(rad(yaw) / 2)
  local cp, sp = cos(rad(pitch) / 2), sin(rad(pitch) / 2)
  local cr, sr = cos(rad(roll) / 2), sin(rad(roll) / 2)
  return cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr, cy * sp * cr + sy * cp * sr,
    sy * cp * cr - cy * sp * sr
end

local function quat_cells(yaw, pitch, roll)
  local w, x, y, z = quaternion(yaw, pitch, roll)
  return num(w) .. "," .. num(x) .. "," .. num(y) .. "," .. num(z)
end

-- truth: the robot at (0, 0) heading 0 at t = 1..10 s, but at t = 4 s heading 30 deg, pitched
-- 10 deg and rolled 5 deg (its yaw is still 30 deg)
local function truth_csv()
  local lines = { "time,x,y,z,qw,qx,qy,qz" }
  for t = 1, 10 do
    local q = t == 4 and quat_cells(30, 10, 5) or quat_cells(0, 0, 0)
    lines[#lines + 1] = ("%d.000000,0,0,0,%s"):format(t, q)
  end
  return table.concat(lines, "\n") .. "\n"
end

-- the frames: (time, camera, detection rows)
local FRAMES = {
  { 1, "front", 1 }, { 2, "front", 2 }, { 3, "back", 1 }, { 4, "front", 3 }, { 5, "back", 1 },
  { 6, "front", 2 }, { 7, "front", 1 }, { 8, "back", 1 }, { 9, "front", 1 }, { 10, "back", 2 },
}

local function corners_csv()
  local lines = { "time,camera,tag,u1,v1,u2,v2,u3,v3,u4,v4" }
  for _, f in ipairs(FRAMES) do
    for tag = 1, f[3] do
      lines[#lines + 1] = ("%d.000000,%s,%d,1,2,3,2,3,1,1,1"):format(f[1], f[2], tag)
    end
  end
  return table.concat(lines, "\n") .. "\n"
end

-- The pose rows: time, camera, x, y, yaw (deg), then the uncertainty cells sx, sy, syaw, c11,
-- c21, c22, c66 ("" for none). Errors, uncertainties and what each row counts in:
--  1  1 s front   0.1 m, yaw 1: sx = sy = 0.2 (chi2 0.25: in), syaw 1 deg (in); 1 tag
--  2  2 s front   0.2 m, yaw 2: sx = sy = 0.05 (chi2 16: out), syaw 0.5 deg (out); 2 tags
--  3  3 s back    0.3 m, yaw -3: c66 missing, so sx = sy = 0.2 (chi2 2.25: in), syaw 2 deg
--                 (in); 1 tag
--  4  4 s front   0.4 m, yaw 34 (4 from the tilted truth): c11 = c22 = 0.01, c21 = 0.02 (det < 0:
--                 no position coverage, its sx, sy ignored), c66 = (3 deg)^2 (in); 3 tags
--  5  5 s back    0.6 m, yaw 5: C = diag(0.04, 0.04) (chi2 9: out), c66 = (1 deg)^2 (out); 1 tag
--  6  6 s front   0.7 m, yaw 6: no uncertainty; 2 tags
--  7  7 s back    0.8 m, yaw 7: sx 0.5, sy 0.1 (chi2 2.56: in), syaw 0 (none); no such frame
--  8  8 s fused   (3, 4): 5 m, yaw 350 (10 after the wrap): C = [[2, 2.6], [2.6, 3.5]] from c21
--                 (chi2 1.1 / 0.24 = 4.58: in; without the correlation it would be 9.07),
--                 c66 = (4 deg)^2 (out); completes frame (8, back) by its time
--  9  10.0005 s back  0.9 m, yaw 8: sx 0 (none), syaw 5 deg (in); truth 10 s is 0.5 ms away;
--                 2 tags
-- 10  9.5 s front: no truth within 1 ms (unmatched)
-- 11  9.0015 s front: 1.5 ms from the truth (unmatched)
-- 12  no time (unmatched)
local function d2(v) return num(rad(v) ^ 2) end
local POSES = {
  { "1.000000", "front", "0.1", "0", 1, "0.2", "0.2", num(rad(1)), "", "", "", "" },
  { "2.000000", "front", "0.2", "0", 2, "0.05", "0.05", num(rad(0.5)), "", "", "", "" },
  { "3.000000", "back", "0.3", "0", -3, "0.2", "0.2", num(rad(2)), "0.01", "", "0.01", "" },
  { "4.000000", "front", "0.4", "0", 34, "0.5", "0.5", "", "0.01", "0.02", "0.01", d2(3) },
  { "5.000000", "back", "0.6", "0", 5, "", "", "", "0.04", "", "0.04", d2(1) },
  { "6.000000", "front", "0.7", "0", 6, "", "", "", "", "", "", "" },
  { "7.000000", "back", "0.8", "0", 7, "0.5", "0.1", "0", "", "", "", "" },
  { "8.000000", "fused", "3", "4", 350, "", "", "", "2", "2.6", "3.5", d2(4) },
  { "10.000500", "back", "0.9", "0", 8, "0", "0.1", num(rad(5)), "", "", "", "" },
  { "9.500000", "front", "0", "0", 0, "", "", "", "", "", "", "" },
  { "9.001500", "front", "0", "0", 0, "", "", "", "", "", "", "" },
  { "", "front", "0", "0", 0, "", "", "", "", "", "", "" },
}

local function poses_csv()
  local lines = { "time,camera,x,y,z,qw,qx,qy,qz,sx,sy,syaw,c11,c21,c22,c66,tags" }
  for _, p in ipairs(POSES) do
    lines[#lines + 1] = table.concat({ p[1], p[2], p[3], p[4], "0", quat_cells(p[5], 0, 0),
      p[6], p[7], p[8], p[9], p[10], p[11], p[12], "1 2" }, ",")
  end
  return table.concat(lines, "\n") .. "\n"
end

describe("bench/score_drive.lua", function()
  local dir = run.tmpdir()
  run.write(dir .. "/truth.csv", truth_csv())
  run.write(dir .. "/corners.csv", corners_csv())
  local poses = run.write(dir .. "/poses.csv", poses_csv())
  local empty = run.write(dir .. "/empty.csv", "time,camera,x,y,z,qw,qx,qy,qz\n")
  -- a fused row heading 0 at (0, 0) at every truth time: every frame complete; the heading
  -- errors nine 0s and 30 (t = 4 s), p95 at 0.95 * 9 = 8.55: 30 - 0.45 * 30 = 16.5
  local lines = { "time,camera,x,y,z,qw,qx,qy,qz" }
  for t = 1, 10 do lines[#lines + 1] = t .. ",fused,0,0,0,1,0,0,0" end
  local fused = run.write(dir .. "/fused.csv", table.concat(lines, "\n") .. "\n")

  teardown(function()
    run.run("rm -r " .. run.quote(dir))
  end)

  describe("percentile() and median()", function()
    it("are numpy's (linear interpolation between the sorted values)", function()
      -- 95 % of (4 - 1) = 2.85: 3 + 0.85 (4 - 3)
      assert.near(3.85, score.percentile({ 4, 1, 3, 2 }, 95), 1e-12)
      assert.near(2.5, score.percentile({ 4, 1, 3, 2 }, 50), 1e-12)
      assert.equal(7, score.percentile({ 7 }, 95))
      assert.is_nil(score.percentile({}, 95))
      assert.equal(2, score.median({ 3, 1, 2 }))
      assert.equal(2.5, score.median({ 4, 1, 3, 2 }))
      assert.is_nil(score.median({}))
    end)
  end)

  describe("hypot()", function()
    it("is the planar distance", function()
      assert.equal(5, score.hypot(3, -4))
      assert.equal(0, score.hypot(0, 0))
      assert.near(sqrt(2) * 1e-200, score.hypot(1e-200, 1e-200), 1e-214)
    end)
  end)

  describe("score()", function()
    local s = score.score(dir, { poses, empty, fused })
    local p = s[1]

    it("counts the rows and those with no truth within 1 ms", function()
      assert.equal(12, p.rows)
      assert.equal(3, p.unmatched)
      assert.equal(9, p.scored)
    end)

    it("gives the planar error's median, p95, max and the rows past 0.5 m and 1 m", function()
      -- sorted: 0.1 0.2 0.3 0.4 0.6 0.7 0.8 0.9 5; p95 at 0.95 * 8 = 7.6: 0.9 + 0.6 (5 - 0.9)
      assert.near(0.6, p.pos.median, 1e-12)
      assert.near(3.36, p.pos.p95, 1e-12)
      assert.near(5, p.pos.max, 1e-12)
      assert.equal(5, p.over_half)
      assert.equal(1, p.over_one)
    end)

    it("gives the heading error in degrees, wrapped, from the quaternions' yaw", function()
      -- |errors|: 1 2 3 4 5 6 7 10 8 (350 wraps to -10; row 4 against a tilted truth)
      assert.near(5, p.yaw.median, 1e-9)
      assert.near(8 + 0.6 * 2, p.yaw.p95, 1e-9)
    end)

    it("covers the position with the chi-square test on the row's first complete form",
      function()
        -- rows 1, 3, 7, 8 in; 2, 5 out; 4 (det < 0), 6 (none), 9 (sx 0) not counted
        assert.equal(6, p.cov95_pos_rows)
        assert.near(4 / 6, p.cov95_pos, 1e-15)
      end)

    it("covers the heading with 1.96 sigma", function()
      -- rows 1, 3, 4, 9 in; 2, 5, 8 out; 6 (none), 7 (syaw 0) not counted
      assert.equal(7, p.cov95_yaw_rows)
      assert.near(4 / 7, p.cov95_yaw, 1e-15)
    end)

    it("counts the frames with detections that have a row", function()
      -- (7, front) has a back row, (9, front) none: 8 of 10
      assert.equal(10, p.frames_with_tags)
      assert.near(0.8, p.completeness, 1e-15)
      assert.near(1, s[3].completeness, 1e-15)
      assert.near(16.5, s[3].yaw.p95, 1e-9)
      assert.equal(0, s[2].completeness)
    end)

    it("splits the camera rows by the tags their frame has", function()
      -- 1 tag: 0.1 0.3 0.6 (p95 at 1.9: 0.3 + 0.9 * 0.3); 2+: 0.2 0.4 0.7 0.9 (p95 at 2.85)
      assert.equal(3, p.one_tag.n)
      assert.near(0.3, p.one_tag.median, 1e-12)
      assert.near(0.57, p.one_tag.p95, 1e-12)
      assert.equal(4, p.more_tags.n)
      assert.near(0.55, p.more_tags.median, 1e-12)
      assert.near(0.87, p.more_tags.p95, 1e-12)
    end)

    it("has no figures for a log without rows", function()
      local e = s[2]
      assert.equal(0, e.rows)
      assert.is_nil(e.pos.median)
      assert.is_nil(e.cov95_pos)
      assert.is_nil(e.cov95_yaw)
    end)
  end)

  describe("the command", function()
    it("prints score_drive.py's table", function()
      local text, status = run.script("bench/score_drive.lua", dir, poses, empty, fused)
      assert.equal(0, status, text)
      local expected = {
        "| file | rows | pos med | p95 | max | >0.5 m | >1 m | yaw med | yaw p95 | cov95 pos"
          .. " | cov95 yaw | complete | 1 tag med/p95 | 2+ tags med/p95 |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        "| poses.csv | 12 (3 unmatched) | 0.600 | 3.360 | 5.000 | 5 | 1 | 5.00 | 9.20 | 66.7 %"
          .. " | 57.1 % | 80.0 % | 0.300/0.570 | 0.550/0.870 |",
        "| empty.csv | 0 | - | - | - | 0 | 0 | - | - | - | - | 0.0 % | - | - |",
        "| fused.csv | 10 | 0.000 | 0.000 | 0.000 | 0 | 0 | 0.00 | 16.50 | - | - | 100.0 % | - |"
          .. " - |",
      }
      assert.equal(table.concat(expected, "\n") .. "\n", text)
    end)

    it("prints its usage and exits 2 without a CSV", function()
      local text, status = run.script("bench/score_drive.lua", dir)
      assert.equal(2, status)
      assert.truthy(text:find("usage: lua5.4 bench/score_drive.lua DIR CSV", 1, true))
    end)

    it("exits 1 naming a file it cannot read", function()
      local text, status = run.script("bench/score_drive.lua", dir, dir .. "/missing.csv")
      assert.equal(1, status)
      assert.truthy(text:find("missing.csv", 1, true))
    end)
  end)
end)
