-- Layout files are read and written as strictly as tagpose's logs: ids are whole numbers below
-- 2^53 in every format, read and written; quaternions are normalised without overflow; CSV
-- numbers are decimal and rows have the header's fields; names come back as written; a file
-- too large is refused unread; a refused layout never touches the file.
local tagpose = require("tagpose")
local assertions = require("support.assertions")
local run = require("support.run")

local dir = run.tmpdir()

local function file(name, text)
  return run.write(dir .. "/" .. name, text)
end

local function tag(x, q)
  return { size = 0.03, position = { x = x, y = 0, z = 0 },
    quaternion = q or { w = 1, x = 0, y = 0, z = 0 } }
end

local FORMATS = { "lua", "yaml", "csv" }
local HEAD = "id,size,x,y,z,qw,qx,qy,qz\n"

-- the files in dir whose names start with prefix
local function listed(prefix)
  local out, n = run.run("ls -a " .. run.quote(dir)), {}
  for name in out:gmatch("[^\n]+") do
    if name:sub(1, #prefix) == prefix or name:sub(1, #prefix + 1) == "." .. prefix then
      n[#n + 1] = name
    end
  end
  table.sort(n)
  return n
end

describe("tagpose.layout files", function()
  it("take ids that are whole numbers of magnitude below 2^53, in every format", function()
    local big = 2 ^ 53 - 1
    local layout = { name = "ids", tags = { [-big] = tag(0), [big] = tag(1), [0] = tag(2),
      [12345678901234] = tag(3) } }
    for _, ext in ipairs(FORMATS) do
      local path = dir .. "/ids." .. ext
      assert(tagpose.layout.write(path, layout))
      local back = assert(tagpose.layout.read(path))
      local ids = {}
      for id in pairs(back.tags) do ids[#ids + 1] = id end
      table.sort(ids)
      assert.same({ -big, 0, 12345678901234, big }, ids, ext)
    end
    local name = "layout_files_spec.lua"
    for _, id in ipairs({ 2 ^ 53, -2 ^ 53, 1e19, 1.5 }) do
      for _, ext in ipairs(FORMATS) do
        local path = file("keep." .. ext, "unchanged")
        local msg = assertions.raised(function()
          tagpose.layout.write(path, { tags = { [id] = tag(0) } })
        end, name)
        assert.matches("^bad argument #2 to 'write' %(layout.tags: key number .* is not a tag id",
          msg)
        assert.equal("unchanged", run.read(path), "the file is not touched")
      end
    end
    local cases = {
      { "big.csv", HEAD .. "9007199254740992,0.03,0,0,0,1,0,0,0\n", "big.csv:2: id 9.007" },
      { "neg.csv", HEAD .. "-1e19,0.03,0,0,0,1,0,0,0\n", "neg.csv:2: id %-1e%+19 is not a tag id" },
      { "half.csv", HEAD .. "1.5,0.03,0,0,0,1,0,0,0\n", "half.csv:2: id 1.5 is not a tag id" },
      { "big.yaml", "tag_bundles:\n  - name: b\n    layout:\n      - {id: 1e19, size: 0.02, x: 0,"
        .. " y: 0, z: 0, qw: 1, qx: 0, qy: 0, qz: 0}\n", "big.yaml:4: id 1e%+19 is not a tag id" },
      { "big.lua", "return { tags = {\n  [1e19] = {} } }\n", "big.lua:2: tags: key 1e%+19 is not" },
    }
    for _, c in ipairs(cases) do
      local none, why = tagpose.layout.read(file(c[1], c[2]))
      assert.is_nil(none, c[1])
      assert.matches(c[3], why, 1, false, c[1])
      assert.matches("a whole number of magnitude below 2%^53", why, 1, false, c[1])
    end
  end)

  it("normalise quaternions of any length without overflow, and refuse a zero one", function()
    -- (1e200, 1e200, 0, 0) is a half turn about x, as (1, 1, 0, 0) is
    local s = math.sqrt(0.5)
    for _, scale in ipairs({ 1e200, 1e-3, 1, 3e307 }) do
      local q = { w = scale, x = scale, y = 0, z = 0 }
      for _, ext in ipairs(FORMATS) do
        local path = dir .. "/q." .. ext
        assert(tagpose.layout.write(path, { tags = { [0] = tag(0, q) } }))
        local back = assert(tagpose.layout.read(path)).tags[0].quaternion
        assert.quaternion_near({ w = s, x = s, y = 0, z = 0 }, back, 1e-15, scale .. " " .. ext)
      end
      -- read as it is written, used normalised
      local path = file("q.csv", HEAD .. ("0,0.03,0,0,0,%.17g,%.17g,0,0\n"):format(scale, scale))
      local read = assert(tagpose.layout.read(path))
      assert.equal(scale, read.tags[0].quaternion.w)
      assert(tagpose.layout.write(dir .. "/again.lua", read))
      local back = assert(tagpose.layout.read(dir .. "/again.lua")).tags[0].quaternion
      assert.quaternion_near({ w = s, x = s, y = 0, z = 0 }, back, 1e-15, scale .. " read")
    end
    for _, q in ipairs({ "0,0,0,1e-7", "1e-200,1e-200,0,0", "0,0,0,0" }) do
      local none, why = tagpose.layout.read(file("zero.csv", HEAD .. "0,0.03,0,0,0," .. q .. "\n"))
      assert.is_nil(none)
      assert.matches("zero.csv:2: tags%[0%].quaternion: zero quaternion", why)
    end
  end)

  it("read CSV numbers as a corner log's: decimal, as many fields as the header", function()
    local cases = {
      { "hex.csv", HEAD .. "0x10,0.03,0,0,0,1,0,0,0\n", "hex.csv:2: column id is not a number" },
      { "hexq.csv", HEAD .. "1,0.03,0,0,0,0x1,0,0,0\n", "hexq.csv:2: column qw is not a number" },
      { "inf.csv", HEAD .. "1,0.03,inf,0,0,1,0,0,0\n", "inf.csv:2: column x is not a number" },
      { "space.csv", HEAD .. "1,0.03,1 2,0,0,1,0,0,0\n", "space.csv:2: column x is not a number" },
      { "quote.csv", HEAD .. '1,0.03,"1",0,0,1,0,0,0\n', "quote.csv:2: column x is not a number" },
      { "more.csv", HEAD .. "1,0.03,0,0,0,1,0,0,0,7\n", "more.csv:2: 10 fields, header has 9" },
      { "less.csv", HEAD .. "1,0.03,0,0,0,1,0,0\n", "less.csv:2: 8 fields, header has 9" },
      { "range.csv", HEAD .. "1,0.03,1e999,0,0,1,0,0,0\n", "range.csv:2: tags%[1%].position" },
      { "twice.csv", "id,size,x,y,z,qw,qx,qy,qz,x\n", "twice.csv:1: header names column x twice" },
      { "empty.csv", "id,size,x,y,z,qw,qx,qy,qz,\n", "empty.csv:1: header column 10 has no name" },
    }
    for _, c in ipairs(cases) do
      local none, why = tagpose.layout.read(file(c[1], c[2]))
      assert.is_nil(none, c[1])
      assert.matches(c[3], why, 1, false, c[1])
    end
    -- what a spreadsheet saves: a byte-order mark, CRLF, spaces around fields, a comment, a
    -- column of notes (named in the header, so ignored)
    local ok = assert(tagpose.layout.read(file("ok.csv", "\239\187\191id,size,x,y,z,qw,qx,qy,qz,"
      .. "note\r\n# glued\r\n 7 , 0.03,-1.5e-2,0,0,1,0,0,0,left\r\n")))
    assert.equal(-0.015, ok.tags[7].position.x)
  end)

  it("write names that their format reads back as they were", function()
    local names = { "cube 1", "a'b\"c\\d", "two\nlines", "tab\there\r\0end",
      "caf\195\169 \226\130\172", "[x]: {y}, #z & *w" }
    for _, name in ipairs(names) do
      for _, ext in ipairs({ "lua", "yaml" }) do
        local path = dir .. "/name." .. ext
        assert(tagpose.layout.write(path, { name = name, tags = { [3] = tag(0) } }))
        local back, why = tagpose.layout.read(path)
        assert.is_table(back, why)
        assert.equal(name, back.name, ext)
      end
    end
    local path = file("name.yaml", "unchanged")
    local none, why = tagpose.layout.write(path, { name = "\255bad", tags = { [3] = tag(0) } })
    assert.is_nil(none)
    assert.matches("not UTF%-8", why)
    assert.equal("unchanged", run.read(path))
  end)

  it("refuse a file larger than MAX_BYTES without reading it", function()
    local io_layout = require("tagpose.formats.layout")
    local path = dir .. "/large.csv"
    local f = assert(io.open(path, "w"))
    f:write(HEAD)
    local line = "1,0.03,0,0,0,1,0,0,0\n"
    f:write(line:rep(math.floor(io_layout.MAX_BYTES / #line) + 1))
    f:close()
    local none, why = tagpose.layout.read(path)
    assert.is_nil(none)
    assert.equal("layout: " .. path .. ": larger than " .. io_layout.MAX_BYTES .. " bytes (a"
      .. " layout of thousands of tags is smaller)", why)
  end)

  it("write a file whole or not at all, and leave no temporary file", function()
    local layout = { tags = { [0] = tag(0), [1] = tag(1) } }
    for _, ext in ipairs(FORMATS) do
      local path = file("whole." .. ext, "old")
      assert(tagpose.layout.write(path, layout))
      assert.same(assert(tagpose.layout.read(path)).tags[1].position, tag(1).position)
      -- a name a CSV cannot hold is dropped, a name of another type refused
      local none, why = tagpose.layout.write(path, { name = {}, tags = layout.tags })
      assert.is_nil(none)
      assert.matches("name: string expected", why)
      assert.same({ "whole." .. ext }, listed("whole." .. ext))
    end
    -- a directory that does not exist, a directory as the file
    local none, why = tagpose.layout.write(dir .. "/missing/x.csv", layout)
    assert.is_nil(none)
    assert.matches("^layout: .*missing/x.csv: ", why)
    none, why = tagpose.layout.write(dir, layout)
    assert.is_nil(none)
    assert.matches("%.lua, %.yaml, %.yml or %.csv expected", why)
    os.execute("mkdir -p " .. run.quote(dir .. "/d.csv"))
    none, why = tagpose.layout.write(dir .. "/d.csv", layout)
    assert.is_nil(none)
    assert.matches("d.csv: ", why)
  end)
end)
