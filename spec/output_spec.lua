-- tagpose.formats.output: a file is written whole or not at all: the old file stays as it was
-- until the new one is complete, whatever fails, and no temporary file is left behind; a
-- target that is not a regular file (a device, a FIFO, a pipe, reached through links or not) is
-- written through, in place, and stays what it was.
--
-- The devices are reached through links in a scratch folder, never named: a writer that renamed
-- a file over its target would replace the link there, not the system's /dev/null. What might
-- wait for ever (a FIFO, a pipe: the writers of old opened them for reading) runs in a process
-- of its own under `timeout`.
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

-- a shell test (`-L`, `-p`, `-f`) of a path
local function is(flag, path)
  local _, status = run.run("test " .. flag .. " " .. run.quote(path))
  return status == 0
end

local HAS = {
  timeout = select(2, run.run("command -v timeout >/dev/null")) == 0,
  mkfifo = select(2, run.run("command -v mkfifo >/dev/null")) == 0,
  fd = is("-d", "/proc/self/fd"),
}

-- A shell command that runs a Lua chunk (the library on its path) with the spec's
-- interpreter, under `timeout` (10 s: a writer that waits for ever fails the spec, not the
-- suite), its standard error joined to the standard output; `redirect` ends the command.
local function chunk(code, redirect)
  return "timeout 10 " .. run.quote(run.lua()) .. " -e " .. run.quote(
    "package.path = './src/?.lua;./src/?/init.lua;' .. package.path " .. code)
    .. " " .. (redirect or "") .. " 2>&1"
end

-- the chunk that writes `text` to `path` with output.write and prints what it returned
local function writer(path, text)
  return chunk(("local output = require('tagpose.formats.output')"
    .. " print('wrote', output.write(%q, %q))"):format(path, text))
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

  describe("a target that is not a regular file", function()
    it("writes a device through a link, in place: the link stays a link", function()
      local null = dir .. "/null"
      run.run("ln -s /dev/null " .. run.quote(null))
      local out = assert(output.open(null))
      assert.is_true(out.through)
      assert.is_nil(out.temporary)
      assert.same({ "null" }, entries(), "no temporary file")
      assert.is_true(out:write(("row\n"):rep(1000)))
      assert.is_true(out:commit())
      assert.is_true(is("-L", null), "the link replaced by a file")
      assert.is_true(output.write(null, "text"))
      assert.is_true(is("-L", null))
      assert.same({ "null" }, entries())
    end)

    it("reports a device's failed write as a file's and leaves the link", function()
      if not io.open("/dev/full", "w") then return end -- Linux, the BSDs
      local full = dir .. "/full"
      run.run("ln -s /dev/full " .. run.quote(full))
      local ok, err = output.write(full, ("x"):rep(100000))
      assert.is_nil(ok)
      assert.equal(full .. ": No space left on device", err)
      assert.is_true(is("-L", full))
      assert.same({ "full" }, entries())
    end)

    it("writes a FIFO through to its reader, once, and leaves the FIFO", function()
      if not (HAS.timeout and HAS.mkfifo) then return end
      local fifo, got = dir .. "/fifo", dir .. "/got"
      run.run("mkfifo " .. run.quote(fifo))
      local text = ("frame,tag\n"):rep(10000) -- more than a pipe holds
      -- the reader first, then the writer
      local shown, status = run.run("timeout 10 cat " .. run.quote(fifo) .. " > "
        .. run.quote(got) .. " & " .. writer(fifo, text) .. "; wait")
      assert.equal(0, status, shown)
      assert.equal("wrote\ttrue\n", shown)
      assert.equal(text, run.read(got))
      assert.is_true(is("-p", fifo), "the FIFO replaced by a file")
      -- the writer first: it waits for its reader, as any writer of a FIFO does
      shown, status = run.run(writer(fifo, "late\n") .. " & sleep 0.2; timeout 10 cat "
        .. run.quote(fifo) .. " > " .. run.quote(got) .. "; wait")
      assert.equal(0, status, shown)
      assert.equal("late\n", run.read(got))
      assert.is_true(is("-p", fifo))
      assert.same({ "fifo", "got" }, entries())
    end)

    it("writes a pipe through (/dev/fd/N), never reading it", function()
      if not (HAS.timeout and HAS.fd) then return end
      local got = dir .. "/got"
      local shown, status = run.run("{ " .. writer("/dev/fd/3", "piped\n") .. " 3>&1 >"
        .. run.quote(dir .. "/said") .. "; } | cat > " .. run.quote(got))
      assert.equal(0, status, shown)
      assert.equal("piped\n", run.read(got))
      assert.equal("wrote\ttrue\n", run.read(dir .. "/said"))
    end)

    it("appends to a process's open file named in /proc or /dev/fd, never renaming", function()
      if not (HAS.timeout and HAS.fd) then return end
      local path = run.write(dir .. "/open.txt", "before\n")
      for _, name in ipairs({ "/proc/self/fd/3", "/dev/fd/3" }) do
        local shown, status = run.run(writer(name, name .. "\n") .. " 3>>" .. run.quote(path))
        assert.equal(0, status, shown)
        assert.equal("wrote\ttrue\n", shown)
      end
      assert.equal("before\n/proc/self/fd/3\n/dev/fd/3\n", run.read(path))
      assert.same({ "open.txt" }, entries())
    end)

    it("still replaces a regular file behind a link (the link, as before)", function()
      local path = run.write(dir .. "/real.txt", "old\n")
      run.run("ln -s real.txt " .. run.quote(dir .. "/link.txt"))
      assert.is_true(output.write(dir .. "/link.txt", "new\n"))
      assert.is_false(is("-L", dir .. "/link.txt"))
      assert.equal("new\n", run.read(dir .. "/link.txt"))
      assert.equal("old\n", run.read(path))
    end)
  end)

  it("is the one writer of files in the library and the commands", function()
    -- any other io.open for writing, os.rename or os.remove in src/ would be a second writer
    -- with its own idea of a device or a FIFO
    local listing = run.run("find src -name '*.lua' | sort")
    local found = {}
    for path in listing:gmatch("[^\n]+") do
      if path ~= "src/tagpose/formats/output.lua" then
        local n = 0
        for line in io.lines(path) do
          n = n + 1
          if line:find("io%.open%([^)]*,%s*[\"'][wa]") or line:find("io%.open%([^)]*%+")
              or line:find("os%.rename") or line:find("os%.remove") then
            found[#found + 1] = path .. ":" .. n .. ": " .. line
          end
        end
      end
    end
    assert.same({}, found)
  end)
end)
