--- The figure of what a recorder holds (see `tagpose.tools.plot.draw`, which this is): the
-- tracks' styles (colour, then marker), the series in order, the position and rotation
-- panels with the ±2σ bands of the series that have deviations, the confidence strip, and
-- the legend of what is drawn.
-- @module tagpose.tools.plot.draw

local recorder_model = require("tagpose.tools.plot.recorder")
local figure = require("tagpose.tools.plot.figure")

local floor, huge = math.floor, math.huge

local M = {}

-- a colour "#rrggbb" mixed with black (f = 0: unchanged, 1: black)
local function darker(colour, f)
  local r, g, b = colour:match("^#(%x%x)(%x%x)(%x%x)$")
  if not r then return colour end
  local function mix(h) return floor(tonumber(h, 16) * (1 - f) + 0.5) end
  return ("#%02x%02x%02x"):format(mix(r), mix(g), mix(b))
end

local function compare_ids(a, b)
  if type(a) == "number" and type(b) == "number" then return a < b end
  if type(a) == type(b) then return tostring(a) < tostring(b) end
  return type(a) == "number"
end

local function by_track(a, b)
  if a.tag ~= b.tag then return compare_ids(a.tag, b.tag) end
  return (a.slot or huge) < (b.slot or huge)
end

-- the tracks (tag, slot) of the recorder's series, in order, and the tag ids; each series
-- gets its track (s.track)
local function tracks_of(recorder)
  local tracks, track_of, ids, seen = {}, {}, {}, {}
  for _, s in ipairs(recorder.order) do
    local key = type(s.tag) .. ":" .. tostring(s.tag) .. "\0" .. tostring(s.slot)
    local t = track_of[key]
    if not t then
      t = { tag = s.tag, slot = s.slot, drawn = false }
      track_of[key] = t
      tracks[#tracks + 1] = t
    end
    if s.drawn then t.drawn = true end
    s.track = t
    if not seen[s.tag] then
      seen[s.tag] = true
      ids[#ids + 1] = s.tag
    end
  end
  table.sort(ids, compare_ids)
  table.sort(tracks, by_track)
  return tracks, ids
end

-- each track's colour, marker and label
local function style(tracks, colours, markers)
  local slots_of = {}
  for _, t in ipairs(tracks) do slots_of[t.tag] = (slots_of[t.tag] or 0) + 1 end
  for i, t in ipairs(tracks) do
    t.colour = colours[(i - 1) % #colours + 1]
    t.marker = markers[floor((i - 1) / #colours) % #markers + 1] or nil
    t.label = "tag " .. tostring(t.tag)
    if slots_of[t.tag] > 1 then t.label = t.label .. " #" .. tostring(t.slot or "?") end
  end
end

-- the series by track, then source
local function series_in_order(recorder)
  local series = {}
  for _, s in ipairs(recorder.order) do series[#series + 1] = s end
  table.sort(series, function(a, b)
    if a.track ~= b.track then return by_track(a.track, b.track) end
    return a.source < b.source
  end)
  return series
end

-- the panel of value c of every series (with its band where the series has deviations);
-- the confidence's panel (c = nv + 1) has only the series that have one
local function panel(recorder, series, c, name, title, unit, wrap)
  local p = { name = name, title = title, unit = unit, series = {} }
  local strip = c > recorder.nv
  for _, s in ipairs(series) do
    if not strip or s.nc > recorder.nv then
      local src = recorder.sources[s.source] or { label = tostring(s.source) }
      local xs, ys = recorder_model.series_xy(s, c)
      local e = { x = xs, y = ys, gap_x = not s.width and s.f or nil,
        colour = s.source == 1 and s.track.colour or darker(s.track.colour, 0.45),
        dash = src.dash, width = s.source == 1 and 1.5 or 1.6, tag = tostring(s.tag),
        source = src.label, wrap = wrap, marker = s.track.marker }
      if not strip then
        local bx, lo, hi = recorder_model.band_xy(s, c)
        if bx then e.band = { x = bx, lo = lo, hi = hi, gap_x = e.gap_x } end
      end
      p.series[#p.series + 1] = e
    end
  end
  return p
end

-- whether a series has a finite confidence
local function has_confidence(recorder, s)
  local c = recorder.nv + 1
  if s.nc < c then return false end
  local values = s.width and s.mn[c] or s.v[c]
  for i = 1, s.n do
    if values[i] == values[i] then return true end
  end
  return false
end

-- the legend: the tracks drawn (at most max_legend, the rest summed up), then the sources
-- when several are drawn
local function legend(recorder, tracks, series, max_legend)
  local entries, hidden = {}, 0
  for _, t in ipairs(tracks) do
    if t.drawn then
      if #entries < max_legend then
        entries[#entries + 1] = { label = t.label, colour = t.colour, marker = t.marker }
      else
        hidden = hidden + 1
      end
    end
  end
  if hidden > 0 then
    entries[#entries + 1] = { label = ("... and %d more"):format(hidden), colour = "#ffffff" }
  end
  local drawn_sources = {}
  for _, s in ipairs(series) do
    if s.drawn then drawn_sources[s.source] = true end
  end
  local nsources = 0
  for _ in pairs(drawn_sources) do nsources = nsources + 1 end
  if nsources > 1 then
    for si, src in ipairs(recorder.sources) do
      if drawn_sources[si] then
        entries[#entries + 1] = { label = src.label, colour = "#333333", dash = src.dash }
      end
    end
  end
  return entries
end

--- `tagpose.tools.plot.draw` (documented there), its arguments checked.
-- @tparam table recorder
-- @tparam table options
-- @tparam table settings where `COLOURS` and `MARKERS` are read (the `tagpose.tools.plot`
--   module)
-- @treturn string the SVG document
-- @treturn table what it shows
function M.draw(recorder, options, settings)
  local unit = options.length_unit
  if unit == nil then unit = "m" end
  local tracks, ids = tracks_of(recorder)
  style(tracks, settings.COLOURS, settings.MARKERS)
  local series = series_in_order(recorder)
  local left, right = {}, {}
  local names = recorder.names
  for c = 1, 3 do
    left[#left + 1] = panel(recorder, series, c, names[c], names[c], unit ~= "" and unit or nil)
  end
  for k, r in ipairs(recorder_model.ROTATION[recorder.rotation]) do
    right[#right + 1] = panel(recorder, series, 3 + k, r.name, r.title, r.unit, r.wrap)
  end
  -- the confidence, a strip under the position, when a series has one
  for _, s in ipairs(series) do
    if has_confidence(recorder, s) then
      local strip = panel(recorder, series, recorder.nv + 1, "confidence", "confidence")
      strip.range, strip.height = { -0.05, 1.05 }, settings.STRIP_HEIGHT
      left[#left + 1] = strip
      break
    end
  end
  local x_label = recorder.x == "time" and "time (s)" or "frame"
  for _, column in ipairs({ left, right }) do
    for _, p in ipairs(column) do p.empty, p.x_label = options.empty, x_label end
  end
  local entries = legend(recorder, tracks, series, options.max_legend or 60)
  local svg, shown = figure.figure({ title = options.title, columns = { left, right },
    legend = entries, width = options.width, panel_height = options.panel_height })
  shown.tags = ids
  shown.tracks = #tracks
  return svg, shown
end

return M
