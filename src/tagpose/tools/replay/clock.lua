--- The time of each frame tagpose-replay feeds the tracker, and the mistakes of time it
-- points out.
--
-- A frame's time is its first row's `time` column (seconds) when the log has one, else its
-- frame number over the frame rate (`--fps`, default 30). What it points out, on standard
-- error when first seen (with the line) and counted for the summary:
--
-- * steps far beyond the tracker's `max_gap` at a steady cadence (`tagpose.tracker`'s
--   warning): times in milliseconds, or frame numbers in the time column, or frame numbers
--   that count milliseconds; every frame would start new tracks;
-- * a fractional frame number in a log without a `time` column: seconds in the frame column
--   (the frame rate then makes steps of a few milliseconds);
-- * rows of a frame whose time is not their frame's first row's (the first is used);
-- * the time going back: the tracker ends every track (as a user's loop over it does).
-- @module tagpose.tools.replay.clock

local stats = require("tagpose.tools.replay.stats")

local floor = math.floor

local M = {}

--- The counts of a replay's clock.
-- @tparam table opt the command's options (`fps`)
-- @tparam boolean has_time the log has a `time` column
-- @tparam function warn writes one line to standard error
-- @treturn table `{has_time =, fps =, warn =, cadence = n, first_cadence =, fractional = n,
--   first_fractional =, mixed = n, first_mixed =, restarts = n, first_restart =}`
function M.new(opt, has_time, warn)
  return { has_time = has_time, fps = opt.fps, warn = warn, cadence = 0, fractional = 0,
    mixed = 0, restarts = 0, previous = nil }
end

--- The time (s) of a frame's rows (of one frame), as both passes of a replay feed it.
-- @tparam table clock
-- @tparam {table,...} group the rows, detections of `tagpose.tools.log.corner_reader`
-- @treturn number
function M.time_of(clock, group)
  local first = group[1]
  if clock.has_time then return first.time end
  return first.frame / clock.fps
end

-- a number in a warning: as the summary writes it, to 4 digits
local function number(v)
  return stats.number(v, 4)
end

-- the step between frames as the log gives it, and what it looks like
local function cadence_message(clock, line, dt, gap)
  if clock.has_time then
    return ("line %d: the time column steps by %s, steadily, far beyond the tracker's max gap"
      .. " (%s s): every frame starts new tracks. The time column is in seconds: are these"
      .. " milliseconds, or frame numbers?"):format(line, number(dt), number(gap))
  end
  return ("line %d: the frame numbers step by %s, %s s at %s frames per second (--fps),"
    .. " steadily, far beyond the tracker's max gap (%s s): every frame starts new tracks. Do"
    .. " the frame numbers count milliseconds? Give --fps (frame numbers per second), or a"
    .. " time column in seconds"):format(line, number(dt * clock.fps), number(dt),
    number(clock.fps), number(gap))
end

--- Check a frame's rows and what the tracker said of their time.
-- @tparam table clock
-- @tparam {table,...} group the rows
-- @tparam number time the frame's time (`time_of`)
-- @tparam table seen the tracker's entries (`restarted`, `warning`)
-- @tparam number gap the tracker's `max_gap` (s)
function M.check(clock, group, time, seen, gap)
  local line = group[1].line
  if seen.restarted then
    clock.restarts = clock.restarts + 1
    clock.first_restart = clock.first_restart or line
  end
  if seen.warning then
    if clock.cadence == 0 then
      clock.warn(cadence_message(clock, line, time - clock.previous, gap))
      clock.first_cadence = line
    end
    clock.cadence = clock.cadence + 1
  end
  clock.previous = time
  for k = 1, #group do
    local row = group[k]
    if clock.has_time then
      if row.time ~= time then
        clock.mixed = clock.mixed + 1
        clock.first_mixed = clock.first_mixed or row.line
      end
    elseif row.frame ~= floor(row.frame) then
      if clock.fractional == 0 then
        clock.warn(("line %d: frame %s is not a whole number: seconds in the frame column?"
          .. " The frame column counts frames (their time is frame / --fps); times in seconds"
          .. " go in a time column"):format(row.line, number(row.frame)))
        clock.first_fractional = row.line
      end
      clock.fractional = clock.fractional + 1
    end
  end
end

return M
