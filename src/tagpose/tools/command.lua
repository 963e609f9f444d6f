--- The command line of the workstation commands (tagpose-replay, tagpose-calibrate,
-- tagpose-localize): their ways out, their options reader, their `main` and their inputs (the
-- corner log, opened before the camera file beside it is looked for).
--
-- A command is made with `new(name, usage, spec)`. Its ways out are raised as `EXIT` tables
-- `{status =, text =}` (the text for standard error, each line after `NAME: `) and caught by
-- its `main`: `usage` (status 2, with the usage), `refuse` (status 2: an output that is an
-- input), `fail` (status 1: a file cannot be read or written) and `help` (status 0, the help
-- on standard output).
--
-- Its options are a table (`spec.options`), one entry an option: `name` (`"--fps"`), `kind`
-- (what its value is, read by `KINDS`: `flag`, `string`, `choice`, `number`, `integer`,
-- `size`, `sizes`, `time`, `length`, `angle`, `list`), `meta` (the value's name in the help),
-- `default` (set when the option is not given; `default_text` says it in the help when it is
-- not a value),
-- `help` (one sentence or more), `key` (the field it sets, default the name's words joined
-- by `_`), `check(value, unit)` (what is wrong with a value read, as `... expected`), `set`
-- (fields set with it), and per kind `choices`, `min`, `max`, `count`, `what`, `bare`.
-- `parse` reads every command line the same way: `--name value` and `--name=value`, `--help`
-- (generated from the table: every option with its default), `--version` (tagpose's
-- version), an unknown option named with the nearest known one (`--trak`: did you mean
-- --track?), a value checked by its kind (a usage error naming the option and what it
-- expects).
--
-- Sizes take a unit everywhere (`24mm`, `0.024m`, `1in`; `UNITS`): `size` reads one, `sizes`
-- a comma-separated list (`22.9mm,54.8mm`), `convert` moves a length between two units.
--
-- A workstation tool's helper, for the commands of bin/.
-- @module tagpose.tools.command

local compat = require("tagpose.core.compat")
local core_args = require("tagpose.core.args")
local files = require("tagpose.tools.files")
local output = require("tagpose.formats.output")

local huge = math.huge

local M = {}

--- The metatable of the ways out.
M.EXIT = {}

local EXIT = M.EXIT

local function leave(status, text)
  error(setmetatable({ status = status, text = text }, EXIT), 0)
end

--- The arguments of command C, read one at a time: `next()` (the next, nil after the last),
-- `peek()` (the one after, not taken) and `value(name)` (the value of option `name`: a usage
-- error when there is none or it is an option).
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
  return A
end

--- A library message with its corner-order hint in the commands' words: the option of the
-- call (`options.order = 'opencv'`, `{order = 'opencv'} in tagpose.tracker.new(...)`) becomes
-- `--order opencv`.
-- @tparam string text
-- @treturn string
function M.order_hint(text)
  return (text:gsub("options%.order = 'opencv'", "--order opencv")
    :gsub("{order = 'opencv'} in [%w_.:]+%b()", "--order opencv"))
end

--- Length units a size may carry, in metres.
M.UNITS = { m = 1, cm = 0.01, mm = 0.001, ["in"] = 0.0254, ft = 0.3048 }

--- Sizes are numbers from this...
M.MIN_SIZE = 1e-12
--- ... to this (in their unit), as the library takes them.
M.MAX_SIZE = 1e12

--- A size with its optional unit: `"24mm"` gives 24, `"mm"`; `"0.024"` gives 0.024, nil.
-- @tparam string text
-- @treturn number|nil the size (nil when `text` is not a size with a known unit)
-- @treturn string|nil the unit, when given
function M.size(text)
  local num, unit = text:match("^%s*(.-)%s*(%a*)%s*$")
  local x = compat.decimal(num or "")
  if not (x and x >= M.MIN_SIZE and x <= M.MAX_SIZE) then return nil end
  if unit == "" then return x, nil end
  if not M.UNITS[unit] then return nil end
  return x, unit
end

--- A length moved from one unit of `UNITS` to another.
-- @tparam number x
-- @tparam string from
-- @tparam string to
-- @treturn number
function M.convert(x, from, to)
  if from == to then return x end
  return x * M.UNITS[from] / M.UNITS[to]
end

local UNIT_NAMES = "m, cm, mm, in, ft"

--- Sizes given without a unit where the command reads them as metres are refused above this:
-- a tag metres wide is millimetres without their unit (corners a few dozen pixels apart then
-- put the camera hundreds of metres or kilometres away).
M.MAX_BARE_METRES = 1

--- The usage message for sizes given without their unit (`value`, the option's text) that
-- the command reads as metres, when the largest tag side is more than `MAX_BARE_METRES`.
-- @tparam string option `--cube`
-- @tparam string value `22.9,54.8`
-- @tparam number tag the tag's side, in metres
-- @treturn string|nil
function M.bare_metres(option, value, tag)
  if tag <= M.MAX_BARE_METRES then return nil end
  return ("%s %s has no unit and reads as metres: a tag %.10g m wide? Give the unit (%s)")
    :format(option, value, tag, value:gsub("%s*,%s*", "mm,") .. "mm")
end

--- How each kind of option reads its value: `read(o, v, bad)` returns what the option sets
-- (and a unit for `size`), or calls `bad(what, note)`, `what` being what was expected (the
-- message: `--NAME: WHAT expected, got V NOTE`).
M.KINDS = {}

local KINDS = M.KINDS

function KINDS.string(_, v) return v end

function KINDS.choice(o, v, bad)
  for _, c in ipairs(o.choices) do
    if v == c then return v end
  end
  bad(table.concat(o.choices, " or "))
end

-- a decimal number within [o.min, o.max] (default: positive and finite)
function KINDS.number(o, v, bad)
  local x = compat.decimal(v)
  local lo, hi = o.min, o.max or huge
  if x and (lo and x >= lo or not lo and x > 0) and x <= hi and x < huge then return x end
  bad(o.what or lo and ("a number from %g to %g"):format(lo, hi) or "positive number")
end

function KINDS.integer(o, v, bad)
  local x = compat.decimal(v)
  if x and x == math.floor(x) and x >= (o.min or 1) and x <= (o.max or 2 ^ 53) then return x end
  bad(o.what or "positive integer")
end

function KINDS.size(_, v, bad)
  local x, unit = M.size(v)
  if not x then
    bad("positive number (with an optional unit " .. UNIT_NAMES .. ")", compat.decimal(v)
      and ("(sizes are from %g to %g)"):format(M.MIN_SIZE, M.MAX_SIZE) or nil)
  end
  return x, unit
end

-- sizes separated by commas, each with its optional unit: the numbers in the first unit
-- given (converted), and that unit
function KINDS.sizes(o, v, bad)
  local xs, units, unit = {}, {}, nil
  for part in (v .. ","):gmatch("([^,]*),") do
    local x, u = M.size(part)
    if not x then break end
    xs[#xs + 1], units[#xs + 1] = x, u
    unit = unit or u
  end
  if #xs ~= (o.count or #xs) or #xs == 0 or select(2, v:gsub(",", "")) ~= #xs - 1 then
    bad(o.what or "sizes separated by commas")
  end
  for i = 1, #xs do
    if units[i] and units[i] ~= unit then xs[i] = M.convert(xs[i], units[i], unit) end
  end
  return xs, unit
end

-- a time with its unit, in seconds
function KINDS.time(o, v, bad)
  local num, unit = v:match("^%s*(.-)%s*(m?s)%s*$")
  local x = num and compat.decimal(num)
  if not (x and x >= 0 and x < huge) then
    bad("a time with its unit (0.5s, 500ms)", compat.decimal(v) and o.bare or nil)
  end
  return unit == "ms" and x / 1000 or x
end

-- A standard deviation with its unit (`units`: their factors), or 0: no bare number, so that
-- millimetres are never read as metres nor degrees as radians.
local function spread(v, units, what, bad)
  local num, unit = v:match("^%s*(.-)%s*(%a*)%s*$")
  local x = num and compat.decimal(num)
  if x == 0 and (unit == "" or units[unit]) then return 0 end
  if not (x and x > 0 and x < huge and units[unit]) then bad(what .. ", or 0") end
  return x * units[unit]
end
local ANGLES = { deg = math.pi / 180, rad = 1 }

-- a length with its unit, in metres; an angle with its unit (deg, rad), in radians
function KINDS.length(_, v, bad)
  return spread(v, M.UNITS, "a length with its unit (" .. UNIT_NAMES .. ")", bad)
end
function KINDS.angle(_, v, bad)
  return spread(v, ANGLES, "an angle with its unit (0.5deg, 0.0087rad)", bad)
end

-- the option's field in the table `parse` returns
local function key_of(o)
  return o.key or o.name:sub(3):gsub("-", "_")
end

-- words wrapped to `width` columns after `first`, each line after the first indented by
-- `indent`
local function wrap(text, indent, first, width)
  local lines, line, fresh = {}, first, true
  for word in text:gmatch("%S+") do
    if not fresh and #line + 1 + #word > width then
      lines[#lines + 1] = line
      line, fresh = indent, true
    end
    line, fresh = line .. (fresh and "" or " ") .. word, false
  end
  lines[#lines + 1] = line
  return table.concat(lines, "\n")
end

-- the help of a command: the usage, what it does, each argument and option with its default
local function help_text(C, spec)
  local out = { C.USAGE }
  if spec.about then out[#out + 1] = "\n" .. wrap(spec.about, "", "", 79) .. "\n" end
  local COLUMN = 24
  local function entry(head, text)
    local first, indent = "  " .. head, (" "):rep(COLUMN)
    if #first + 1 < COLUMN then
      first = first .. (" "):rep(COLUMN - #first)
    else
      out[#out + 1] = first .. "\n"
      first = indent
    end
    out[#out + 1] = wrap(text, indent, first, 79) .. "\n"
  end
  out[#out + 1] = "\n"
  for _, a in ipairs(spec.arguments or {}) do entry(a.name, a.help) end
  for _, o in ipairs(spec.options) do
    local text = o.help
    local default = o.default_text or (o.default ~= nil and tostring(o.default))
    if default then text = text .. " (default: " .. default .. ")" end
    entry(o.name .. (o.meta and " " .. o.meta or ""), text)
  end
  entry("--help, -h", "print this help and exit")
  entry("--version", "print the version of tagpose and exit")
  return table.concat(out)
end

-- the nearest known option to an unknown one (`tagpose.core.args.nearest`)
local function nearest(name, options)
  local names = {}
  for i, o in ipairs(options) do names[i] = o.name end
  return core_args.nearest(name, names)
end

--- A command's frame.
-- @tparam string name what its messages start with (`"replay"`: `replay: ...`)
-- @tparam string usage its usage lines
-- @tparam[opt] table spec `{about =, arguments = {{name =, key =, help =}}, options = {...}}`
--   (see the module's header): what `parse` reads and `help` prints
-- @treturn table `{name =, USAGE =, usage(msg), refuse(msg), fail(msg), help(), version(),
--   parse(argv), inputs(opt, missing), output(open, path, what), main(run, argv)}`
--   (functions, not methods)
function M.new(name, usage, spec)
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

  --- Leave with status 0 after writing the help to standard output (`--help`): the usage,
  -- then every argument and option with its default.
  function C.help()
    io.stdout:write(spec and help_text(C, spec) or usage)
    leave(0, "")
  end

  --- Leave with status 0 after writing the command's name and tagpose's version.
  function C.version()
    io.stdout:write("tagpose-", name, " (", require("tagpose")._VERSION, ")\n")
    leave(0, "")
  end

  -- one option of the command line (`a` the argument, `value()` the next one): into opt
  local function read_option(opt, a, value, more)
    local oname, inline = a:match("^(%-%-[^=]+)=(.*)$")
    oname = oname or a
    local o
    for _, x in ipairs(spec.options) do
      if x.name == oname then o = x end
    end
    if not o then
      local near = nearest(oname, spec.options)
      C.usage("unknown option " .. oname .. (near and " (did you mean " .. near .. "?)" or ""))
    end
    local key = key_of(o)
    opt.given[key] = true
    if o.kind == "flag" then
      if inline then C.usage(oname .. " takes no value, got " .. a) end
      opt[key] = true
    else
      local v = inline or value(oname)
      opt.given[key] = v
      if o.kind == "list" then
        local list = opt[key] or {}
        list[#list + 1] = v
        for w in more do list[#list + 1] = w end
        opt[key] = list
      else
        local x, unit = KINDS[o.kind](o, v, function(what, note)
          C.usage(oname .. ": " .. what .. " expected, got " .. v .. (note and " " .. note or ""))
        end)
        local problem = o.check and o.check(x, unit)
        if problem then C.usage(oname .. ": " .. problem .. ", got " .. v) end
        opt[key] = x
        opt[key .. "_unit"] = unit
      end
    end
    for k, v in pairs(o.set or {}) do opt[k] = v end
  end

  --- The command line read by the options of `spec`: `--name value`, `--name=value`, the
  -- argument (one), `--help` and `--version`; each option's default set when it is not given.
  -- @tparam {string,...} argv
  -- @treturn table the options by key, `given` (the text of each option given, `true` for a
  --   flag), the argument by its key
  -- @raise an `EXIT` for `--help`, `--version` and a usage error
  function C.parse(argv)
    local opt = { given = {} }
    local positional = spec.arguments[1]
    local args = arguments(C, argv)
    local function more()
      local w = args.peek()
      if w and w:sub(1, 2) ~= "--" then return args.next() end
    end
    for a in args.next do
      if a == "--help" or a == "-h" then
        C.help()
      elseif a == "--version" then
        C.version()
      elseif a:sub(1, 2) == "--" and #a > 2 then
        read_option(opt, a, args.value, more)
      elseif opt[positional.key] == nil then
        opt[positional.key] = a
      else
        C.usage("one " .. positional.what .. " expected, got " .. opt[positional.key] .. " and "
          .. a)
      end
    end
    if opt[positional.key] == nil then C.usage() end
    for _, o in ipairs(spec.options) do
      local key = key_of(o)
      if opt[key] == nil then
        if o.kind == "list" then opt[key] = {} else opt[key] = o.default end
      end
    end
    return opt
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

  --- An output opened (`tagpose.formats.output.open`) and kept in `open` for `main` to abort
  -- unless committed; one that cannot be opened is a failure naming the output (`what`, as
  -- `the plot (--svg)`), not one of the inputs.
  -- @tparam table open
  -- @tparam string path
  -- @tparam string what
  -- @treturn table the output
  function C.output(open, path, what)
    local out, err = output.open(path)
    if not out then C.fail(what .. ": " .. tostring(err)) end
    open[#open + 1] = out
    return out
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
