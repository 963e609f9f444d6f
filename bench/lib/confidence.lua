--- What the confidence benches share (bench/confidence_sets.lua, bench/fit_confidence.lua,
-- bench/track_pool.lua, bench/real_noise.lua): their command line, the data sets a command
-- names, and the expected calibration error of a confidence. A bench script loads it with
--
--   package.path = "./src/?.lua;./src/?/init.lua;./bench/lib/?.lua;" .. package.path
--   local bench = require("confidence")
--
-- (run from the repository root, as the scripts are).

local floor, abs = math.floor, math.abs

local M = {}

--- The command line `args`: each argument that `options` names is handed to its function with
-- `take` (the next argument, or nil when there is none); any other `--` argument is refused with
-- `usage`; the rest are the directories, returned in order.
function M.arguments(args, options, usage)
  local dirs, i = {}, 1
  local function take()
    i = i + 1
    return args[i]
  end
  while i <= #args do
    local a = args[i]
    if options[a] then
      options[a](take)
    elseif a:sub(1, 2) == "--" then
      usage("unknown option " .. a)
    else
      dirs[#dirs + 1] = a
    end
    i = i + 1
  end
  return dirs
end

--- The option `--set NAME=VALUE`: sets the number `module[NAME]` (a module's constant, for
-- measuring it), or refuses with `usage`.
function M.set_constant(module, usage)
  return function(take)
    local name, value = (take() or ""):match("^([%u_%d]+)=([-%d.eE+]+)$")
    if not name or type(module[name]) ~= "number" then
      usage("--set NAME=NUMBER (a tagpose.track constant)")
    end
    module[name] = tonumber(value)
  end
end

function M.exists(path)
  local f = io.open(path, "r")
  if f then f:close() end
  return f ~= nil
end

--- The data sets named: each DIR that holds a corners.csv, else its subdirectories (in name
-- order) that hold a set of tag poses: corners.csv, truth.csv and camera.lua (not a drive log
-- of robot poses, which has no camera.lua).
function M.sets(dirs)
  local out = {}
  for _, dir in ipairs(dirs) do
    dir = dir:gsub("/*$", "")
    if M.exists(dir .. "/corners.csv") then
      out[#out + 1] = dir
    else
      local p = io.popen('ls -1 "' .. dir .. '"')
      local names = {}
      for name in p:lines() do names[#names + 1] = name end
      p:close()
      table.sort(names)
      for _, name in ipairs(names) do
        local sub = dir .. "/" .. name
        if M.exists(sub .. "/truth.csv") and M.exists(sub .. "/camera.lua")
          and M.exists(sub .. "/corners.csv") then
          out[#out + 1] = sub
        end
      end
    end
  end
  return out
end

--- The expected calibration error (10 equal bins of confidence) of the confidences
-- c[i0..i1] (default all) with the outcomes y (true: right), and of those at 0.95 or more how
-- many are wrong and how many there are.
function M.calibration(c, y, i0, i1)
  i0, i1 = i0 or 1, i1 or #c
  local sum, hits = {}, {}
  for b = 1, 10 do sum[b], hits[b] = 0, 0 end
  local high, wrong = 0, 0
  for i = i0, i1 do
    local b = c[i] >= 1 and 10 or floor(c[i] * 10) + 1
    sum[b] = sum[b] + c[i]
    if y[i] then hits[b] = hits[b] + 1 end
    if c[i] >= 0.95 then
      high = high + 1
      if not y[i] then wrong = wrong + 1 end
    end
  end
  local e = 0
  for b = 1, 10 do e = e + abs(hits[b] - sum[b]) end
  return e / math.max(i1 - i0 + 1, 1), wrong, high
end

return M
