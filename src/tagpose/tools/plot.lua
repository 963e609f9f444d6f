--- SVG plots of poses over frames, written in plain Lua (no I/O: the functions return text).
--
-- `poses` draws the figure of a replay: one panel each for the position `x`, `y`, `z` (left
-- column) and for the rotation (right column), the frame number along every horizontal axis,
-- one line per tag id (one colour per tag), one line style per source: the first source solid,
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
-- @module tagpose.tools.plot

local compat = require("tagpose.compat")
local args = require("tagpose.args")

local floor, ceil, abs, log, max = math.floor, math.ceil, math.abs, math.log, math.max
local asin, deg, huge, sqrt = math.asin, math.deg, math.huge, math.sqrt
local concat = table.concat
local atan2, is_finite = compat.atan2, compat.is_finite

local M = {}

--- Colours of the tags, in the order of their ids (Tableau 10); the list repeats after ten.
M.COLOURS = { "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
  "#7f7f7f", "#bcbd22", "#17becf" }
--- Stroke dash patterns of the sources, in order (`false`: solid); the list repeats.
M.DASHES = { false, "7 4", "2 3", "10 3 2 3" }

local FONT = 11 -- px, tick labels and legend
local CHAR = 0.58 * FONT -- estimated width of one character of FONT
local TITLE_FONT = 15

local function raise(n, fname, message)
  args.raise(n, fname, message, 3)
end

local function escape(s)
  return (tostring(s):gsub("[&<>\"']", { ["&"] = "&amp;", ["<"] = "&lt;", [">"] = "&gt;",
    ['"'] = "&quot;", ["'"] = "&apos;" }))
end

local function coord(v)
  local s = ("%.1f"):format(v)
  if s == "-0.0" then s = "0.0" end
  return s
end

local LOG10 = log(10)

local function log10(v)
  return log(v) / LOG10
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
function M.ticks(lo, hi, count)
  if not is_finite(lo) then
    raise(1, "ticks", "finite number expected, got " .. args.describe(lo))
  end
  if not is_finite(hi) or hi < lo then
    raise(2, "ticks", "finite number >= lo expected, got " .. args.describe(hi))
  end
  if count == nil then count = 5 end
  if not (is_finite(count) and count >= 1) then
    raise(3, "ticks", "number >= 1 expected, got " .. args.describe(count))
  end
  if hi == lo then
    local pad = abs(lo) > 0 and 0.1 * abs(lo) or 1
    lo, hi = lo - pad, hi + pad
  end
  local span = hi - lo
  local raw = span / count
  local magnitude = 10 ^ floor(log10(raw) + 1e-9)
  local f = raw / magnitude
  local mantissa = f < 1.5 and 1 or f < 3 and 2 or f < 7 and 5 or 10
  local ticks, step
  for _ = 1, 64 do
    step = mantissa * magnitude
    ticks = {}
    local k = ceil(lo / step - 1e-9)
    local v = k * step
    while v <= hi + step * 1e-9 do
      if abs(v) < step * 1e-9 then v = 0 end
      ticks[#ticks + 1] = v
      k = k + 1
      v = k * step
    end
    if #ticks >= 3 then break end
    -- too few labels for the axis to be read: the next smaller nice step
    if mantissa == 10 then
      mantissa = 5
    elseif mantissa == 5 then
      mantissa = 2
    elseif mantissa == 2 then
      mantissa = 1
    else
      mantissa, magnitude = 5, magnitude / 10
    end
  end
  local decimals = -floor(log10(step) + 1e-9)
  if decimals < 1 then decimals = 0 end -- and never -0, which would print as "-0"
  return ticks, step, decimals
end

local function label(v, decimals)
  local s = ("%." .. decimals .. "f"):format(v)
  if s:match("^%-0%.?0*$") then s = s:sub(2) end
  return s
end

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
function M.roll_pitch_yaw(w, x, y, z)
  local n = sqrt(w * w + x * x + y * y + z * z)
  w, x, y, z = w / n, x / n, y / n, z / n
  local s = 2 * (w * y - z * x)
  if s >= 1 - 1e-12 or s <= -1 + 1e-12 then
    -- gimbal lock: R = Rz(yaw) Ry(±π/2); read yaw from the first two rows of the 2nd column
    local r12 = 2 * (x * y - w * z)
    local r22 = 1 - 2 * (x * x + z * z)
    return 0, s > 0 and math.pi / 2 or -math.pi / 2, atan2(-r12, r22)
  end
  return atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)), asin(s),
    atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
end

-- the contiguous runs of a series to draw: {{i1, i2, ...}, ...}
local function runs(xs, ys, wrap)
  local step = huge
  local prev = nil
  for i = 1, #xs do
    local x = xs[i]
    if is_finite(x) then
      if prev and x > prev and x - prev < step then step = x - prev end
      prev = x
    end
  end
  local gap = step < huge and 1.5 * step or huge
  local out, run, px, py = {}, nil, nil, nil
  for i = 1, #xs do
    local x, y = xs[i], ys[i]
    if is_finite(x) and is_finite(y) then
      if run and (x - px > gap or x < px or (wrap and abs(y - py) > wrap)) then run = nil end
      if not run then
        run = {}
        out[#out + 1] = run
      end
      run[#run + 1] = i
      px, py = x, y
    else
      run = nil
    end
  end
  return out
end

local function range_of(values, lo, hi)
  for i = 1, #values do
    local v = values[i]
    if is_finite(v) then
      if v < lo then lo = v end
      if v > hi then hi = v end
    end
  end
  return lo, hi
end

-- pad a data range for the plot area
local function padded(lo, hi, fixed)
  if fixed then return fixed[1], fixed[2] end
  if lo > hi then return 0, 1 end
  local span = hi - lo
  if span <= 1e-12 * max(1, abs(hi)) then
    local pad = abs(hi) > 0 and 0.1 * abs(hi) or 1
    return lo - pad, hi + pad
  end
  return lo - 0.05 * span, hi + 0.05 * span
end

local function check_panel(p, where)
  if type(p) ~= "table" then return where .. ": panel table expected, got " .. type(p) end
  if type(p.series) ~= "table" then
    return where .. ".series: table expected, got " .. type(p.series)
  end
  for k, s in ipairs(p.series) do
    if type(s) ~= "table" or type(s.x) ~= "table" or type(s.y) ~= "table" then
      return where .. ".series[" .. k .. "]: table with arrays x and y expected"
    end
  end
  if p.range ~= nil and not (type(p.range) == "table" and is_finite(p.range[1])
    and is_finite(p.range[2]) and p.range[2] > p.range[1]) then
    return where .. ".range: {lo, hi} with lo < hi expected"
  end
  return nil
end

local function check_figure(fig)
  if type(fig) ~= "table" then return "figure table expected, got " .. type(fig) end
  if type(fig.columns) ~= "table" or #fig.columns == 0 then
    return "figure.columns: non-empty array of columns expected"
  end
  for c, column in ipairs(fig.columns) do
    if type(column) ~= "table" then
      return "figure.columns[" .. c .. "]: array of panels expected, got " .. type(column)
    end
    for r = 1, #column do
      local problem = check_panel(column[r], "figure.columns[" .. c .. "][" .. r .. "]")
      if problem then return problem end
    end
  end
  for _, name in ipairs({ "width", "panel_height" }) do
    local v = fig[name]
    if v ~= nil and not (is_finite(v) and v >= 100) then
      return "figure." .. name .. ": number >= 100 expected, got " .. args.describe(v)
    end
  end
  if fig.legend ~= nil and type(fig.legend) ~= "table" then
    return "figure.legend: table expected, got " .. type(fig.legend)
  end
  return nil
end

--- Marker shapes that tell apart the tags beyond the ten colours (`false`: none); the list
-- repeats.
M.MARKERS = { false, "circle", "square", "triangle", "diamond", "cross" }

local MARKER_R = 3.2 -- px
local MARKER_SPACING = 40 -- px along a line between markers

local function marker_svg(kind, x, y, colour)
  local r = MARKER_R
  local c = escape(colour)
  if kind == "circle" then
    return ('<circle class="marker" cx="%s" cy="%s" r="%s" fill="#ffffff" stroke="%s"'
      .. ' stroke-width="1.3" stroke-dasharray="none"/>'):format(coord(x), coord(y), coord(r), c)
  elseif kind == "cross" then
    return ('<path class="marker" d="M%s %sL%s %sM%s %sL%s %s" fill="none" stroke="%s"'
      .. ' stroke-width="1.5" stroke-dasharray="none"/>'):format(coord(x - r), coord(y - r),
      coord(x + r), coord(y + r), coord(x - r), coord(y + r), coord(x + r), coord(y - r), c)
  end
  local pts
  if kind == "square" then
    pts = { x - r, y - r, x + r, y - r, x + r, y + r, x - r, y + r }
  elseif kind == "triangle" then
    pts = { x, y - 1.2 * r, x + 1.1 * r, y + 0.8 * r, x - 1.1 * r, y + 0.8 * r }
  else -- diamond
    pts = { x, y - 1.3 * r, x + 1.1 * r, y, x, y + 1.3 * r, x - 1.1 * r, y }
  end
  local parts = {}
  for i = 1, #pts, 2 do parts[#parts + 1] = coord(pts[i]) .. "," .. coord(pts[i + 1]) end
  return ('<polygon class="marker" points="%s" fill="#ffffff" stroke="%s" stroke-width="1.3"'
    .. ' stroke-dasharray="none"/>'):format(concat(parts, " "), c)
end

-- the legend's entries laid out in rows across `width`; returns the SVG lines and the height
local function legend(entries, left, top, width)
  local out, x, y = {}, left, top + FONT
  for _, e in ipairs(entries) do
    local w = 34 + #tostring(e.label) * CHAR + 18
    if x > left and x + w > left + width then
      x, y = left, y + FONT + 8
    end
    local dash = e.dash and (' stroke-dasharray="' .. e.dash .. '"') or ""
    out[#out + 1] = ('<line class="legend-line" x1="%s" y1="%s" x2="%s" y2="%s" stroke="%s"'
      .. ' stroke-width="2"%s/>'):format(coord(x), coord(y - 4), coord(x + 28), coord(y - 4),
      escape(e.colour or "#333333"), dash)
    if e.marker then out[#out + 1] = marker_svg(e.marker, x + 14, y - 4, e.colour or "#333333") end
    out[#out + 1] = ('<text class="legend-label" x="%s" y="%s">%s</text>'):format(coord(x + 34),
      coord(y), escape(e.label))
    x = x + w
  end
  if #entries == 0 then return out, 0 end
  return out, y - top + 6
end

local function panel_svg(out, p, id, left, top, width, height, x0, x1, x_ticks, x_dec, bottom)
  local ylo, yhi = huge, -huge
  for _, s in ipairs(p.series) do ylo, yhi = range_of(s.y, ylo, yhi) end
  local has_data = ylo <= yhi
  local y0, y1 = padded(ylo, yhi, p.range)
  local y_ticks, _, y_dec = M.ticks(y0, y1, max(2, floor(height / 38)))
  local function sx(v) return left + (v - x0) / (x1 - x0) * width end
  local function sy(v) return top + height - (v - y0) / (y1 - y0) * height end
  local title = p.title or p.name or id
  if p.unit then title = title .. " (" .. p.unit .. ")" end
  out[#out + 1] = ('<g class="panel" id="panel-%s" data-title="%s" data-series="%d">')
    :format(escape(id), escape(title), #p.series)
  out[#out + 1] = ('<text class="panel-title" x="%s" y="%s" font-size="12" font-weight="bold">'
    .. '%s</text>'):format(coord(left), coord(top - 6), escape(title))
  out[#out + 1] = ('<rect class="plot-area" x="%s" y="%s" width="%s" height="%s" fill="#ffffff"'
    .. ' stroke="none"/>'):format(coord(left), coord(top), coord(width), coord(height))
  -- grid and ticks
  out[#out + 1] = '<g class="ticks" stroke="#e3e3e3" stroke-width="1">'
  for _, v in ipairs(y_ticks) do
    local y = coord(sy(v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(coord(left),
      y, coord(left + width), y)
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(coord(left - 4), y, coord(left), y)
  end
  for _, v in ipairs(x_ticks) do
    local x = coord(sx(v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(x,
      coord(top), x, coord(top + height))
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(x, coord(top + height), x, coord(top + height + 4))
  end
  out[#out + 1] = "</g>"
  out[#out + 1] = '<g class="tick-labels" fill="#333333">'
  for _, v in ipairs(y_ticks) do
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="end">%s</text>')
      :format(coord(left - 7), coord(sy(v) + 0.35 * FONT), label(v, y_dec))
  end
  for _, v in ipairs(x_ticks) do
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="middle">%s</text>')
      :format(coord(sx(v)), coord(top + height + 6 + FONT), label(v, x_dec))
  end
  out[#out + 1] = "</g>"
  if bottom then
    out[#out + 1] = ('<text class="axis-label" x="%s" y="%s" text-anchor="middle">%s</text>')
      :format(coord(left + width / 2), coord(top + height + 12 + 2 * FONT),
        escape(p.x_label or "frame"))
  end
  if not has_data then
    out[#out + 1] = ('<text class="no-data" x="%s" y="%s" text-anchor="middle" fill="#999999">'
      .. 'no data</text>'):format(coord(left + width / 2), coord(top + height / 2))
  end
  -- the series, clipped to the plot area
  out[#out + 1] = ('<g clip-path="url(#clip-%s)">'):format(escape(id))
  for _, s in ipairs(p.series) do
    local colour = escape(s.colour or "#333333")
    local dash = s.dash and (' stroke-dasharray="' .. escape(s.dash) .. '"') or ""
    out[#out + 1] = ('<g class="series" data-tag="%s" data-source="%s" stroke="%s" fill="none"'
      .. ' stroke-width="%s"%s>'):format(escape(s.tag or ""), escape(s.source or s.label or ""),
      colour, s.width or 1.5, dash)
    local marks = {}
    for _, run in ipairs(runs(s.x, s.y, s.wrap)) do
      if #run == 1 then
        local i = run[1]
        if s.marker then
          marks[#marks + 1] = marker_svg(s.marker, sx(s.x[i]), sy(s.y[i]), s.colour or "#333333")
        else
          out[#out + 1] = ('<circle cx="%s" cy="%s" r="2" fill="%s" stroke="none"/>')
            :format(coord(sx(s.x[i])), coord(sy(s.y[i])), colour)
        end
      else
        local pts = {}
        local last_mark = -huge
        for k, i in ipairs(run) do
          local px, py = sx(s.x[i]), sy(s.y[i])
          pts[k] = coord(px) .. "," .. coord(py)
          if s.marker and px - last_mark >= MARKER_SPACING then
            marks[#marks + 1] = marker_svg(s.marker, px, py, s.colour or "#333333")
            last_mark = px
          end
        end
        out[#out + 1] = '<polyline points="' .. concat(pts, " ") .. '"/>'
      end
    end
    for _, m in ipairs(marks) do out[#out + 1] = m end
    out[#out + 1] = "</g>"
  end
  out[#out + 1] = "</g>"
  out[#out + 1] = ('<rect class="frame" x="%s" y="%s" width="%s" height="%s" fill="none"'
    .. ' stroke="#444444"/>'):format(coord(left), coord(top), coord(width), coord(height))
  out[#out + 1] = "</g>"
end

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
function M.figure(fig)
  local problem = check_figure(fig)
  if problem then raise(1, "figure", problem) end
  local width = fig.width or 1000
  local panel_height = fig.panel_height or 150
  local ncol, nrow = #fig.columns, 0
  for _, column in ipairs(fig.columns) do nrow = max(nrow, #column) end
  -- the shared horizontal axis
  local xlo, xhi = huge, -huge
  for _, column in ipairs(fig.columns) do
    for _, p in ipairs(column) do
      for _, s in ipairs(p.series) do xlo, xhi = range_of(s.x, xlo, xhi) end
    end
  end
  if xlo > xhi then xlo, xhi = 0, 1 end
  if xhi - xlo < 1e-12 then
    xlo, xhi = xlo - 1, xhi + 1
  else
    -- a little room, so that a point at either end is drawn whole
    local pad = 0.01 * (xhi - xlo)
    xlo, xhi = xlo - pad, xhi + pad
  end
  local margin, gutter = 16, 30
  local cell = (width - 2 * margin - (ncol - 1) * gutter) / ncol
  -- the legend's height, then each column's room for its tick labels
  local top = margin
  local head = {}
  if fig.title then
    top = top + TITLE_FONT
    head[#head + 1] = ('<text class="title" x="%s" y="%s" font-size="%d" font-weight="bold">%s'
      .. '</text>'):format(coord(margin), coord(top), TITLE_FONT, escape(fig.title))
    top = top + 10
  end
  local legend_lines, legend_height = legend(fig.legend or {}, margin, top, width - 2 * margin)
  for _, l in ipairs(legend_lines) do head[#head + 1] = l end
  top = top + legend_height + 22
  local row_height = panel_height + 2 * FONT + 30
  local height = top + nrow * row_height + 2
  local x_ticks, _, x_dec = M.ticks(xlo, xhi, max(2, floor(cell / 70)))
  local out = {
    '<?xml version="1.0" encoding="UTF-8"?>',
    ('<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="%d" height="%d"'
      .. ' viewBox="0 0 %d %d" font-family="DejaVu Sans, Arial, sans-serif" font-size="%d"'
      .. ' data-panels="%d" data-series="%d">'):format(ceil(width), ceil(height), ceil(width),
      ceil(height), FONT, 0, 0),
    "<title>" .. escape(fig.title or "tagpose plot") .. "</title>",
    '<rect width="100%" height="100%" fill="#ffffff"/>',
  }
  local defs, body, panels, series = { "<defs>" }, {}, 0, 0
  for c, column in ipairs(fig.columns) do
    -- room for the widest tick label in this column
    local label_chars = 1
    for _, p in ipairs(column) do
      local ylo, yhi = huge, -huge
      for _, s in ipairs(p.series) do ylo, yhi = range_of(s.y, ylo, yhi) end
      local y0, y1 = padded(ylo, yhi, p.range)
      local ticks, _, dec = M.ticks(y0, y1, max(2, floor(panel_height / 38)))
      for _, v in ipairs(ticks) do label_chars = max(label_chars, #label(v, dec)) end
    end
    local left = margin + (c - 1) * (cell + gutter) + label_chars * CHAR + 10
    local plot_width = margin + (c - 1) * (cell + gutter) + cell - left
    for r, p in ipairs(column) do
      panels = panels + 1
      series = series + #p.series
      local id = tostring(p.name or (c .. "-" .. r)):gsub("[^%w_%-]", "_")
      local ptop = top + (r - 1) * row_height
      defs[#defs + 1] = ('<clipPath id="clip-%s"><rect x="%s" y="%s" width="%s" height="%s"/>'
        .. '</clipPath>'):format(id, coord(left), coord(ptop), coord(plot_width),
        coord(panel_height))
      panel_svg(body, p, id, left, ptop, plot_width, panel_height, xlo, xhi, x_ticks, x_dec,
        r == #column)
    end
  end
  out[2] = out[2]:gsub('data%-panels="0" data%-series="0"', ('data-panels="%d" data-series="%d"')
    :format(panels, series))
  defs[#defs + 1] = "</defs>"
  for _, part in ipairs({ defs, head, body }) do
    for _, l in ipairs(part) do out[#out + 1] = l end
  end
  out[#out + 1] = "</svg>"
  out[#out + 1] = ""
  return concat(out, "\n"), { panels = panels, series = series }
end

local ROTATION = {
  quaternion = {
    { name = "qw", title = "qw" }, { name = "qx", title = "qx" },
    { name = "qy", title = "qy" }, { name = "qz", title = "qz" },
  },
  rpy = {
    { name = "roll", title = "roll", unit = "deg", wrap = 180 },
    { name = "pitch", title = "pitch", unit = "deg", wrap = 180 },
    { name = "yaw", title = "yaw", unit = "deg", wrap = 180 },
  },
}

--- Most points a series of a `recorder` keeps exactly; beyond, it keeps the minimum and the
-- maximum of each value over buckets of frames (at most this many buckets, their width
-- doubling as the log goes on), which draws as the envelope a dense line fills at the
-- figure's resolution: memory stays bounded and no outlier is dropped.
M.MAX_POINTS = 1024

-------------------------------------------------------------------------------------------------
-- tracks: keeping apart the tags that share an id

local Tracker = {}
Tracker.__index = Tracker

--- A tracker that keeps apart the tags sharing an id (lab tags are often all id 0): each
-- detection of a frame joins the live track of its id whose last position is nearest (pairs
-- taken nearest first, each track at most once a frame), if it is within the track's gate;
-- the others start tracks. A track not seen for more than `keep` frames ends, and its slot
-- number is given to the next new track of the id.
-- @tparam[opt] table options `keep` (frames, default 1), `max_tracks` (per id, default 16:
--   further detections get no track, slot `nil`)
-- @treturn table a tracker with `assign(frame, id, points)`: `points` an array of
--   `{x, y[, z][, gate = r]}` (a point or `nil` each); returns an array of slots (1, 2, ...)
--   and an array of the tracks (tables the caller may keep its own fields in)
function M.tracker(options)
  options = options or {}
  return setmetatable({ keep = options.keep or 1, max_tracks = options.max_tracks or 16,
    tracks = {} }, Tracker)
end

local function finite_point(p)
  if type(p) ~= "table" then return false end
  for i = 1, #p do
    if not is_finite(p[i]) then return false end
  end
  return #p > 0
end

function Tracker:assign(frame, id, points)
  local list = self.tracks[id]
  local slots, tracks = {}, {}
  if list then
    -- end the tracks not seen for too long (or seen at a later frame: the log went back)
    local live = {}
    for _, t in ipairs(list) do
      local age = frame - t.frame
      if (age >= 0 and age <= self.keep) then live[#live + 1] = t end
    end
    list = live
  else
    list = {}
  end
  -- pairs of a point and a live track not yet matched in this frame, nearest first
  local pairs_ = {}
  for i = 1, #points do
    local p = points[i]
    if finite_point(p) then
      for k, t in ipairs(list) do
        if t.matched ~= frame then
          local d = 0
          for c = 1, #p do d = d + (p[c] - (t.point[c] or 0)) ^ 2 end
          local gate = t.gate
          if gate == nil or d <= gate * gate then pairs_[#pairs_ + 1] = { d, i, k } end
        end
      end
    end
  end
  table.sort(pairs_, function(a, b)
    if a[1] ~= b[1] then return a[1] < b[1] end
    if a[2] ~= b[2] then return a[2] < b[2] end
    return a[3] < b[3]
  end)
  local taken = {}
  for _, pr in ipairs(pairs_) do
    local i, t = pr[2], list[pr[3]]
    if not slots[i] and not taken[t] then
      taken[t] = true
      slots[i], tracks[i] = t.slot, t
    end
  end
  for i = 1, #points do
    local p = points[i]
    if not slots[i] and finite_point(p) and #list < self.max_tracks then
      local used = {}
      for _, t in ipairs(list) do used[t.slot] = true end
      local slot = 1
      while used[slot] do slot = slot + 1 end
      local t = { slot = slot }
      list[#list + 1] = t
      slots[i], tracks[i] = slot, t
    end
  end
  for i = 1, #points do
    local t = tracks[i]
    if t then
      t.frame, t.matched = frame, frame
      t.point, t.gate = points[i], points[i].gate
    end
  end
  if #list == 0 then list = nil end
  self.tracks[id] = list
  return slots, tracks
end

-------------------------------------------------------------------------------------------------
-- the recorder: what a pose figure draws, kept compact as it comes

local Recorder = {}
Recorder.__index = Recorder

--- A recorder of poses for a figure, fed row by row (memory bounded by `MAX_POINTS` per
-- series, whatever the length of the log).
-- Each series is one source's track of one tag id (`slot` tells apart the tags that share an
-- id). The quaternion of each series is kept continuous: a pose whose quaternion points away
-- from the series' previous one (`q · q_prev < 0`) is drawn as `-q`, the same rotation (the
-- poses themselves keep `w >= 0`).
-- @tparam[opt] table options `rotation` (`"quaternion"`, default, or `"rpy"`), `max_points`
--   (default `MAX_POINTS`)
-- @treturn table the recorder: `source(label[, dash])` → a source index; `add(source, tag,
--   slot, frame, pose)` (a `nil` pose is a gap: a failed row); `dropped` counts the points
--   that came out of frame order once a series was bucketed (not drawn)
function M.recorder(options)
  options = options or {}
  local rotation = options.rotation or "quaternion"
  if not ROTATION[rotation] then
    raise(1, "recorder", "options.rotation: 'quaternion' or 'rpy' expected, got "
      .. args.describe(rotation))
  end
  local names = { "x", "y", "z" }
  for _, r in ipairs(ROTATION[rotation]) do names[#names + 1] = r.name end
  return setmetatable({ rotation = rotation, names = names, sources = {}, series = {},
    order = {}, max_points = options.max_points or M.MAX_POINTS, dropped = 0 }, Recorder)
end

function Recorder:source(name, dash)
  local n = #self.sources + 1
  if dash == nil then dash = M.DASHES[(n - 1) % #M.DASHES + 1] end
  self.sources[n] = { label = tostring(name or n), dash = dash or nil }
  return n
end

local function series_key(source, tag, slot)
  return tostring(source) .. "\0" .. type(tag) .. ":" .. tostring(tag) .. "\0" .. tostring(slot)
end

-- merge bucket b into bucket a of series s (a, b indices), for every value
local function merge_bucket(s, a, b)
  for c = 1, #s.mn do
    local mn, mx = s.mn[c], s.mx[c]
    local u, v = mn[b], mx[b]
    if u == u and (mn[a] ~= mn[a] or u < mn[a]) then mn[a] = u end
    if v == v and (mx[a] ~= mx[a] or v > mx[a]) then mx[a] = v end
  end
end

-- turn an exact series into buckets of width w from origin (or double the width)
local function rebucket(s, w)
  local nv = #s.names
  if not s.width then
    -- from exact points: each point a bucket of its own, then merged below
    local lo, hi = huge, -huge
    for i = 1, s.n do
      local x = s.x[i]
      if x < lo then lo = x end
      if x > hi then hi = x end
    end
    s.origin = lo
    w = (hi - lo) / (s.max_points / 2)
    if not (w > 0) then w = 1 end
    s.mn, s.mx, s.index = {}, {}, {}
    for c = 1, nv do s.mn[c], s.mx[c] = s.v[c], {} end
    for c = 1, nv do
      local src, mx = s.v[c], s.mx[c]
      for i = 1, s.n do mx[i] = src[i] end
    end
    s.v = nil
  end
  s.width = w
  local index, x, n = s.index, s.x, 0
  local last = nil
  for i = 1, s.n do
    local k = floor((x[i] - s.origin) / w)
    if last ~= nil and k <= last then
      if k < last then s.recorder.dropped = s.recorder.dropped + 1 end
      merge_bucket(s, n, i)
    else
      n = n + 1
      last = k
      index[n] = k
      if n ~= i then
        x[n] = x[i]
        for c = 1, nv do s.mn[c][n], s.mx[c][n] = s.mn[c][i], s.mx[c][i] end
      end
    end
  end
  for i = n + 1, s.n do
    x[i], index[i] = nil, nil
    for c = 1, nv do s.mn[c][i], s.mx[c][i] = nil, nil end
  end
  s.n = n
end

function Recorder:add(source, tag, slot, frame, pose)
  if not is_finite(frame) then return end
  local key = series_key(source, tag, slot)
  local s = self.series[key]
  local names = self.names
  local nv = #names
  if not s then
    s = { source = source, tag = tag, slot = slot, n = 0, x = {}, v = {}, names = names,
      max_points = self.max_points, recorder = self, drawn = false }
    for c = 1, nv do s.v[c] = {} end
    self.series[key] = s
    self.order[#self.order + 1] = s
  end
  -- the values: position, then the rotation, its quaternion continuous along the series
  local vals = self.scratch or {}
  self.scratch = vals
  for c = 1, nv do vals[c] = 0 / 0 end
  if type(pose) == "table" then
    local p, q = pose.position, pose.quaternion
    if type(p) == "table" then vals[1], vals[2], vals[3] = p.x, p.y, p.z end
    if type(q) == "table" and is_finite(q.w) and is_finite(q.x) and is_finite(q.y)
      and is_finite(q.z) and q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z > 0 then
      local w, x, y, z = q.w, q.x, q.y, q.z
      local lq = s.last_q
      if lq and lq[1] * w + lq[2] * x + lq[3] * y + lq[4] * z < 0 then
        w, x, y, z = -w, -x, -y, -z
      end
      s.last_q = lq or {}
      s.last_q[1], s.last_q[2], s.last_q[3], s.last_q[4] = w, x, y, z
      if self.rotation == "quaternion" then
        vals[4], vals[5], vals[6], vals[7] = w, x, y, z
      else
        local roll, pitch, yaw = M.roll_pitch_yaw(w, x, y, z)
        vals[4], vals[5], vals[6] = deg(roll), deg(pitch), deg(yaw)
      end
    end
  end
  for c = 1, nv do
    local v = vals[c]
    if type(v) ~= "number" or not is_finite(v) then vals[c] = 0 / 0 else s.drawn = true end
  end
  if not s.width then
    local n = s.n + 1
    s.n = n
    s.x[n] = frame
    for c = 1, nv do s.v[c][n] = vals[c] end
    if n > s.max_points then rebucket(s) end
    return
  end
  local k = floor((frame - s.origin) / s.width)
  local n = s.n
  local last = s.index[n]
  if k < last then
    self.dropped = self.dropped + 1
    return
  end
  if k > last then
    n = n + 1
    s.n = n
    s.index[n], s.x[n] = k, frame
    for c = 1, nv do s.mn[c][n], s.mx[c][n] = 0 / 0, 0 / 0 end
  end
  for c = 1, nv do
    local v, mn, mx = vals[c], s.mn[c], s.mx[c]
    if v == v then
      if mn[n] ~= mn[n] or v < mn[n] then mn[n] = v end
      if mx[n] ~= mx[n] or v > mx[n] then mx[n] = v end
    end
  end
  if n > s.max_points then rebucket(s, 2 * s.width) end
end

-- the x and y arrays a panel draws of series s, value c
local function series_xy(s, c)
  if not s.width then return s.x, s.v[c] end
  local xs, ys = {}, {}
  local mn, mx = s.mn[c], s.mx[c]
  for i = 1, s.n do
    local xc = s.origin + (s.index[i] + 0.5) * s.width
    local a, b = mn[i], mx[i]
    if i % 2 == 0 then a, b = b, a end
    xs[2 * i - 1], ys[2 * i - 1] = xc, a
    xs[2 * i], ys[2 * i] = xc, b
  end
  return xs, ys
end

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

local function check_title(fname, n, options)
  if options.title ~= nil and type(options.title) ~= "string" then
    raise(n, fname, "options.title: string expected, got " .. args.describe(options.title))
  end
  for _, name in ipairs({ "width", "panel_height" }) do
    local v = options[name]
    if v ~= nil and not (is_finite(v) and v >= 100) then
      raise(n, fname, "options." .. name .. ": number >= 100 expected, got " .. args.describe(v))
    end
  end
  local unit = options.length_unit
  if unit ~= nil and type(unit) ~= "string" then
    raise(n, fname, "options.length_unit: string expected, got " .. args.describe(unit))
  end
end

--- The SVG figure of what a `recorder` holds: position and rotation over frames, one line per
-- source and track of a tag.
-- Tracks are told apart by colour (ten, `COLOURS`), then by marker (`MARKERS`: the 11th to
-- 20th track carry circles, and so on), sources by dash (`DASHES`: the first solid). The
-- legend shows what is drawn: the tracks that have a finite point, and the sources (when
-- there are several) that have one.
-- @tparam table recorder a `recorder`
-- @tparam[opt] table options `title`, `length_unit` (the unit of the tag size, for the
--   position titles, default `"m"`), `width` (px, default 1000), `panel_height` (px, default
--   150), `max_legend` (entries, default 60; the rest are summed up in one)
-- @treturn string the SVG document
-- @treturn table what it shows: `{panels = n, series = n, tags = {id, ...}, tracks = n}`
--   (a series is one source's line of one track in one panel)
-- @raise `bad argument #n to 'draw' (...)` when the options are not of that shape
function M.draw(recorder, options)
  if getmetatable(recorder) ~= Recorder then
    raise(1, "draw", "a recorder expected, got " .. type(recorder))
  end
  if options ~= nil and type(options) ~= "table" then
    raise(2, "draw", "options table expected, got " .. type(options))
  end
  options = options or {}
  check_title("draw", 2, options)
  local unit = options.length_unit
  if unit == nil then unit = "m" end
  -- the tracks (tag, slot) in order, their styles
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
  table.sort(tracks, function(a, b)
    if a.tag ~= b.tag then return compare_ids(a.tag, b.tag) end
    return (a.slot or huge) < (b.slot or huge)
  end)
  local slots_of = {}
  for _, t in ipairs(tracks) do slots_of[t.tag] = (slots_of[t.tag] or 0) + 1 end
  for i, t in ipairs(tracks) do
    t.colour = M.COLOURS[(i - 1) % #M.COLOURS + 1]
    t.marker = M.MARKERS[floor((i - 1) / #M.COLOURS) % #M.MARKERS + 1] or nil
    t.label = "tag " .. tostring(t.tag)
    if slots_of[t.tag] > 1 then t.label = t.label .. " #" .. tostring(t.slot or "?") end
  end
  local series = {}
  for _, s in ipairs(recorder.order) do series[#series + 1] = s end
  table.sort(series, function(a, b)
    if a.track ~= b.track then
      if a.track.tag ~= b.track.tag then return compare_ids(a.track.tag, b.track.tag) end
      return (a.track.slot or huge) < (b.track.slot or huge)
    end
    return a.source < b.source
  end)
  local function panel(c, name, title, panel_unit, wrap)
    local p = { name = name, title = title, unit = panel_unit, series = {} }
    for _, s in ipairs(series) do
      local src = recorder.sources[s.source] or { label = tostring(s.source) }
      local xs, ys = series_xy(s, c)
      p.series[#p.series + 1] = { x = xs, y = ys,
        colour = s.source == 1 and s.track.colour or darker(s.track.colour, 0.45),
        dash = src.dash, width = s.source == 1 and 1.5 or 1.6, tag = tostring(s.tag),
        source = src.label, wrap = wrap, marker = s.track.marker }
    end
    return p
  end
  local left, right = {}, {}
  local names = recorder.names
  for c = 1, 3 do left[#left + 1] = panel(c, names[c], names[c], unit ~= "" and unit or nil) end
  for k, r in ipairs(ROTATION[recorder.rotation]) do
    right[#right + 1] = panel(3 + k, r.name, r.title, r.unit, r.wrap)
  end
  local legend_entries, max_legend, hidden = {}, options.max_legend or 60, 0
  for _, t in ipairs(tracks) do
    if t.drawn then
      if #legend_entries < max_legend then
        legend_entries[#legend_entries + 1] = { label = t.label, colour = t.colour,
          marker = t.marker }
      else
        hidden = hidden + 1
      end
    end
  end
  if hidden > 0 then
    legend_entries[#legend_entries + 1] = { label = ("... and %d more"):format(hidden),
      colour = "#ffffff" }
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
        legend_entries[#legend_entries + 1] = { label = src.label, colour = "#333333",
          dash = src.dash }
      end
    end
  end
  local svg, shown = M.figure({ title = options.title, columns = { left, right },
    legend = legend_entries, width = options.width, panel_height = options.panel_height })
  shown.tags = ids
  shown.tracks = #tracks
  return svg, shown
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

-- the position of a pose as a tracker point, or nil
local function position_point(pose)
  local p = type(pose) == "table" and pose.position
  if type(p) ~= "table" then return nil end
  return { p.x, p.y, p.z }
end

--- Feed a recorder the entries of one source, keeping apart the tags that share an id in a
-- frame (by the nearest position to each track's last one; see `tracker`).
-- @tparam table recorder a `recorder`
-- @tparam int source the source's index (`recorder:source(...)`)
-- @tparam {table,...} entries `{frame =, tag =, pose =}` in log order
function M.record_entries(recorder, source, entries)
  local tracker = M.tracker()
  local i, n = 1, #entries
  while i <= n do
    -- the entries of one frame
    local frame = entries[i].frame
    local j = i
    while j + 1 <= n and entries[j + 1].frame == frame do j = j + 1 end
    local by_tag, tags = {}, {}
    for k = i, j do
      local e = entries[k]
      if e.tag ~= nil then
        local list = by_tag[e.tag]
        if not list then
          list = {}
          by_tag[e.tag] = list
          tags[#tags + 1] = e.tag
        end
        list[#list + 1] = e
      end
    end
    for _, tag in ipairs(tags) do
      local list = by_tag[tag]
      local points = {}
      for k, e in ipairs(list) do points[k] = position_point(e.pose) or false end
      local slots = is_finite(frame) and tracker:assign(frame, tag, points) or {}
      for k, e in ipairs(list) do
        recorder:add(source, tag, slots[k] or 1, frame, e.pose)
      end
    end
    i = j + 1
  end
end

--- The SVG figure of pose logs: position and rotation over frames, one line per tag id (and
-- per track of an id that several tags share in a frame).
-- @tparam {table,...} sources the logs to draw, each `{label = string, entries = {...}}` with
--   entries `{frame =, tag =, pose =}` as `tagpose.tools.log.read_poses` returns them (or as a
--   replay builds them from `tagpose.solve`'s results; a `nil` pose is a gap). The first source
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
  if not ROTATION[rotation] then
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
