--- Files written whole or not at all, and streams written through: every file tagpose writes
-- goes to a temporary file beside its target and is renamed onto it once everything was
-- written and closed, so that a failure at any point (a full disk, an error in the data, a
-- killed process) leaves the old file as it was; a target that is not a regular file (a
-- device such as /dev/null, a FIFO, a pipe, a terminal, after following symbolic links) is
-- written through, in place: it is opened once and written, never replaced.
--
-- * The temporary file is in the target's directory (a rename within one file system
--   replaces the target at once), named `.NAME.tagpose-XXXXXXXX.tmp` after the target, with a
--   suffix that is tried until no file of that name exists; it is removed on every failure.
-- * `open` finds what can be found before any work: a target that is a directory or a file
--   that may not be written (permissions are respected, not worked around by the rename), a
--   directory that does not exist or may not be written.
-- * A rename replaces the target's directory entry: a symbolic link named as the target is
--   replaced by the file, not followed, and the new file has the permissions of a new file.
-- * Where a rename cannot replace an existing file (Windows), the old file is first renamed
--   aside and put back if the new one cannot take its place.
--
-- Which targets are written through. Pure Lua has no `stat`, and a target is never opened for
-- reading (a FIFO would block until a writer came, and a probe read would wait on a pipe or
-- a terminal for ever), so the kind is told with what `io.open` and `seek` say:
--
-- * `io.open(PATH .. "/")` resolves the path, links followed, without opening what it names:
--   it opens a directory (refused), says "Not a directory" of anything else that exists and
--   "No such file" of a new name (then confirmed with a plain open, for systems where a
--   trailing slash says nothing: Windows, which has no FIFOs).
-- * An existing target is opened once, in append mode (`"ab"`: never truncated, never
--   created), and asked to seek to byte 1. A regular file goes there; a FIFO, a pipe, a
--   terminal or a socket cannot seek, and Linux keeps /dev/null, /dev/zero and /dev/full at 0
--   (measured on Lua 5.1 to 5.4 and LuaJIT). A regular file is closed unwritten and takes the
--   temporary file's route; anything else is written through that one handle (so that a
--   FIFO's reader sees one writer, opened once, and its end of file when it is closed).
--   Not `"wb"`: it would empty a regular file before it is known to be one. Not `"r+b"`
--   (which does not wait on a FIFO on Linux): it makes the writer a reader too, so that with
--   no reader what is written is lost at the close, and a reader that goes away leaves the
--   writer waiting on a full pipe for ever instead of ending it (both measured).
-- * A name in /dev itself (`/dev/null`, `/dev/stdout`), under `/dev/fd/` or under `/proc/` is
--   always written through, appended to, even when it leads to a regular file
--   (`--out /dev/stdout > poses.csv`): those names are the system's, for devices and for what
--   a process has open, and a rename would replace the system's entry (or fail in /proc). It
--   also covers systems whose devices seek as files do.
--
-- Opening a FIFO for writing waits for its reader, as any writer of a FIFO does; a reader
-- that goes away ends the process by SIGPIPE, as it ends any Unix filter (status 141 in the
-- shell), unless SIGPIPE is ignored: the write then fails with "Broken pipe". A device
-- elsewhere that seeks as a file does (a block device) takes the regular file's route. A
-- target written through is not undone by `abort` or a failure: what was written has gone.
--
-- And files read whole up to a size (`read_text`: a file larger is refused unread).
--
-- Errors are `nil, "PATH: reason"` (the file's path: the caller adds its module's name).
-- This module does file I/O, so it is for reading and writing files, never for the solve path.
-- @module tagpose.formats.output

local M = {}

--- The errno of a file that does not exist (the same on Linux, the BSDs, macOS and Windows).
local ENOENT = 2

local counter = 0

-- A suffix for a temporary name: the process's table addresses, clock and a counter (two
-- processes or two writers rarely draw the same; a name that exists is never used).
local function suffix()
  counter = counter + 1
  local address = tostring({}):match("0x(%x+)") or tostring({}):match("(%x+)$") or ""
  local mix = (tonumber(address:sub(-7), 16) or 0) + counter * 7919
    + math.floor(os.clock() * 1e6) + os.time()
  return ("%08x"):format(mix % 4294967296)
end

-- True when a file exists at path (an error other than "no such file" counts as existing).
local function exists(path)
  local f, _, code = io.open(path, "rb")
  if f then
    f:close()
    return true
  end
  return code ~= ENOENT
end

-- The message of an io error about `name`, told about `path` instead.
local function reason(err, name, path)
  err = tostring(err)
  if name and err:sub(1, #name + 2) == name .. ": " then err = err:sub(#name + 3) end
  return path .. ": " .. err
end

-- The errno of a path whose directory part names something that is not a directory (Linux,
-- the BSDs, macOS).
local ENOTDIR = 20

-- Where the probe asks a target to seek: a regular file goes there, a device or a stream not.
local PROBE = 1

-- True for the names of the system's devices and of a process's open streams (`/dev/NAME`,
-- `/dev/fd/N`, anything in /proc), written through whatever they lead to.
local function is_system_name(path)
  local p = path:gsub("//+", "/")
  while p:find("/%./") do p = p:gsub("/%./", "/") end
  return p:match("^/dev/[^/]+$") ~= nil or p:match("^/dev/fd/") ~= nil
    or p:match("^/proc/") ~= nil
end

-- What the target is, without opening it for reading: `"new"`; `"file"` (a regular file that
-- may be written); `"stream", handle` (anything else, opened in append mode: written
-- through); or nil and why.
local function probe(path)
  local d, _, dcode = io.open(path .. "/", "rb")
  if d then
    d:close()
    return nil, path .. ": Is a directory"
  end
  if dcode ~= ENOTDIR then
    -- nothing there (or a system where a trailing slash says nothing: no FIFOs there)
    local f, err, code = io.open(path, "rb")
    if not f then
      if code == ENOENT then return "new" end
      return nil, reason(err, path, path)
    end
    f:close()
  end
  local w, werr = io.open(path, "ab") -- it exists: neither truncated nor created
  if not w then return nil, reason(werr, path, path) end
  if not is_system_name(path) and w:seek("set", PROBE) == PROBE then
    w:close()
    return "file"
  end
  return "stream", w
end

local Output = {}
Output.__index = Output

--- Open a file to be written whole: its temporary file is created now; a target that is not
-- a regular file is opened to be written through.
-- @tparam string path the target
-- @treturn table the output: `write(...)` (strings, as `file:write`), `commit()`, `abort()`,
--   `path`, `temporary` (nil when written through), `through` (true when written through)
-- @return nil, string `"PATH: reason"` when it cannot be written
function M.open(path)
  if type(path) ~= "string" or path == "" then return nil, "output: a file name expected" end
  local kind, handle = probe(path)
  if not kind then return nil, handle end
  if kind == "stream" then
    return setmetatable({ path = path, f = handle, through = true, err = nil }, Output)
  end
  local dir, name = path:match("^(.*[/\\])([^/\\]*)$")
  if not dir then dir, name = "", path end
  local tmp, f, err
  for _ = 1, 100 do
    tmp = dir .. "." .. name .. ".tagpose-" .. suffix() .. ".tmp"
    if not exists(tmp) then
      f, err = io.open(tmp, "wb")
      if not f then return nil, reason(err, tmp, path) end
      break
    end
  end
  if not f then return nil, path .. ": no free name for a temporary file beside it" end
  return setmetatable({ path = path, temporary = tmp, f = f, err = nil }, Output)
end

--- Write strings to the file; the first error is kept (`commit` reports it).
-- @param ... strings or numbers
-- @treturn boolean|nil true, or nil and the error
-- @treturn string the error
function Output:write(...)
  if self.err then return nil, self.err end
  if not self.f then
    self.err = self.path .. ": already closed"
    return nil, self.err
  end
  local ok, err = self.f:write(...)
  if not ok then
    self.err = reason(err, self.temporary or self.path, self.path)
    return nil, self.err
  end
  return true
end

--- Close and remove the temporary file; the target is left as it was (a target written
-- through is closed: what was written to it has gone).
function Output:abort()
  if self.f then
    self.f:close()
    self.f = nil
  end
  if self.temporary then
    os.remove(self.temporary)
    self.temporary = nil
  end
end

-- Rename tmp onto path; where the system refuses to replace a file, move the old one aside
-- first and put it back on failure.
local function replace(tmp, path)
  local ok, err = os.rename(tmp, path)
  if ok then return true end
  if not exists(path) then return nil, err end
  local aside
  for _ = 1, 100 do
    aside = path .. ".tagpose-" .. suffix() .. ".old"
    if not exists(aside) then break end
  end
  local moved = os.rename(path, aside)
  if not moved then return nil, err end
  ok, err = os.rename(tmp, path)
  if not ok then
    os.rename(aside, path)
    return nil, err
  end
  os.remove(aside)
  return true
end

-- Close a target written through: the first error of a write, the flush or the close.
local function close_through(self)
  local f, err = self.f, self.err
  if not f then return nil, err or (self.path .. ": already closed") end
  self.f = nil
  if not err then
    local ok, ferr = f:flush()
    if not ok then err = reason(ferr, self.path, self.path) end
  end
  local ok, cerr = f:close()
  if not ok and not err then err = reason(cerr, self.path, self.path) end
  self.err = err
  if err then return nil, err end
  return true
end

--- Close the file and put it in place of the target (a target written through is closed).
-- @treturn true
-- @return nil, string `"PATH: reason"` when anything failed (a write, the close, the rename):
--   the temporary file is removed and the target left as it was (a target written through
--   keeps what was written)
function Output:commit()
  if self.through then return close_through(self) end
  if not self.temporary then return nil, self.err or (self.path .. ": already closed") end
  local err = self.err
  if not err then
    local ok, cerr = self.f:close()
    self.f = nil
    if not ok then err = reason(cerr, self.temporary, self.path) end
  end
  if not err then
    local ok, rerr = replace(self.temporary, self.path)
    if ok then
      self.temporary = nil
      return true
    end
    err = reason(rerr, self.temporary, self.path)
  end
  self.err = err
  self:abort()
  return nil, err
end

--- Write a whole file at once (`open`, `write`, `commit`).
-- @tparam string path
-- @tparam string text
-- @treturn true
-- @return nil, string `"PATH: reason"`
function M.write(path, text)
  local out, err = M.open(path)
  if not out then return nil, err end
  out:write(text)
  return out:commit()
end

--- Read a whole file of at most `max_bytes` bytes (no more than `max_bytes + 1` are read).
-- @tparam string path
-- @tparam int max_bytes
-- @tparam string hint said of a file larger: `"PATH: larger than N bytes (HINT)"`
-- @treturn string the file's text
-- @return nil, string `"PATH: reason"`
function M.read_text(path, max_bytes, hint)
  local f, err = io.open(path, "rb")
  if not f then return nil, tostring(err) end
  local text, rerr = f:read(max_bytes + 1)
  f:close()
  if text == nil then
    if rerr then return nil, path .. ": " .. tostring(rerr) end
    text = ""
  end
  if #text > max_bytes then
    return nil, path .. ": larger than " .. max_bytes .. " bytes (" .. hint .. ")"
  end
  return text
end

return M
