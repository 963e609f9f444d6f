local log = require("tagpose.tools.log")
local run = require("support.run")

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

    it("reads a time column in seconds, and refuses a row whose time is not one", function()
      local path = tmpfile("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,time\n"
        .. "1,0,1,2,3,4,5,6,7,8,0.0333\n"
        .. "2,0,1,2,3,4,5,6,7,8,\n"
        .. "3,0,1,2,3,4,5,6,7,8,soon\n"
        .. "4,0,1,2,3,4,5,6,7,8,inf\n")
      local reader = assert(log.corner_reader(path))
      assert.is_true(reader.has_time)
      reader:close()
      local rows, problems = log.read_corners(path)
      os.remove(path)
      assert.equal(1, #rows)
      assert.equal(0.0333, rows[1].time)
      assert.same({
        { line = 3, reason = "column time is empty" },
        { line = 4, reason = "column time is not a number" },
        { line = 5, reason = "column time is not finite (inf)" },
      }, problems)
      path = tmpfile("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4\n1,0,1,2,3,4,5,6,7,8\n")
      reader = assert(log.corner_reader(path))
      assert.is_false(reader.has_time)
      assert.is_nil(reader:read().time)
      reader:close()
      os.remove(path)
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
      assert.equal("4,2,0.5,-1,2,1,0,0,0,0.25,3,,,,,,,", log.pose_line(4, 2, pose))
      assert.equal("5,2,,,,,,,,,,,,,,,,", log.pose_line(5, 2, nil))
      assert.equal(#log.POSE_COLUMNS, select(2, log.pose_line(5, 2, nil):gsub(",", "")) + 1)
    end)

    it("writes a solved pose's confidence and the standard deviations of its covariance",
      function()
      local tagpose = require("tagpose")
      local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }
      local pose = assert(tagpose.solve({ { 280.3, 281.1 }, { 361.2, 279.4 }, { 358.9, 200.7 },
        { 279.1, 199.6 } }, camera, 0.024, { sigma = 0.5 }))
      local fields = {}
      for f in (log.pose_line(1, 2, pose) .. ","):gmatch("([^,]*),") do fields[#fields + 1] = f end
      assert.equal(#log.POSE_COLUMNS, #fields)
      local column = {}
      for i, name in ipairs(log.POSE_COLUMNS) do column[name] = tonumber(fields[i]) end
      assert.equal(pose.confidence, column.confidence)
      for i, name in ipairs({ "sx", "sy", "sz", "srx", "sry", "srz" }) do
        assert.equal(math.sqrt(pose.covariance[i][i]), column[name])
        assert.is_true(column[name] > 0)
      end
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
      assert.equal("frame,tag,x,y,z,qw,qx,qy,qz,error,iterations,confidence,sx,sy,sz,srx,sry,"
        .. "srz\n"
        .. "1,3,0.5,-1,2,0.59999999999999998,0,0.80000000000000004,0,0.25,3,,,,,,,\n"
        .. "2,3,,,,,,,,,,,,,,,,\n"
        .. "2,5,0.5,-1,2,0.59999999999999998,0,0.80000000000000004,0,0.25,3,,,,,,,\n", text)
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
      -- a truth file's track column (the physical tag of a row)
      path = tmpfile("frame,tag,x,y,z,qw,qx,qy,qz,track\n0,0,0.1,0.2,0.3,1,0,0,0,2\n"
        .. "0,0,,,,,,,,b\n0,0,0.1,0.2,0.3,1,0,0,0,\n")
      rows = assert(log.read_poses(path))
      os.remove(path)
      assert.same({ 2, "b" }, { rows[1].track, rows[2].track })
      assert.is_nil(rows[3].track)
      path = tmpfile("frame,tag,x,y,z\n")
      local none, err = log.read_poses(path)
      os.remove(path)
      assert.is_nil(none)
      assert.equal("log: header has no column 'qw' (line 1)", err)
    end)
  end)

  describe("read_camera()", function()
    it("reads a camera file as data, through tagpose.calibration", function()
      local path = os.tmpname() .. ".lua"
      run.write(path, "return { fx = 300, fy = 310, cx = 160, cy = 120, tag_size = 0.024 }")
      local camera, info = assert(log.read_camera(path))
      os.remove(path)
      assert.same({ fx = 300, fy = 310, cx = 160, cy = 120, model = "pinhole" }, camera)
      assert.equal(0.024, info.tag_size)
      run.write(path, "os.exit(3)")
      local ok, err = log.read_camera(path)
      os.remove(path)
      assert.is_nil(ok)
      assert.equal("calibration: " .. path .. ":1: an assignment or a call ('os.exit') is not"
        .. " data: 'return { ... }' expected", err)
    end)
  end)

  describe("read_corners() and corner_reader()", function()
    local HEADER = "frame,tag,u1,v1,u2,v2,u3,v3,u4,v4"
    local M_HEADER = log.CORNER_COLUMNS

    -- every detection and problem ("line: reason") of a log text
    local function read(text)
      local path = tmpfile(text)
      local rows, problems = log.read_corners(path)
      os.remove(path)
      if not rows then return nil, problems end
      local out = {}
      for k, p in ipairs(problems) do out[k] = p.line .. ": " .. p.reason end
      return rows, out
    end

    it("reads a log row by row", function()
      local path = tmpfile(HEADER .. "\n1,0,1,2,3,4,5,6,7,8\n2,0,1,2\n3,4,1,2,3,4,5,6,7,8\n")
      local reader = assert(log.corner_reader(path))
      assert.same(M_HEADER, reader.header)
      local a = reader:read()
      local b, line, reason = reader:read()
      local c = reader:read()
      assert.is_nil(reader:read())
      reader:close()
      os.remove(path)
      assert.same({ 1, 0, 2 }, { a.frame, a.tag, a.line })
      assert.same({ false, 3, "4 fields, header has 10" }, { b, line, reason })
      assert.same({ 3, 4, 4 }, { c.frame, c.tag, c.line })
      assert.same({ { 1, 2 }, { 3, 4 }, { 5, 6 }, { 7, 8 } }, c.corners)
    end)

    it("refuses a row with too many fields: two rows glued by a lost line end", function()
      local rows, problems = read(HEADER .. "\n1,0,1,2,3,4,5,6,7,114.4996"
        .. "2,0,1,2,3,4,5,6,7,8\n3,0,1,2,3,4,5,6,7,8\n")
      assert.same({ "2: 19 fields, header has 10" }, problems)
      assert.equal(1, #rows)
      assert.equal(3, rows[1].line)
    end)

    it("refuses a header that names a column twice or leaves one unnamed", function()
      local rows, err = read("frame,tag,u1,v1,u2,v2,u3,v3,u4,v4,u1\n1,0,1,2,3,4,5,6,7,8,9\n")
      assert.is_nil(rows)
      assert.equal("log: header names column 'u1' twice (columns 3 and 11, line 1)", err)
      rows, err = read("# comment\n" .. HEADER .. ",\n")
      assert.is_nil(rows)
      assert.equal("log: header column 11 has no name (line 2)", err)
      rows, err = read(HEADER .. string.rep(",x", log.MAX_COLUMNS) .. "\n")
      assert.is_nil(rows)
      assert.equal("log: header has " .. (log.MAX_COLUMNS + 10) .. " columns, more than "
        .. log.MAX_COLUMNS .. " (line 1)", err)
      rows, err = read("frame;tag;u1;v1;u2;v2;u3;v3;u4;v4\n")
      assert.is_nil(rows)
      assert.equal("log: header has no column 'frame' (line 1): its fields are separated by ';',"
        .. " not commas", err)
    end)

    it("keeps line numbers apart from a column named 'line'", function()
      local rows, problems = read(HEADER .. ",line\n1,0,1,2,3,4,5,6,7,8,abc\n"
        .. "2,0,1,2,3,4,5,6,7,8,17\n")
      assert.same({}, problems)
      assert.same({ 2, 3 }, { rows[1].line, rows[2].line })
      assert.same({ "abc", 17 }, { rows[1].fields.line, rows[2].fields.line })
    end)

    it("reports nan, inf and tags that are not ids in the frame or tag column, the same on every"
      .. " VM", function()
      local rows, problems = read(HEADER .. "\n1,nan,1,2,3,4,5,6,7,8\nNaN,0,1,2,3,4,5,6,7,8\n"
        .. "3,-inf,1,2,3,4,5,6,7,8\n4,1e999,1,2,3,4,5,6,7,8\n5,0x10,1,2,3,4,5,6,7,8\n"
        .. "6,0,nan,2,3,4,5,6,7,inf\n7,1.5,1,2,3,4,5,6,7,8\n8,1e19,1,2,3,4,5,6,7,8\n"
        .. "9,-9007199254740992,1,2,3,4,5,6,7,8\n10,9007199254740991,1,2,3,4,5,6,7,8\n")
      assert.same({ "2: column tag is not finite (nan)", "3: column frame is not finite (NaN)",
        "4: column tag is not finite (-inf)", "5: column tag is not finite (1e999)",
        "6: column tag is not a number",
        "8: column tag is not a tag id (1.5 is not a whole number of magnitude below 2^53)",
        "9: column tag is not a tag id (1e19 is not a whole number of magnitude below 2^53)",
        "10: column tag is not a tag id (-9007199254740992 is not a whole number of magnitude"
          .. " below 2^53)" }, problems)
      -- corners that are not finite go to the solver, which refuses them
      assert.equal(2, #rows)
      assert.equal(9007199254740991, rows[2].tag)
      local c = rows[1].corners
      assert.is_true(c[1][1] ~= c[1][1])
      assert.equal(math.huge, c[4][2])
    end)

    it("trims long runs of spaces in linear time", function()
      local spaces = string.rep(" ", 80000)
      local rows, problems = read(HEADER .. ",note\n1," .. spaces .. "0" .. spaces
        .. ",1,2,3,4,5,6,7,8," .. spaces .. "\n2,0,1,2,3,4,5,6,7,8,a" .. spaces .. "b\n"
        .. spaces .. "\n")
      assert.same({}, problems)
      assert.equal(2, #rows)
      assert.equal(0, rows[1].tag)
      assert.is_nil(rows[1].fields.note)
      assert.equal(80002, #rows[2].fields.note)
    end)

    it("reads LF, CRLF and CR-only line ends and a UTF-8 byte-order mark alike", function()
      local body = { HEADER, "1,0,1,2,3,4,5,6,7,8", "", "# c", "2,3,1,2,3,4,5,6,7,8" }
      local want
      for _, eol in ipairs({ "\n", "\r\n", "\r" }) do
        for _, bom in ipairs({ "", "\239\187\191" }) do
          local rows, problems = read(bom .. table.concat(body, eol) .. eol)
          assert.same({}, problems)
          local got = {}
          for _, r in ipairs(rows) do got[#got + 1] = { r.frame, r.tag, r.line } end
          want = want or got
          assert.same({ { 1, 0, 2 }, { 2, 3, 5 } }, got)
        end
      end
    end)

    it("reads line ends split across the reader's chunks", function()
      -- rows of 30 bytes with CRLF: some CR ends a 64 KiB chunk, its LF starts the next
      local lines = { HEADER }
      for i = 1, 5000 do lines[#lines + 1] = ("%5d,0,1,2,3,4,5,6,7,8.00000"):format(i) end
      local rows, problems = read(table.concat(lines, "\r\n") .. "\r\n")
      assert.same({}, problems)
      assert.equal(5000, #rows)
      for i = 1, 5000 do
        assert.equal(i, rows[i].frame)
        assert.equal(i + 1, rows[i].line)
      end
    end)

    it("reads RFC 4180 quoted fields as a spreadsheet saves them", function()
      local rows, problems = read('"frame","tag","u1","v1","u2","v2","u3","v3","u4","v4","note"\r\n'
        .. '"1","0","1","2","3","4","5","6","7","8","a, ""quoted"" note"\r\n'
        .. '3,0,1,2,3,4,5,6,7,8, "spaced" \r\n')
      assert.same({}, problems)
      assert.equal(2, #rows)
      assert.equal('a, "quoted" note', rows[1].fields.note)
      assert.equal(3, rows[2].line)
      assert.equal("spaced", rows[2].fields.note)
    end)

    it("reports quoting errors with the line and goes on", function()
      local rows, problems = read(HEADER .. "\n1,0,1,2,3,4,5,6,7,\"8\"x\n"
        .. '2,0,1,2,3,4,5,6,7,8"\n3,0,1,2,3,4,5,6,7,8\n4,0,1,2,3,4,5,6,7,"8\n')
      assert.same({ "2: text after the closing quote of field 10",
        '3: a quote inside field 10 (quote the whole field, with "" for a quote)',
        "5: quoted field 10 not closed on its line" }, problems)
      assert.equal(1, #rows)
      assert.equal(4, rows[1].line)
    end)

    it("never reads a quoted field across lines: a stray quote costs its own line", function()
      -- a quote opening a field anywhere in a long log, and one before a line end inside a
      -- field that a spreadsheet would have read across lines
      for _, stray in ipairs({ '"', ' "12.5', '"note' }) do
        local lines = { HEADER .. ",note" }
        for i = 1, 3000 do
          lines[#lines + 1] = ("%d,%d,1,2,3,4,5,6,7,8,%s"):format(i, i % 7,
            i == 1234 and stray or "x")
        end
        lines[#lines + 1] = '3001,0,1,2,3,4,5,6,7,8,"two'
        lines[#lines + 1] = 'lines"'
        local rows, problems = read(table.concat(lines, "\n") .. "\n")
        assert.equal(3000 - 1, #rows, stray)
        assert.equal("1235: quoted field 11 not closed on its line", problems[1])
        assert.equal("3002: quoted field 11 not closed on its line", problems[2])
        assert.matches("^3003: ", problems[3])
        assert.equal(3, #problems)
        assert.equal(1236, rows[1234].line)
      end
    end)

    it("reports a line longer than MAX_RECORD and reads on", function()
      local rows, problems = read(HEADER .. "\n1,0,1,2,3,4,5,6,7,8"
        .. string.rep("9", log.MAX_RECORD) .. "\n2,0,1,2,3,4,5,6,7,8\n")
      assert.same({ "2: line longer than " .. log.MAX_RECORD .. " bytes" }, problems)
      assert.equal(1, #rows)
      assert.equal(3, rows[1].line)
    end)
  end)

  describe("pose_writer() and pose_reader()", function()
    it("write and read row by row", function()
      local path = os.tmpname()
      local writer = assert(log.pose_writer(path))
      local pose = { position = { x = 0.5, y = -1, z = 2 },
        quaternion = { w = 0.6, x = 0, y = 0.8, z = 0 }, error = 0.25, iterations = 3 }
      for i = 1, 1000 do writer:write(i, 7, i % 3 ~= 0 and pose or nil) end
      assert.equal(1000, writer:close())
      local reader = assert(log.pose_reader(path))
      local n, failed = 0, 0
      while true do
        local e = reader:read()
        if e == nil then break end
        n = n + 1
        assert.equal(n, e.frame)
        if e.pose then assert.same(pose, e.pose) else failed = failed + 1 end
      end
      reader:close()
      os.remove(path)
      assert.same({ 1000, 333 }, { n, failed })
    end)
  end)
end)
