-- tagpose.formats.output: a file is written whole or not at all: the old file stays as it was
-- until the new one is complete, whatever fails, and no temporary file is left behind.
local output = require("tagpose.formats.output")
local run = require("support.run")

local dir = run.tmpdir()

local function entries()
  local out, names = run.run("ls -a " .. run.quote(dir)), {}
  for name in out:gmatch("[^\n]+") do
    if name ~= "." and name ~= ".." then names[#names + 1] = name end
  end
  table.sort(names)
  return names
end

local function clean()
  os.execute("rm -rf " .. run.quote(dir) .. "/* " .. run.quote(dir) .. "/.[!.]*")
end

describe("tagpose.formats.output", function()
  before_each(clean)

  it("replaces the file only when everything was written", function()
    local path = run.write(dir .. "/log.csv", "old\n")
    local out = assert(output.open(path))
    assert.equal(2, #entries(), "the temporary file beside the target")
    for i = 1, 1000 do assert.is_true(out:write(i, ",", "row\n")) end
    assert.equal("old\n", run.read(path))
    assert.is_true(out:commit())
    local text = run.read(path)
    assert.equal(1000, run.count(text, "row\n"))
    assert.same({ "log.csv" }, entries())
    -- a new file, and the one-shot form
    assert.is_true(output.write(dir .. "/new.txt", "text"))
    assert.equal("text", run.read(dir .. "/new.txt"))
    assert.same({ "log.csv", "new.txt" }, entries())
  end)

  it("leaves the old file as it was when a write, the close or the rename fails", function()
    local path = run.write(dir .. "/keep.csv", "old\n")
    -- aborted
    local out = assert(output.open(path))
    out:write("half")
    out:abort()
    assert.equal("old\n", run.read(path))
    assert.same({ "keep.csv" }, entries())
    -- a write that fails (a full disk): every later write and the commit report it
    out = assert(output.open(path))
    local real = out.f
    out.f = setmetatable({ write = function() return nil, "No space left on device" end,
      close = function() return real:close() end }, {})
    local ok, err = out:write("x")
    assert.is_nil(ok)
    assert.equal(path .. ": No space left on device", err)
    assert.is_nil((out:write("y")))
    ok, err = out:commit()
    assert.is_nil(ok)
    assert.equal(path .. ": No space left on device", err)
    assert.equal("old\n", run.read(path))
    assert.same({ "keep.csv" }, entries())
    -- a rename that fails (the temporary file taken away)
    out = assert(output.open(path))
    out:write("new")
    os.remove(out.temporary)
    ok, err = out:commit()
    assert.is_nil(ok)
    assert.matches("^" .. path:gsub("%p", "%%%0") .. ": ", err)
    assert.equal("old\n", run.read(path))
    assert.same({ "keep.csv" }, entries())
  end)

  it("refuses what it cannot write before any work", function()
    local cases = {
      { dir .. "/missing/x.csv", "missing/x.csv: No such file or directory" },
      { dir, ": Is a directory" },
      { "", "output: a file name expected" },
    }
    for _, c in ipairs(cases) do
      local out, err = output.open(c[1])
      assert.is_nil(out)
      assert.truthy(err:find(c[2], 1, true), err)
    end
    assert.same({}, entries())
  end)

  it("gives two writers of one file their own temporary files: the last commit wins", function()
    local path = dir .. "/both.txt"
    local a, b = assert(output.open(path)), assert(output.open(path))
    assert.are_not.equal(a.temporary, b.temporary)
    a:write(("a"):rep(100000))
    b:write(("b"):rep(10))
    assert.is_true(a:commit())
    assert.equal(100000, #run.read(path))
    assert.is_true(b:commit())
    assert.equal(("b"):rep(10), run.read(path))
    assert.same({ "both.txt" }, entries())
  end)
end)
