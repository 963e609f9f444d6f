--- The files of a command: which of them are one file, so that a command never writes over
-- what it reads.
--
-- Two names are one file when the file system says so, whatever the names: `log.csv` and
-- `./log.csv`, a symbolic link and its target, two hard links. Pure Lua has no `stat`, so the
-- system is asked, once per command, through `io.popen` and a POSIX shell: GNU `stat -L -c`
-- (Linux) or BSD `stat -L -f` (macOS, the BSDs) prints each file's device and inode (`-L`
-- follows links). Where neither answers (no shell, no `stat`, Windows), two names are one
-- file when they name the same path once `.` and `..` are resolved, or when both files exist
-- and hold the same bytes: one file always reads the same under both names, so no case of one
-- file is missed; two files that are byte-identical copies are then refused too (named as
-- such in the message). That fallback opens an existing output for reading to compare it: an
-- output that is a FIFO would wait there for a writer (Windows, where it runs, has none;
-- `stat` never opens a file).
--
-- A workstation tool's helper: the library never asks the system anything.
-- @module tagpose.tools.files

local M = {}

local CHUNK = 65536

-- A path quoted for a POSIX shell.
local function quote(path)
  return "'" .. path:gsub("'", "'\\''") .. "'"
end

--- The identity (`"device:inode"`) of each path, as the system's `stat` gives it: `false` for
-- a path that names no file, `nil` for all when the system cannot say.
-- @tparam {string,...} paths
-- @treturn {string|false,...}|nil
function M.identities(paths)
  if #paths == 0 then return {} end
  local quoted = {}
  for i, p in ipairs(paths) do quoted[i] = quote(p) end
  local list = table.concat(quoted, " ")
  local script = "if stat -L -c %i . >/dev/null 2>&1; then form=gnu;"
    .. " elif stat -L -f %i . >/dev/null 2>&1; then form=bsd; else echo unknown; exit; fi;"
    .. " for f in " .. list .. "; do if [ \"$form\" = gnu ];"
    .. " then stat -L -c %d:%i -- \"$f\" 2>/dev/null || echo -;"
    .. " else stat -L -f %d:%i -- \"$f\" 2>/dev/null || echo -; fi; done"
  local ok, pipe = pcall(io.popen, "sh -c " .. quote(script) .. " 2>/dev/null", "r")
  if not ok or not pipe then return nil end
  local out = pipe:read("*a") or ""
  pipe:close()
  local ids = {}
  for line in out:gmatch("[^\n]+") do
    if line == "-" then
      ids[#ids + 1] = false
    elseif line:match("^%d+:%d+$") then
      ids[#ids + 1] = line
    else
      return nil
    end
  end
  if #ids ~= #paths then return nil end
  return ids
end

-- The path with `.` and `..` resolved and repeated slashes merged, made absolute with $PWD
-- when relative (the name alone: links are not followed).
local function normal(path)
  if path:sub(1, 1) ~= "/" then path = (os.getenv("PWD") or ".") .. "/" .. path end
  local parts = {}
  for part in path:gmatch("[^/]+") do
    if part == ".." then
      if #parts > 0 then parts[#parts] = nil end
    elseif part ~= "." then
      parts[#parts + 1] = part
    end
  end
  return "/" .. table.concat(parts, "/")
end

-- True when two existing files hold the same bytes (read in chunks, up to the first
-- difference); false when either cannot be read.
local function same_bytes(a, b)
  local fa = io.open(a, "rb")
  if not fa then return false end
  local fb = io.open(b, "rb")
  if not fb then
    fa:close()
    return false
  end
  local same = fa:seek("end") == fb:seek("end")
  if same then
    fa:seek("set")
    fb:seek("set")
    while true do
      local x, y = fa:read(CHUNK), fb:read(CHUNK)
      if x ~= y then
        same = false
        break
      end
      if x == nil then break end
    end
  end
  fa:close()
  fb:close()
  return same
end

--- True when a file can be opened for reading (the one "does this file exist" of the tools).
-- @tparam string path
-- @treturn boolean
function M.exists(path)
  local f = io.open(path, "rb")
  if f then f:close() end
  return f ~= nil
end

local exists = M.exists

--- The first output that is one of the inputs, or another output, and why: `nil` when there
-- is none.
-- @tparam table inputs what the command reads: an array of `{name =, path =}` (`name` says
--   what it is, as `"the corner log"`); entries without a path are left out
-- @tparam table outputs what it writes, in the same form
-- @tparam[opt] table options `{stat = false}` to check as where the system cannot say
-- @treturn string|nil the reason, naming both
function M.clash(inputs, outputs, options)
  local all, paths = {}, {}
  for _, list in ipairs({ outputs, inputs }) do
    for _, f in ipairs(list) do
      if f.path then
        all[#all + 1] = f
        paths[#paths + 1] = f.path
      end
    end
  end
  local ids = nil
  if not (options and options.stat == false) then ids = M.identities(paths) end
  local nout = 0
  for _, f in ipairs(outputs) do
    if f.path then nout = nout + 1 end
  end
  for i = 1, nout do
    local out = all[i]
    for j = i + 1, #all do
      local other = all[j]
      local one, copy = false, false
      if ids and ids[i] then
        one = ids[i] == ids[j]
      elseif normal(out.path) == normal(other.path) then
        one = true -- also two outputs of one name that does not exist yet
      elseif not ids and exists(out.path) and same_bytes(out.path, other.path) then
        one, copy = true, true
      end
      if one then
        return out.name .. " " .. out.path .. " is " .. (j <= nout and "also " or "")
          .. other.name .. (other.path ~= out.path and " " .. other.path or "")
          .. (copy and " (or a copy of it, byte for byte)" or "") .. ": give another file"
      end
    end
  end
  return nil
end

return M
