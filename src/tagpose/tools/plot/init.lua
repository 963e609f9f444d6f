--- SVG plots of poses over frames, written in plain Lua (no I/O: the functions return text).
--
-- `poses` draws the figure of a replay: one panel each for the position `x`, `y`, `z` (left
-- column) and for the rotation (right column), the frame number along every horizontal axis,
-- one line per track of a tag (one colour per track: the entries' `track` tells apart the tags
-- that share an id, as `tagpose.tracker` or a truth file's `track` column gives it; the plot
-- itself associates nothing), one line style per source: the first source solid,
-- the others dashed (for instance a ground truth or another solver's pose log). `figure` is the
-- general layout underneath, for panels of any series.
--
-- The rotation is shown either as the quaternion components `qw, qx, qy, qz` of the pose
-- (tag → camera, unit, as stored) or as roll, pitch and yaw in degrees, with the convention of
-- `roll_pitch_yaw`.
--
-- A line is broken where a value is missing or not finite, and where a tag was not seen for
-- more than one frame (more than 1.5 times the series' smallest frame step), so that gaps in
-- the detections show as gaps; a run of a single point is drawn as a dot. Every panel is a
-- `<g class="panel">` and every line a `<g class="series">` with `data-tag` and `data-source`
-- attributes, so that a test (or a script) can count what a figure shows.
--
-- Lengths are in the unit of the tag size; the unit's name for the axis titles is an option
-- (`"m"` by default). SVG coordinates are in CSS pixels.
--
-- Its parts: `tagpose.tools.plot.scale` (ticks, ranges), `tagpose.tools.plot.svg` (a panel,
-- markers, the legend), `tagpose.tools.plot.figure` (the layout),
-- `tagpose.tools.plot.recorder` (series kept compact) and
-- `tagpose.tools.plot.draw` (a recorder's figure). The constants below are read from this
-- module when they are used, so that a caller may change them.
-- @module tagpose.tools.plot

local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")
local scale = require("tagpose.tools.plot.scale")
local figure = require("tagpose.tools.plot.figure")
local recorder_model = require("tagpose.tools.plot.recorder")
local draw = require("tagpose.tools.plot.draw")

local is_finite = compat.is_finite

local M = {}

--- Colours of the tags, in the order of their ids (Tableau 10); the list repeats after ten.
M.COLOURS = { "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
  "#7f7f7f", "#bcbd22", "#17becf" }
--- Stroke dash patterns of the sources, in order (`false`: solid); the list repeats.
M.DASHES = { false, "7 4", "2 3", "10 3 2 3" }

--- Marker shapes that tell apart the tags beyond the ten colours (`false`: none); the list
-- repeats.
M.MARKERS = { false, "circle", "square", "triangle", "diamond", "cross" }

--- Most points a series of a `recorder` keeps exactly; beyond, it keeps the minimum and the
-- maximum of each value over buckets of frames (at most this many buckets, their width
-- doubling as the log goes on), which draws as the envelope a dense line fills at the
-- figure's resolution: memory stays bounded and no outlier is dropped.
M.MAX_POINTS = 1024

--- The height of the confidence's strip (px), under the position's panels.
M.STRIP_HEIGHT = 56

--- Most series a `recorder` keeps (one per source and track); the points of further series are
-- counted in its `skipped`, not drawn (a log whose every row carries a new tag id must not fill
-- memory with series).
M.MAX_SERIES = 256

local function raise(n, fname, message)
  args.raise(n, fname, message, 3)
end

--- Ticks of an axis at "nice" values: multiples of 1, 2 or 5 times a power of ten.
-- There are always at least three, so that an axis can be read (the step is made smaller
-- until three fit); when `hi` equals `lo` the range is first widened by 10 % of `|lo|` (or by
-- 1 around 0).
-- @tparam number lo the low end of the axis
-- @tparam number hi the high end (`>= lo`)
-- @tparam[opt=5] int count about how many ticks are wanted (at least 1)
-- @treturn {number,...} the tick values in `[lo, hi]` (widened as above), ascending, at least
--   three (a value within round-off of zero is exactly 0)
-- @treturn number the step between them
-- @treturn int the number of decimals that writes every tick exactly (for `%.Nf`)
-- @raise `bad argument #n to 'ticks' (...)` when `lo` or `hi` is not finite or `hi < lo`
-- @usage
-- local ticks, step, decimals = plot.ticks(0, 0.7)  -- {0, 0.1, ..., 0.7}, 0.1, 1
-- @function ticks
M.ticks = scale.ticks

--- Roll, pitch and yaw of a rotation given as a quaternion.
-- The convention: intrinsic Z-Y-X angles (yaw about z, then pitch about the new y, then
-- roll about the newest x) of the tag → camera rotation, so that
-- `R = Rz(yaw) · Ry(pitch) · Rx(roll)`; equivalently, rotations about the fixed camera axes x,
-- then y, then z. A tag seen face-on and upright (tag axes along the camera's) has all three
-- at 0; pitch is in `[-π/2, π/2]`, roll and yaw in `[-π, π]`. At pitch `±π/2` (gimbal lock)
-- roll is 0 and yaw takes the whole rotation about z. Mind the camera's axes (x right, y down,
-- z forward): roll turns the tag about the horizontal image axis, pitch about the vertical one
-- (what a ground robot calls a heading change) and yaw about the line of sight.
-- @tparam number w
-- @tparam number x
-- @tparam number y
-- @tparam number z the quaternion (any non-zero length; it is normalised)
-- @treturn number roll, radians
-- @treturn number pitch, radians
-- @treturn number yaw, radians
-- @usage
-- local roll, pitch, yaw = plot.roll_pitch_yaw(pose.quaternion.w, pose.quaternion.x,
--   pose.quaternion.y, pose.quaternion.z)
-- @function roll_pitch_yaw
M.roll_pitch_yaw = recorder_model.roll_pitch_yaw

--- An SVG figure of panels in columns, with a title and a legend above them.
-- All panels share the horizontal range (the union of their series' finite x values, with
-- 1 % of room at either end); each panel's vertical range is its series' finite y values,
-- padded by 5 % (or `range`).
-- @tparam table fig the figure:
--
--   - `columns`: array of columns, each an array of panels from top to bottom; a panel is
--     `{name =, title =, unit =, x_label =, range = {lo, hi} or nil, series = {...}}`, a series
--     `{x = {...}, y = {...}, colour = "#rrggbb", dash = "7 4" or nil, width = px, tag =,
--     source =, wrap = number or nil, marker = name or nil}` (`wrap`: break the line where y
--     jumps by more, as an angle does at ±180°; `marker`: one of `MARKERS`, drawn every 40 px
--     along the line and in place of the dot of a single point);
--   - `title` (optional), `legend` (optional array of `{label =, colour =, dash =,
--     marker =}`),
--   - `width` (px, default 1000), `panel_height` (px, default 150).
-- @treturn string the SVG document
-- @treturn table what it shows: `{panels = n, series = n}`
-- @raise `bad argument #1 to 'figure' (...)` when `fig` is not of that shape
-- @function figure
M.figure = figure.figure

--- The rows of one frame by tag id (rows without a tag left out), and the ids in the order
-- they first come.
-- @tparam {table,...} rows entries with a `tag` field
-- @tparam[opt] int first the first row (default 1)
-- @tparam[opt] int last the last row (default #rows)
-- @treturn table tag → the array of its rows
-- @treturn {any,...} the tags
function M.by_tag(rows, first, last)
  local by_tag, tags = {}, {}
  for k = first or 1, last or #rows do
    local row = rows[k]
    local tag = row.tag
    if tag ~= nil then
      local list = by_tag[tag]
      if not list then
        list = {}
        by_tag[tag] = list
        tags[#tags + 1] = tag
      end
      list[#list + 1] = row
    end
  end
  return by_tag, tags
end

--- A recorder of poses for a figure, fed row by row (memory bounded by `MAX_POINTS` per
-- series, whatever the length of the log).
-- Each series is one source's track of one tag id (`slot` tells apart the tags that share an
-- id). The quaternion of each series is kept continuous: a pose whose quaternion points away
-- from the series' previous one (`q · q_prev < 0`) is drawn as `-q`, the same rotation (the
-- poses themselves keep `w >= 0`).
--
-- What the pose log has is drawn: a pose's `covariance` (6×6, position then rotation vector,
-- camera frame, as `tagpose.solve` gives it) as a band of ±2 standard deviations around each
-- value (the rotation's deviations, taken as independent, carried to the quaternion's
-- components or to roll, pitch and yaw through their derivatives), and its `confidence` (or
-- the one given to `add`) in a strip under the position's panels.
-- @tparam[opt] table options `rotation` (`"quaternion"`, default, or `"rpy"`), `max_points`
--   (default `MAX_POINTS`), `x` (the horizontal axis: `"frame"`, default, or `"time"`, in
--   seconds)
-- @treturn table the recorder: `source(label[, dash])` → a source index; `add(source, tag,
--   slot, frame, pose[, confidence[, time]])` (a `nil` pose is a gap: a failed row; `time`
--   is the point's place on a time axis, where the lines still break at gaps in the frames);
--   `dropped` counts the points that came out of order once a series was bucketed,
--   `skipped` those of series past `MAX_SERIES` (neither is drawn)
function M.recorder(options)
  options = options or {}
  local rotation = options.rotation or "quaternion"
  if not recorder_model.ROTATION[rotation] then
    raise(1, "recorder", "options.rotation: 'quaternion' or 'rpy' expected, got "
      .. args.describe(rotation))
  end
  local x = options.x or "frame"
  if x ~= "frame" and x ~= "time" then
    raise(1, "recorder", "options.x: 'frame' or 'time' expected, got " .. args.describe(x))
  end
  return recorder_model.new(rotation, options.max_points or M.MAX_POINTS, M, x)
end

-- check the options of draw or poses (fname), argument n; a misuse is blamed on the caller of
-- draw or poses, one level above this helper's caller
local function check_title(fname, n, options)
  local function refuse(message) args.raise(n, fname, message, 4) end
  if options.title ~= nil and type(options.title) ~= "string" then
    refuse("options.title: string expected, got " .. args.describe(options.title))
  end
  for _, name in ipairs({ "width", "panel_height" }) do
    local v = options[name]
    if v ~= nil and not (is_finite(v) and v >= 100) then
      refuse("options." .. name .. ": number >= 100 expected, got " .. args.describe(v))
    end
  end
  for _, name in ipairs({ "length_unit", "empty" }) do
    if options[name] ~= nil and type(options[name]) ~= "string" then
      refuse("options." .. name .. ": string expected, got " .. args.describe(options[name]))
    end
  end
end

--- The SVG figure of what a `recorder` holds: position and rotation over frames (or time),
-- one line per source and track of a tag, with the ±2σ band of each line whose poses have a
-- covariance, and the confidence in a strip (`STRIP_HEIGHT`) under the position's panels
-- when a pose has one.
-- Tracks are told apart by colour (ten, `COLOURS`), then by marker (`MARKERS`: the 11th to
-- 20th track carry circles, and so on), sources by dash (`DASHES`: the first solid). The
-- legend shows what is drawn: the tracks that have a finite point, and the sources (when
-- there are several) that have one.
-- @tparam table recorder a `recorder`
-- @tparam[opt] table options `title`, `length_unit` (the unit of the tag size, for the
--   position titles, default `"m"`), `width` (px, default 1000), `panel_height` (px, default
--   150), `max_legend` (entries, default 60; the rest are summed up in one), `empty` (what
--   a panel with nothing to draw says, default `"no data"`: why there is nothing)
-- @treturn string the SVG document
-- @treturn table what it shows: `{panels = n, series = n, tags = {id, ...}, tracks = n}`
--   (a series is one source's line of one track in one panel)
-- @raise `bad argument #n to 'draw' (...)` when the options are not of that shape
function M.draw(recorder, options)
  if not recorder_model.is_recorder(recorder) then
    raise(1, "draw", "a recorder expected, got " .. type(recorder))
  end
  if options ~= nil and type(options) ~= "table" then
    raise(2, "draw", "options table expected, got " .. type(options))
  end
  options = options or {}
  check_title("draw", 2, options)
  return draw.draw(recorder, options, M)
end

local function check_sources(sources)
  if type(sources) ~= "table" then return "array of sources expected, got " .. type(sources) end
  for i = 1, #sources do
    local s = sources[i]
    if type(s) ~= "table" or type(s.entries) ~= "table" then
      return "sources[" .. i .. "]: {label =, entries = {...}} expected"
    end
    for k = 1, #s.entries do
      local e = s.entries[k]
      if type(e) ~= "table" or (e.pose ~= nil and type(e.pose) ~= "table") then
        return "sources[" .. i .. "].entries[" .. k .. "]: {frame =, tag =, pose =} expected"
      end
    end
  end
  return nil
end

--- Feed a recorder the entries of one source: one line per tag id, and per track of an id
-- where the entries carry one (`track`: `tagpose.tracker`'s track, or a truth file's `track`
-- column), the tracks of an id drawn as `#1`, `#2`, ... in the order they come.
-- @tparam table recorder a `recorder`
-- @tparam int source the source's index (`recorder:source(...)`)
-- @tparam {table,...} entries `{frame =, tag =, pose =[, track =]}` in log order
function M.record_entries(recorder, source, entries)
  local slots = {} -- tag -> {[track] = slot, n = slots}
  for i = 1, #entries do
    local e = entries[i]
    local tag, slot = e.tag, 1
    if tag ~= nil then
      if e.track ~= nil then
        local of = slots[tag] or { n = 0 }
        slots[tag] = of
        slot = of[e.track]
        if not slot then
          of.n = of.n + 1
          slot, of[e.track] = of.n, of.n
        end
      end
      recorder:add(source, tag, slot, e.frame, e.pose)
    end
  end
end

--- The SVG figure of pose logs: position and rotation over frames, one line per tag id (and
-- per track of an id, where the entries carry `track`: see `record_entries`).
-- @tparam {table,...} sources the logs to draw, each `{label = string, entries = {...}}` with
--   entries `{frame =, tag =, pose =[, track =]}` as `tagpose.tools.log.read_poses` returns
--   them (or as a replay builds them from `tagpose.tracker`'s results; a `nil` pose is a
--   gap). The first source
--   is drawn solid, the others dashed (`DASHES`); a source's `dash` field overrides its style.
-- @tparam[opt] table options
--
--   - `rotation`: `"quaternion"` (default) or `"rpy"` (roll, pitch, yaw in degrees, see
--     `roll_pitch_yaw`);
--   - `length_unit`: the unit of the tag size, for the position titles (default `"m"`);
--   - `title`, `width` (px, default 1000), `panel_height` (px, default 150).
-- @treturn string the SVG document
-- @treturn table what it shows: `{panels = n, series = n, tags = {id, ...}}` (a series is one
--   source's line of one track in one panel)
-- @raise `bad argument #n to 'poses' (...)` when the sources or options are not of that shape
-- @usage
-- local entries = log.read_poses("poses.csv")
-- local truth = log.read_poses("truth.csv")
-- local svg = plot.poses({ { label = "tagpose", entries = entries },
--   { label = "truth", entries = truth } }, { title = "approach" })
function M.poses(sources, options)
  local problem = check_sources(sources)
  if problem then raise(1, "poses", problem) end
  if options ~= nil and type(options) ~= "table" then
    raise(2, "poses", "options table expected, got " .. type(options))
  end
  options = options or {}
  local rotation = options.rotation or "quaternion"
  if not recorder_model.ROTATION[rotation] then
    raise(2, "poses", "options.rotation: 'quaternion' or 'rpy' expected, got "
      .. args.describe(rotation))
  end
  check_title("poses", 2, options)
  local recorder = M.recorder({ rotation = rotation })
  for _, src in ipairs(sources) do
    local si = recorder:source(src.label, src.dash)
    M.record_entries(recorder, si, src.entries)
  end
  local svg, shown = M.draw(recorder, options)
  shown.tracks = nil
  return svg, shown
end

return M
