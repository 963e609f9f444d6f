--- What tagpose-replay says when it has replayed a log: the camera, the method, the time and
-- σ, the counts of rows (solved, failed, malformed, repeated, out of order, smoothed), the
-- mistakes of time, the medians and the noise, the comparisons, the files written; and the
-- figure.
--
-- Every function takes `say(fmt, ...)`, which writes one formatted line, and the replay's
-- record of `tagpose.tools.replay.frames`.
-- @module tagpose.tools.replay.summary

local plot = require("tagpose.tools.plot")
local stats = require("tagpose.tools.replay.stats")
local command = require("tagpose.tools.replay.command")
local frame = require("tagpose.tools.command")
local frames = require("tagpose.tools.replay.frames")
local compare = require("tagpose.tools.replay.compare")

local ceil, min = math.ceil, math.min
local concat = table.concat
local number, quantile = stats.number, stats.quantile

local M = {}

local function compare_ids(a, b)
  if type(a) == type(b) then return a < b end
  return type(a) == "number"
end

-- the ids of a set, sorted, the first `most` of them as the summary writes them
local function id_names(set, most)
  local ids = {}
  for id in pairs(set) do ids[#ids + 1] = id end
  table.sort(ids, compare_ids)
  local names = {}
  for k = 1, min(#ids, most) do names[k] = number(ids[k]) end
  if #ids > most then names[#names + 1] = "..." end
  return names, #ids
end

local function describe_lens(camera)
  local d = camera.distortion
  if not d then return "no lens distortion" end
  local names = camera.model == "fisheye" and { "k1", "k2", "k3", "k4" }
    or { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
  local parts = {}
  for _, k in ipairs(names) do
    if d[k] ~= nil and (d[k] ~= 0 or k == "k1") then
      parts[#parts + 1] = k .. " " .. number(d[k])
    end
  end
  return (camera.model == "fisheye" and "fisheye lens " or "Brown-Conrady lens ")
    .. concat(parts, ", ")
end

local function describe_sizes(sizes)
  if type(sizes) == "number" then return number(sizes) end
  local ids = {}
  for k in pairs(sizes) do
    if k ~= "default" then ids[#ids + 1] = k end
  end
  table.sort(ids)
  local parts = {}
  if sizes.default then parts[1] = number(sizes.default) .. " (default)" end
  for k = 1, min(#ids, 10) do
    parts[#parts + 1] = number(sizes[ids[k]]) .. " (tag " .. number(ids[k]) .. ")"
  end
  if #ids > 10 then parts[#parts + 1] = "..." end
  return concat(parts, ", ")
end

--- The lines on the log, the camera and the method.
-- @tparam function say
-- @tparam table run
-- @tparam table source `{path =, info =, unit =}`: the camera file, what it said, the unit
function M.head(say, run, source)
  local opt, camera, info = run.opt, run.camera, source.info
  local unit = source.unit
  say("replay %s", opt.log)
  say("  camera %s (%s): fx %s, fy %s, cx %s, cy %s, %s; tag size %s%s", source.path,
    info.format, number(camera.fx), number(camera.fy), number(camera.cx), number(camera.cy),
    describe_lens(camera), describe_sizes(run.sizes), unit ~= "tag-size units" and " " .. unit
    or "")
  if info.ignored and #info.ignored > 0 then
    say("  (not read from %s: %s)", source.path, concat(info.ignored, ", "))
  end
  local tracker = run.tracker
  say("  method %s, %s", opt.method or "refined", opt.track
    and ("tracked by tagpose.tracker (a track ends unseen for more than %s s)%s"):format(
      number(tracker.max_gap), opt.smooth and ", smoothed over the whole log" or "")
    or "each row solved alone (no tracking; the tracker's tracks only tell tags apart)")
  local times = run.clock
  if times.has_time then
    say("  time   the log's time column (s)%s", opt.given.fps and "; --fps not used" or "")
  else
    say("  time   frame / %s (frames per second, --fps; the log has no time column)",
      number(opt.fps))
  end
  if opt.sigma then
    say("  sigma  %s px (--sigma)", number(opt.sigma))
  elseif opt.track then
    say("  sigma  each track's running estimate from its residuals (no --sigma)")
  else
    say("  sigma  tagpose.solve's default, pooled with each row's residuals (no --sigma)")
  end
end

local function list_reasons(say, t, what)
  if t.n > #t.listed then
    say("  ... %d more (%s); by reason:", t.n - #t.listed, what)
    for _, reason in ipairs(t.order) do say("  %6d  %s", t.counts[reason], reason) end
    if t.other > 0 then say("  %6d  (other reasons)", t.other) end
  end
end

--- The lines on the rows: read, solved, failed, malformed, repeated, untracked, out of order.
-- @tparam function say
-- @tparam table run
function M.rows(say, run)
  local rows, failures, malformed = run.rows, run.failures, run.malformed
  local tag_names = id_names(run.tags, 20)
  say("rows       %d%s", rows, rows > 0 and (" (%s%d tag%s: %s; frames %s to %s)"):format(
    run.more_tags and "more than " or "", run.ntags, run.ntags == 1 and "" or "s",
    concat(tag_names, ", "), number(run.first_frame), number(run.last_frame)) or "")
  say("solved     %d", run.solved)
  say("failed     %d", failures.n)
  for _, f in ipairs(failures.listed) do
    say("  line %d (frame %s, tag %s): %s", f.line, number(f.frame), number(f.tag), f.reason)
  end
  list_reasons(say, failures, "every failed row is in the pose log with empty pose fields")
  say("malformed  %d%s", malformed.n, malformed.n > 0 and " (skipped, not in the pose log)" or "")
  for _, p in ipairs(malformed.listed) do say("  line %d: %s", p.line, p.reason) end
  list_reasons(say, malformed, "skipped")
  local repeated = run.repeated
  if repeated.rows > 0 then
    local names, nids = id_names(repeated.tags, 10)
    say("repeated   %d rows share their frame and tag with another row (tag%s %s, up to %d in"
      .. " a frame; first at line %d): kept apart as tracks by image position", repeated.rows,
      nids == 1 and "" or "s", concat(names, ", "), repeated.max, repeated.first)
  end
  if run.uncounted > 0 then
    say("uncounted  %d rows of ids past the first %d of their frame: not checked for repeated"
      .. " keys", run.uncounted, frames.MAX_IDS)
  end
  if run.order.rows > 0 then
    say("order      %d rows come after a later frame (first at line %d): the plot and the"
      .. " comparisons assume frame order", run.order.rows, run.order.first)
  end
  M.time(say, run)
  if run.smoothed then
    say("smoothed   %d rows take the other pose of the planar ambiguity once the later frames"
      .. " are seen", run.switched)
  end
end

--- The lines on the frames' times: what looks like a mistake.
-- @tparam function say
-- @tparam table run
function M.time(say, run)
  local times = run.clock
  if times.restarts > 0 then
    say("restarts   %d time%s the time went back (first at line %d): the tracker ended every"
      .. " track there", times.restarts, times.restarts == 1 and "" or "s", times.first_restart)
  end
  if times.cadence > 0 then
    say("time       %d frames step far beyond the max gap at a steady cadence (first at line"
      .. " %d): milliseconds or frame numbers where seconds belong?", times.cadence,
      times.first_cadence)
  end
  if times.fractional > 0 then
    say("frames     %d rows have a fractional frame number (first at line %d): seconds in the"
      .. " frame column?", times.fractional, times.first_fractional)
  end
  if times.mixed > 0 then
    say("time       %d rows carry a time other than their frame's first row's (first at line"
      .. " %d): the first is used", times.mixed, times.first_mixed)
  end
end

--- The line on the medians of the reprojection error and of the iterations.
-- @tparam function say
-- @tparam table run
function M.medians(say, run)
  local med_error = quantile(run.errors, 0.5)
  if not med_error then
    say("median reprojection error -, median solveQuad iterations - (no row solved)")
    return
  end
  local iterations = run.iterations
  local its, count = {}, 0
  for it in pairs(iterations) do its[#its + 1] = it end
  table.sort(its)
  local med_iterations
  for _, it in ipairs(its) do
    count = count + iterations[it]
    if count >= ceil(run.solved / 2) then
      med_iterations = it
      break
    end
  end
  say("median reprojection error %.3g px, median solveQuad iterations %s", med_error,
    number(med_iterations))
  say("noise      sigma %.3g px, from the median squared residual of the %d solved rows (2"
    .. " degrees of freedom a tag)", frames.sigma(run), run.solved)
end

--- The lines on each compared log.
-- @tparam function say
-- @tparam table run
-- @tparam string unit the length unit
function M.comparisons(say, run, unit)
  for _, c in ipairs(run.compares) do
    if c.matched > 0 then
      local lu = unit == "tag-size units" and "" or " " .. unit
      say("vs %s: %d rows matched; position difference median %.3g%s, p95 %.3g%s; rotation"
        .. " median %.3g deg, p95 %.3g deg; %d row%s (%.2f %%) more than %s deg apart",
        c.path, c.matched, quantile(c.dt, 0.5), lu, quantile(c.dt, 0.95), lu,
        quantile(c.dr, 0.5), quantile(c.dr, 0.95), c.apart, c.apart == 1 and "" or "s",
        100 * c.apart / c.matched, number(compare.APART))
    else
      say("vs %s: no solved row has a pose there with the same frame and tag", c.path)
    end
    for _, p in ipairs(c.problems.listed) do
      say("  %s line %d: %s (skipped)", c.path, p.line, p.reason)
    end
    if c.problems.n > #c.problems.listed then
      say("  %s: %d more malformed rows", c.path, c.problems.n - #c.problems.listed)
    end
    if c.out_of_order > 0 then
      say("  %s: %d rows come after a later frame (first at line %d): not compared", c.path,
        c.out_of_order, c.first_out_of_order)
    end
  end
end

--- Beyond this median distance from the camera (in metres) the tags are not where a tag
-- detector sees tags: the tag size is in another unit than the one it is read in.
M.FAR_METRES = 100

--- A warning when the solved tags are a median `FAR_METRES` or more from the camera, once the
-- length unit is one of `tagpose.tools.command.UNITS`: the tag size's unit is wrong (the
-- camera file's `tag_size = 165.1`, millimetres, read as metres, puts the camera kilometres
-- away).
-- @tparam table run
-- @tparam string unit the length unit
-- @treturn string|nil
function M.far(run, unit)
  local metres = frame.UNITS[unit]
  local median = quantile(run.distances, 0.5)
  if not (metres and median and median * metres >= M.FAR_METRES) then return nil end
  return ("the tags are a median %s m from the camera, with a tag size of %s %s: is the tag"
    .. " size in another unit? (give it with its unit: --tag-size %s)"):format(
    number(median * metres, 4), describe_sizes(run.sizes), unit,
    type(run.sizes) == "number" and number(run.sizes) .. "mm" or "S[UNIT]")
end

--- Why a replay gave no pose at all, or nil when a row was solved: no row read, or the
-- reason most of the rows failed for.
-- @tparam table run
-- @treturn string|nil
function M.nothing_solved(run)
  if run.solved > 0 then return nil end
  if run.rows == 0 then
    return ("no pose: %s has no row to solve (%d malformed)"):format(run.opt.log,
      run.malformed.n)
  end
  local failures, top = run.failures, nil
  for _, reason in ipairs(failures.order) do
    if not top or failures.counts[reason] > failures.counts[top] then top = reason end
  end
  return ("no pose: no row of %s was solved; %d of its %d rows failed with %s"):format(
    run.opt.log, failures.counts[top] or failures.n, run.rows, top or "various reasons")
end

--- Draw the figure into `opt.svg` and say so.
-- @tparam function say
-- @tparam table run
-- @tparam string unit the length unit
-- @tparam table svg the plot's file, a `tagpose.formats.output` (committed here)
-- @tparam[opt] string empty why nothing is drawn, said in every panel (`nothing_solved`)
-- @raise an `EXIT` of `tagpose.tools.replay.command` when the file cannot be written
function M.figure(say, run, unit, svg, empty)
  local opt, recorder = run.opt, run.recorder
  local title = opt.title or ("replay of " .. command.short_name(opt.log))
  local text, shown = plot.draw(recorder, { title = title, length_unit = unit, empty = empty })
  svg:write(text)
  local ok, werr = svg:commit()
  if not ok then command.fail(werr) end
  local ntracks = shown.tracks
  local nsources = #run.compares + 1
  say("wrote %s (%d panels, %d series: %s%d tag%s x %d log%s)", opt.svg, shown.panels,
    shown.series, ntracks > #shown.tags and (ntracks .. " tracks of ") or "", #shown.tags,
    #shown.tags == 1 and "" or "s", nsources, nsources == 1 and "" or "s")
  if recorder.dropped > 0 then
    say("  %d points out of frame order not drawn", recorder.dropped)
  end
  if recorder.skipped > 0 then
    say("  %d points of tracks past the first %d not drawn", recorder.skipped,
      plot.MAX_SERIES)
  end
end

return M
