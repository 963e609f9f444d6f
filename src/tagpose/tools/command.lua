--- The command line of the workstation commands (tagpose-replay, tagpose-calibrate): their
-- ways out, their option readers, their `main` and their inputs (the corner log, opened
-- before the camera file beside it is looked for).
--
-- A command is made with `new(name, usage)`. Its ways out are raised as `EXIT` tables
-- `{status =, text =}` (the text for standard error, each line after `NAME: `) and caught by
-- its `main`: `usage` (status 2, with the usage), `refuse` (status 2: an output that is an
-- input), `fail` (status 1: a file cannot be read or written) and `help` (status 0, the usage
-- on standard output).
--
-- A workstation tool's helper, for the commands of bin/.
-- @module tagpose.tools.command

local compat = require("tagpose.core.compat")
local files = require("tagpose.tools.files")

local huge = math.huge

local M = {}

--- The metatable of the ways out.
M.EXIT = {}

local EXIT = M.EXIT

local function leave(status, text)
  error(setmetatable({ status = status, text = text }, EXIT), 0)
end

local function positive_finite(x)
  return x > 0 and x < huge
end

--- The arguments of command C, read one at a time: `next()` (the next, nil after the last),
-- `peek()` (the one after, not taken), `value(name)` (the value of option `name`: a usage error
-- when there is none or it is an option), `number(name, check, what)` (the value a decimal
-- number for which `check` is true, else the usage error `NAME: WHAT expected, got V`) and
-- `positive(name)` (a positive finite number).
local function arguments(C, argv)
  local A, i = {}, 0
  function A.next()
    i = i + 1
    return argv[i]
  end
  function A.peek()
    return argv[i + 1]
  end
  function A.value(option)
    local v = A.next()
    if v == nil or (v:sub(1, 2) == "--" and #v > 2) then C.usage(option .. " needs a value") end
    return v
  end
  function A.number(option, check, what)
    local v = A.value(option)
    local x = compat.decimal(v)
    if not (x and check(x)) then C.usage(option .. ": " .. what .. " expected, got " .. v) end
    return x
  end
  function A.positive(option)
    return A.number(option, positive_finite, "positive number")
  end
  return A
end

--- A command's frame.
-- @tparam string name what its messages start with (`"replay"`: `replay: ...`)
-- @tparam string usage its usage lines
-- @treturn table `{name =, USAGE =, usage(msg), refuse(msg), fail(msg), help(),
--   args(argv), inputs(opt, missing), main(run, argv)}` (functions, not methods)
function M.new(name, usage)
  local C = { name = name, USAGE = usage }

  --- Leave with status 2: a usage error (`msg`, then the usage).
  function C.usage(msg)
    leave(2, (msg and name .. ": " .. msg .. "\n" or "") .. usage)
  end

  --- Leave with status 2 without the usage: a command line that names one file twice (an
  -- output that is one of the inputs).
  function C.refuse(msg)
    leave(2, name .. ": " .. msg .. "\n")
  end

  --- Leave with status 1: a file cannot be read or written.
  function C.fail(msg)
    leave(1, name .. ": " .. msg .. "\n")
  end

  --- Leave with status 0 after writing the usage to standard output (`--help`).
  function C.help()
    io.stdout:write(usage)
    leave(0, "")
  end

  --- The arguments, read one at a time (`arguments`).
  -- @tparam {string,...} argv
  -- @treturn table
  function C.args(argv)
    return arguments(C, argv)
  end

  --- The corner log, opened, and the camera file's path, in this order: a log that cannot be
  -- read is named as such (`fail`, `log: PATH: reason`), not as a missing camera file. The
  -- camera file is `opt.camera`, or camera.lua beside the log (a usage error, `missing`
  -- formatted with its path, when there is none).
  -- @tparam table opt `{log =, camera =}`
  -- @tparam string missing the message's format, `%s` the path
  -- @treturn file the log, open for reading (the caller closes it)
  -- @treturn string the camera file's path
  function C.inputs(opt, missing)
    local log, err = io.open(opt.log, "rb")
    if not log then C.fail("log: " .. tostring(err)) end
    if opt.camera then return log, opt.camera end
    local path = (opt.log:match("^(.*)/[^/]*$") or ".") .. "/camera.lua"
    if not files.exists(path) then
      log:close()
      C.usage(missing:format(path))
    end
    return log, path
  end

  --- Run the command: `run(argv, open)` returns its status or raises a way out; what it
  -- adds to `open` (outputs with `abort`) is aborted whatever happens (an output committed is
  -- not touched by its abort). A way out's text goes to standard error; an error that is not
  -- one is raised again.
  -- @tparam function run
  -- @tparam {string,...} argv
  -- @treturn int the exit status (1 when standard output could not be written)
  function C.main(run, argv)
    local open = {}
    local ok, status = pcall(run, argv, open)
    for i = #open, 1, -1 do open[i]:abort() end
    if ok then status = setmetatable({ status = status, text = "" }, EXIT) end
    if getmetatable(status) ~= EXIT then error(status, 0) end
    if status.status ~= 0 then
      io.stderr:write(status.text)
      return status.status
    end
    -- what was written to standard output (the summary, --help) reached it, or status 1
    local flushed, err = io.stdout:flush()
    if flushed then return 0 end
    io.stderr:write(name .. ": standard output: " .. tostring(err) .. "\n")
    return 1
  end

  return C
end

return M
