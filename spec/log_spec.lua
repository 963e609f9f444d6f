local log = require("tagpose.tools.log")

local function tmpfile(text)
  local path = os.tmpname()
  local f = assert(io.open(path, "w"))
  f:write(text)
  f:close()
  return path
end

describe("tagpose.tools.log", function()
  describe("read_corners()", function()
    it("reads rows in file order, ignoring extra columns, comments and blank lines", function()
      local path = tmpfile(table.concat({
        "# recorded on the robot",
        "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,score",
        "1,7,10,20,30,20,30,0,10,0,0.9",
        "",
        "  # a comment",
        "2,7,11.5,21,31,21,31,1,11,1,0.8",
      }, "\n") .. "\n")
      local rows, problems = log.read_corners(path)
      os.remove(path)
      assert.same({}, problems)
      assert.equal(2, #rows)
      assert.same({ { 10, 20 }, { 30, 20 }, { 30, 0 }, { 10, 0 } }, rows[1].corners)
      assert.same({ 2, 7, 6 }, { rows[2].frame, rows[2].tag, rows[2].line })
      assert.equal(11.5, rows[2].corners[1][1])
      assert.equal(0.8, rows[2].fields.score)
    end)

    it("reports malformed rows with their line numbers and keeps the rest", function()
      local path = tmpfile("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n"
        .. "1,0,1,2,3,4,5,6,7,8\n"
        .. "2,0,1,2,3\n"
        .. "3,0,1,2,3,4,5,six,7,8\n"
        .. "4,0,1,2,3,4,5,,7,8\n"
        .. "5,0,1,2,3,4,5,6,7,8\n")
      local rows, problems = log.read_corners(path)
      os.remove(path)
      assert.equal(2, #rows)
      assert.same({ 1, 5 }, { rows[1].frame, rows[2].frame })
      assert.same({
        { line = 3, reason = "5 fields, header has 10" },
        { line = 4, reason = "column v3 is not a number" },
        { line = 5, reason = "column v3 is empty" },
      }, problems)
    end)

    it("refuses a header without the corner columns", function()
      local path = tmpfile("frame,tag,x,y\n1,2,3,4\n")
      local rows, err = log.read_corners(path)
      os.remove(path)
      assert.is_nil(rows)
      assert.equal("log: header has no column 'u1' (line 1)", err)
      assert.is_nil((log.read_corners("/nonexistent/corners.csv")))
    end)
  end)

  describe("pose_line()", function()
    it("writes a pose, and empty pose fields for a failed row", function()
      local pose = { position = { x = 0.5, y = -1, z = 2 },
        quaternion = { w = 1, x = 0, y = 0, z = 0 },
        error = 0.25, iterations = 3 }
      assert.equal("4,2,0.5,-1,2,1,0,0,0,0.25,3", log.pose_line(4, 2, pose))
      assert.equal("5,2,,,,,,,,,", log.pose_line(5, 2, nil))
      assert.equal(#log.POSE_COLUMNS, select(2, log.pose_line(5, 2, nil):gsub(",", "")) + 1)
    end)
  end)

  describe("write_poses() and read_poses()", function()
    local pose = { position = { x = 0.5, y = -1, z = 2 },
      quaternion = { w = 0.6, x = 0, y = 0.8, z = 0 }, error = 0.25, iterations = 3 }

    it("write a whole log in order and read it back, failed rows included", function()
      local path = os.tmpname()
      local entries = { { frame = 1, tag = 3, pose = pose }, { frame = 2, tag = 3 },
        { frame = 2, tag = 5, pose = pose } }
      assert.equal(3, log.write_poses(path, entries))
      local f = assert(io.open(path, "r"))
      local text = f:read("*a")
      f:close()
      assert.equal("frame,tag,x,y,z,qw,qx,qy,qz,error,iterations\n"
        .. "1,3,0.5,-1,2,0.59999999999999998,0,0.80000000000000004,0,0.25,3\n"
        .. "2,3,,,,,,,,,\n"
        .. "2,5,0.5,-1,2,0.59999999999999998,0,0.80000000000000004,0,0.25,3\n", text)
      local back, problems = log.read_poses(path)
      os.remove(path)
      assert.same({}, problems)
      assert.equal(3, #back)
      assert.same({ 1, 3, 2 }, { back[1].frame, back[1].tag, back[1].line })
      assert.same(pose, back[1].pose)
      assert.same({ 2, 3, 3 }, { back[2].frame, back[2].tag, back[2].line })
      assert.is_nil(back[2].pose)
    end)

    it("write to an open file and leave it open", function()
      local path = os.tmpname()
      local f = assert(io.open(path, "w"))
      assert.equal(0, log.write_poses(f, {}))
      f:write("# more\n")
      f:close()
      local rows = assert(log.read_poses(path))
      os.remove(path)
      assert.same({}, rows)
    end)

    it("write_poses() reports a file it cannot create", function()
      local ok, err = log.write_poses("/nonexistent/dir/poses.csv", {})
      assert.is_nil(ok)
      assert.truthy(err:find("^log: /nonexistent/dir/poses.csv"))
    end)

    it("read_poses() reads truth files and reports malformed rows by line", function()
      local path = tmpfile(table.concat({
        "frame,tag,x,y,z,qw,qx,qy,qz",
        "0,1,0.1,0.2,0.3,1,0,0,0",
        "1,1,0.1,0.2,,1,0,0,0",
        "2,1,0.1,0.2,0.3,one,0,0,0",
        ",1,0.1,0.2,0.3,1,0,0,0",
        "4,1,,,,,,,",
      }, "\n") .. "\n")
      local rows, problems = log.read_poses(path)
      os.remove(path)
      assert.equal(2, #rows)
      assert.same({ position = { x = 0.1, y = 0.2, z = 0.3 },
        quaternion = { w = 1, x = 0, y = 0, z = 0 } }, rows[1].pose)
      assert.same({ 4, 6 }, { rows[2].frame, rows[2].line })
      assert.is_nil(rows[2].pose)
      assert.same({
        { line = 3, reason = "column z is empty" },
        { line = 4, reason = "column qw is not a number" },
        { line = 5, reason = "column frame is empty" },
      }, problems)
      path = tmpfile("frame,tag,x,y,z\n")
      local none, err = log.read_poses(path)
      os.remove(path)
      assert.is_nil(none)
      assert.equal("log: header has no column 'qw' (line 1)", err)
    end)
  end)

  describe("read_camera()", function()
    it("loads a camera file without access to globals", function()
      local path = tmpfile("return { fx = 300, fy = 310, cx = 160, cy = 120, tag_size = 0.024 }")
      local camera = assert(log.read_camera(path))
      os.remove(path)
      assert.same({ fx = 300, fy = 310, cx = 160, cy = 120, tag_size = 0.024 }, camera)
      path = tmpfile("os.exit(3)")
      local ok, err = log.read_camera(path)
      os.remove(path)
      assert.is_nil(ok)
      assert.truthy(err:find("attempt to index", 1, true))
    end)
  end)
end)
