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
-- @tparam number lo the low end of the axis
-- @tparam number hi the high end (`>= lo`)
-- @tparam[opt=5] int count about how many ticks are wanted (at least 1)
-- @treturn {number,...} the tick values in `[lo, hi]`, ascending (a value within round-off of
--   zero is exactly 0)
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
  local span = hi - lo
  if span <= 0 then span = abs(lo) > 0 and abs(lo) or 1 end
  local raw = span / count
  local magnitude = 10 ^ floor(log10(raw) + 1e-9)
  local f = raw / magnitude
  local step = (f < 1.5 and 1 or f < 3 and 2 or f < 7 and 5 or 10) * magnitude
  local decimals = -floor(log10(step) + 1e-9)
  if decimals < 1 then decimals = 0 end -- and never -0, which would print as "-0"
  local ticks = {}
  local k = ceil(lo / step - 1e-9)
  local v = k * step
  while v <= hi + step * 1e-9 do
    if abs(v) < step * 1e-9 then v = 0 end
    ticks[#ticks + 1] = v
    k = k + 1
    v = k * step
  end
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
    for _, run in ipairs(runs(s.x, s.y, s.wrap)) do
      if #run == 1 then
        local i = run[1]
        out[#out + 1] = ('<circle cx="%s" cy="%s" r="2" fill="%s" stroke="none"/>')
          :format(coord(sx(s.x[i])), coord(sy(s.y[i])), colour)
      else
        local pts = {}
        for k, i in ipairs(run) do pts[k] = coord(sx(s.x[i])) .. "," .. coord(sy(s.y[i])) end
        out[#out + 1] = '<polyline points="' .. concat(pts, " ") .. '"/>'
      end
    end
    out[#out + 1] = "</g>"
  end
  out[#out + 1] = "</g>"
  out[#out + 1] = ('<rect class="frame" x="%s" y="%s" width="%s" height="%s" fill="none"'
    .. ' stroke="#444444"/>'):format(coord(left), coord(top), coord(width), coord(height))
  out[#out + 1] = "</g>"
end

--- An SVG figure of panels in columns, with a title and a legend above them.
-- All panels share the horizontal range (the union of their series' finite x values); each
-- panel's vertical range is its series' finite y values, padded by 5 % (or `range`).
-- @tparam table fig the figure:
--
--   - `columns`: array of columns, each an array of panels from top to bottom; a panel is
--     `{name =, title =, unit =, x_label =, range = {lo, hi} or nil, series = {...}}`, a series
--     `{x = {...}, y = {...}, colour = "#rrggbb", dash = "7 4" or nil, width = px, tag =,
--     source =, wrap = number or nil}` (`wrap`: break the line where y jumps by more, as an
--     angle does at ±180°);
--   - `title` (optional), `legend` (optional array of `{label =, colour =, dash =}`),
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
  if xhi - xlo < 1e-12 then xlo, xhi = xlo - 1, xhi + 1 end
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

-- a colour "#rrggbb" mixed with black (f = 0: unchanged, 1: black)
local function darker(colour, f)
  local r, g, b = colour:match("^#(%x%x)(%x%x)(%x%x)$")
  if not r then return colour end
  local function mix(h) return floor(tonumber(h, 16) * (1 - f) + 0.5) end
  return ("#%02x%02x%02x"):format(mix(r), mix(g), mix(b))
end

local function pose_values(pose, rotation)
  if type(pose) ~= "table" then return nil end
  local p, q = pose.position, pose.quaternion
  local v = {}
  if type(p) == "table" then v.x, v.y, v.z = p.x, p.y, p.z end
  if type(q) == "table" then
    local w, x, y, z = q.w, q.x, q.y, q.z
    if rotation == "quaternion" then
      v.qw, v.qx, v.qy, v.qz = w, x, y, z
    elseif is_finite(w) and is_finite(x) and is_finite(y) and is_finite(z)
      and w * w + x * x + y * y + z * z > 0 then
      local roll, pitch, yaw = M.roll_pitch_yaw(w, x, y, z)
      v.roll, v.pitch, v.yaw = deg(roll), deg(pitch), deg(yaw)
    end
  end
  return v
end

--- The SVG figure of pose logs: position and rotation over frames, one line per tag id.
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
--   source's line of one tag in one panel)
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
  local unit = options.length_unit
  if unit == nil then unit = "m" end
  if type(unit) ~= "string" then
    raise(2, "poses", "options.length_unit: string expected, got " .. args.describe(unit))
  end
  for _, name in ipairs({ "width", "panel_height" }) do
    local v = options[name]
    if v ~= nil and not (is_finite(v) and v >= 100) then
      raise(2, "poses", "options." .. name .. ": number >= 100 expected, got " .. args.describe(v))
    end
  end
  if options.title ~= nil and type(options.title) ~= "string" then
    raise(2, "poses", "options.title: string expected, got " .. args.describe(options.title))
  end
  -- the tag ids, and each source's series per tag
  local ids, seen = {}, {}
  for _, src in ipairs(sources) do
    for _, e in ipairs(src.entries) do
      local tag = e.tag
      if tag ~= nil and not seen[tag] then
        seen[tag] = true
        ids[#ids + 1] = tag
      end
    end
  end
  table.sort(ids, function(a, b)
    if type(a) == "number" and type(b) == "number" then return a < b end
    if type(a) == type(b) then return tostring(a) < tostring(b) end
    return type(a) == "number"
  end)
  local colour_of = {}
  for i, id in ipairs(ids) do colour_of[id] = M.COLOURS[(i - 1) % #M.COLOURS + 1] end
  local names = { "x", "y", "z" }
  for _, r in ipairs(ROTATION[rotation]) do names[#names + 1] = r.name end
  -- per source and tag: frames and every panel's values
  local lines = {}
  for si, src in ipairs(sources) do
    local by_tag = {}
    for _, e in ipairs(src.entries) do
      if e.tag ~= nil then
        local t = by_tag[e.tag]
        if not t then
          t = { frames = {}, values = {} }
          for _, n in ipairs(names) do t.values[n] = {} end
          by_tag[e.tag] = t
        end
        local k = #t.frames + 1
        t.frames[k] = e.frame
        local v = pose_values(e.pose, rotation) or {}
        for _, n in ipairs(names) do t.values[n][k] = v[n] or 0 / 0 end
      end
    end
    local dash = src.dash
    if dash == nil then dash = M.DASHES[(si - 1) % #M.DASHES + 1] end
    lines[si] = { by_tag = by_tag, dash = dash or nil, label = tostring(src.label or si) }
  end
  local function panel(name, title, panel_unit, wrap)
    local p = { name = name, title = title, unit = panel_unit, series = {} }
    for _, id in ipairs(ids) do
      for si = 1, #sources do
        local t = lines[si].by_tag[id]
        if t then
          -- the first source in the tag's colour, the others darker, on top of it
          p.series[#p.series + 1] = { x = t.frames, y = t.values[name],
            colour = si == 1 and colour_of[id] or darker(colour_of[id], 0.45),
            dash = lines[si].dash, width = si == 1 and 1.5 or 1.6, tag = tostring(id),
            source = lines[si].label, wrap = wrap }
        end
      end
    end
    return p
  end
  local left, right = {}, {}
  for _, n in ipairs({ "x", "y", "z" }) do left[#left + 1] = panel(n, n, unit ~= "" and unit) end
  for _, r in ipairs(ROTATION[rotation]) do
    right[#right + 1] = panel(r.name, r.title, r.unit, r.wrap)
  end
  local legend_entries = {}
  for _, id in ipairs(ids) do
    legend_entries[#legend_entries + 1] = { label = "tag " .. tostring(id), colour = colour_of[id] }
  end
  for si = 1, #sources do
    legend_entries[#legend_entries + 1] = { label = lines[si].label, colour = "#333333",
      dash = lines[si].dash }
  end
  local svg, shown = M.figure({ title = options.title, columns = { left, right },
    legend = legend_entries, width = options.width, panel_height = options.panel_height })
  shown.tags = ids
  return svg, shown
end

return M
