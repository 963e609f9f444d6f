--- SVG drawing of a figure's parts: one panel (its grid, ticks, labels and series, lines
-- broken at gaps), the markers that tell tracks apart, the legend. Coordinates are CSS pixels.
--
-- A panel is drawn into its area, a record
--
--     { id =, left =, top =, width =, height =,  -- the plot area, px
--       x0 =, x1 =, x_ticks =, x_decimals =,     -- the shared horizontal axis, its labels
--       x_offset =,                              -- counted from x_offset (0: none)
--       bottom = boolean }                       -- the lowest panel of its column
-- @module tagpose.tools.plot.svg

local compat = require("tagpose.core.compat")
local scale = require("tagpose.tools.plot.scale")

local abs, huge = math.abs, math.huge
local concat = table.concat
local is_finite = compat.is_finite
local label = scale.label

local M = {}

--- Tick labels and legend, px.
M.FONT = 11
--- The estimated width of one character of `FONT`, px.
M.CHAR = 0.58 * M.FONT
--- The figure's title, px.
M.TITLE_FONT = 15

local FONT, CHAR = M.FONT, M.CHAR

local MARKER_R = 3.2 -- px
local MARKER_SPACING = 40 -- px along a line between markers

--- A text for SVG: `& < > " '` escaped.
-- @param s
-- @treturn string
function M.escape(s)
  return (tostring(s):gsub("[&<>\"']", { ["&"] = "&amp;", ["<"] = "&lt;", [">"] = "&gt;",
    ['"'] = "&quot;", ["'"] = "&apos;" }))
end

local escape = M.escape

--- A coordinate to 0.1 px (never `-0.0`).
-- @tparam number v
-- @treturn string
function M.coord(v)
  local s = ("%.1f"):format(v)
  if s == "-0.0" then s = "0.0" end
  return s
end

local coord = M.coord

--- A marker (`circle`, `square`, `triangle`, `diamond`, `cross`) at (x, y).
-- @tparam string kind
-- @tparam number x
-- @tparam number y
-- @tparam string colour
-- @treturn string the SVG element
function M.marker(kind, x, y, colour)
  local r = MARKER_R
  local c = escape(colour)
  if kind == "circle" then
    return ('<circle class="marker" data-marker="circle" cx="%s" cy="%s" r="%s" fill="#ffffff"'
      .. ' stroke="%s" stroke-width="1.3" stroke-dasharray="none"/>'):format(coord(x), coord(y),
      coord(r), c)
  elseif kind == "cross" then
    return ('<path class="marker" data-marker="cross" d="M%s %sL%s %sM%s %sL%s %s" fill="none"'
      .. ' stroke="%s" stroke-width="1.5" stroke-dasharray="none"/>'):format(coord(x - r),
      coord(y - r), coord(x + r), coord(y + r), coord(x - r), coord(y + r), coord(x + r),
      coord(y - r), c)
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
  return ('<polygon class="marker" data-marker="%s" points="%s" fill="#ffffff" stroke="%s"'
    .. ' stroke-width="1.3" stroke-dasharray="none"/>'):format(kind, concat(parts, " "), c)
end

local marker = M.marker

--- The legend's entries laid out in rows across `width`.
-- @tparam {table,...} entries `{label =, colour =, dash =, marker =}`
-- @tparam number left
-- @tparam number top
-- @tparam number width
-- @treturn {string,...} the SVG lines
-- @treturn number the legend's height (0 without entries)
function M.legend(entries, left, top, width)
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
    if e.marker then out[#out + 1] = marker(e.marker, x + 14, y - 4, e.colour or "#333333") end
    out[#out + 1] = ('<text class="legend-label" x="%s" y="%s">%s</text>'):format(coord(x + 34),
      coord(y), escape(e.label))
    x = x + w
  end
  if #entries == 0 then return out, 0 end
  return out, y - top + 6
end

-- the contiguous runs of a series to draw: {{i1, i2, ...}, ...}, broken where a value is not
-- finite (y, or `also` where given), where x goes back, where x (or `gs`, the frames of a
-- series drawn over time, where given) jumps by more than 1.5 of its smallest step, and where
-- y jumps by more than `wrap`
local function runs(xs, ys, wrap, gs, also)
  gs = gs or xs
  local step = huge
  local prev = nil
  for i = 1, #gs do
    local x = gs[i]
    if is_finite(x) then
      if prev and x > prev and x - prev < step then step = x - prev end
      prev = x
    end
  end
  local gap = step < huge and 1.5 * step or huge
  local out, run, px, pg, py = {}, nil, nil, nil, nil
  for i = 1, #xs do
    local x, y, g = xs[i], ys[i], gs[i]
    if is_finite(x) and is_finite(y) and (not also or is_finite(also[i])) then
      if run and (g - pg > gap or x < px or (wrap and abs(y - py) > wrap)) then run = nil end
      if not run then
        run = {}
        out[#out + 1] = run
      end
      run[#run + 1] = i
      px, pg, py = x, g, y
    else
      run = nil
    end
  end
  return out
end

local function sx(a, v) return a.left + (v - a.x0) / (a.x1 - a.x0) * a.width end
local function sy(a, v) return a.top + a.height - (v - a.y0) / (a.y1 - a.y0) * a.height end

-- a series' band (±2σ), under its line: a polygon a run (from the high ends forward, back
-- along the low ends), a run of one point a vertical line; a band wider than the series'
-- `wrap` (an angle's band across ±180°, where it would fill the panel) is left out
local function band(out, a, s)
  local b = s.band
  local colour = escape(s.colour or "#333333")
  local lo = b.lo
  if s.wrap then
    lo = {}
    for i = 1, #b.x do
      lo[i] = b.hi[i] - b.lo[i] <= s.wrap and b.lo[i] or 0 / 0
    end
  end
  out[#out + 1] = ('<g class="band" data-tag="%s" data-source="%s" fill="%s" stroke="none"'
    .. ' fill-opacity="0.18">'):format(escape(s.tag or ""), escape(s.source or s.label or ""),
    colour)
  for _, run in ipairs(runs(b.x, lo, s.wrap, b.gap_x, b.hi)) do
    if #run == 1 then
      local i = run[1]
      local x = coord(sx(a, b.x[i]))
      out[#out + 1] = ('<line x1="%s" y1="%s" x2="%s" y2="%s" stroke="%s" stroke-width="3"'
        .. ' stroke-opacity="0.3"/>'):format(x, coord(sy(a, b.hi[i])), x, coord(sy(a, b.lo[i])),
        colour)
    else
      local pts = {}
      for _, i in ipairs(run) do
        pts[#pts + 1] = coord(sx(a, b.x[i])) .. "," .. coord(sy(a, b.hi[i]))
      end
      for k = #run, 1, -1 do
        local i = run[k]
        pts[#pts + 1] = coord(sx(a, b.x[i])) .. "," .. coord(sy(a, b.lo[i]))
      end
      out[#out + 1] = '<polygon points="' .. concat(pts, " ") .. '"/>'
    end
  end
  out[#out + 1] = "</g>"
end

-- the grid lines and the ticks of both axes
local function grid(out, a, y_ticks)
  local left, top, width, height = a.left, a.top, a.width, a.height
  out[#out + 1] = '<g class="ticks" stroke="#e3e3e3" stroke-width="1">'
  for _, v in ipairs(y_ticks) do
    local y = coord(sy(a, v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(coord(left),
      y, coord(left + width), y)
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(coord(left - 4), y, coord(left), y)
  end
  for _, v in ipairs(a.x_ticks) do
    local x = coord(sx(a, v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(x,
      coord(top), x, coord(top + height))
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(x, coord(top + height), x, coord(top + height + 4))
  end
  out[#out + 1] = "</g>"
end

-- the tick labels of both axes, and the horizontal axis's name under the lowest panel
local function tick_labels(out, a, p, y_ticks, y_decimals)
  local left, top, width, height = a.left, a.top, a.width, a.height
  out[#out + 1] = '<g class="tick-labels" fill="#333333">'
  for _, v in ipairs(y_ticks) do
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="end">%s</text>')
      :format(coord(left - 7), coord(sy(a, v) + 0.35 * FONT), label(v, y_decimals))
  end
  local offset = a.x_offset or 0
  for _, v in ipairs(a.x_ticks) do
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="middle">%s</text>')
      :format(coord(sx(a, v)), coord(top + height + 6 + FONT), label(v - offset, a.x_decimals))
  end
  out[#out + 1] = "</g>"
  if a.bottom then
    local name = p.x_label or "frame"
    if offset ~= 0 then name = name .. " from " .. label(offset, 0) end
    out[#out + 1] = ('<text class="axis-label" x="%s" y="%s" text-anchor="middle">%s</text>')
      :format(coord(left + width / 2), coord(top + height + 12 + 2 * FONT), escape(name))
  end
end

-- one series: its runs as polylines (a run of one point a dot, or its marker), its markers
local function series(out, a, s)
  local colour = escape(s.colour or "#333333")
  local dash = s.dash and (' stroke-dasharray="' .. escape(s.dash) .. '"') or ""
  out[#out + 1] = ('<g class="series" data-tag="%s" data-source="%s" stroke="%s" fill="none"'
    .. ' stroke-width="%s"%s>'):format(escape(s.tag or ""), escape(s.source or s.label or ""),
    colour, s.width or 1.5, dash)
  local marks = {}
  for _, run in ipairs(runs(s.x, s.y, s.wrap, s.gap_x)) do
    if #run == 1 then
      local i = run[1]
      if s.marker then
        marks[#marks + 1] = marker(s.marker, sx(a, s.x[i]), sy(a, s.y[i]), s.colour or "#333333")
      else
        out[#out + 1] = ('<circle cx="%s" cy="%s" r="2" fill="%s" stroke="none"/>')
          :format(coord(sx(a, s.x[i])), coord(sy(a, s.y[i])), colour)
      end
    else
      local pts = {}
      local last_mark = -huge
      for k, i in ipairs(run) do
        local px, py = sx(a, s.x[i]), sy(a, s.y[i])
        pts[k] = coord(px) .. "," .. coord(py)
        if s.marker and px - last_mark >= MARKER_SPACING then
          marks[#marks + 1] = marker(s.marker, px, py, s.colour or "#333333")
          last_mark = px
        end
      end
      out[#out + 1] = '<polyline points="' .. concat(pts, " ") .. '"/>'
    end
  end
  for _, m in ipairs(marks) do out[#out + 1] = m end
  out[#out + 1] = "</g>"
end

--- Draw a panel (see `tagpose.tools.plot.figure`) into its area, appending SVG lines to out.
-- @tparam {string,...} out
-- @tparam table p the panel
-- @tparam table a its area (see the module's header); its vertical range is set here
function M.panel(out, p, a)
  local y_ticks, y_decimals, has_data
  a.y0, a.y1, y_ticks, y_decimals, has_data = scale.panel_range(p, a.height)
  local left, top, width, height = a.left, a.top, a.width, a.height
  local title = p.title or p.name or a.id
  if p.unit then title = title .. " (" .. p.unit .. ")" end
  out[#out + 1] = ('<g class="panel" id="panel-%s" data-title="%s" data-series="%d">')
    :format(escape(a.id), escape(title), #p.series)
  out[#out + 1] = ('<text class="panel-title" x="%s" y="%s" font-size="12" font-weight="bold">'
    .. '%s</text>'):format(coord(left), coord(top - 6), escape(title))
  out[#out + 1] = ('<rect class="plot-area" x="%s" y="%s" width="%s" height="%s" fill="#ffffff"'
    .. ' stroke="none"/>'):format(coord(left), coord(top), coord(width), coord(height))
  grid(out, a, y_ticks)
  tick_labels(out, a, p, y_ticks, y_decimals)
  if not has_data then
    -- the panel's reason (p.empty, default "no data"), in lines that fit the panel
    local lines, line = {}, nil
    local fit = math.max(20, math.floor(width / CHAR / 1.1))
    for word in (p.empty or "no data"):gmatch("%S+") do
      if line and #line + 1 + #word > fit then
        lines[#lines + 1] = line
        line = word
      else
        line = line and line .. " " .. word or word
      end
    end
    lines[#lines + 1] = line
    local cx = coord(left + width / 2)
    out[#out + 1] = ('<text class="no-data" x="%s" y="%s" text-anchor="middle" fill="#999999">')
      :format(cx, coord(top + height / 2 - 7 * (#lines - 1)))
    for k, l in ipairs(lines) do
      out[#out + 1] = ('<tspan x="%s" dy="%s">%s</tspan>'):format(cx, k == 1 and "0" or "14",
        escape(l))
    end
    out[#out + 1] = "</text>"
  end
  -- the series, clipped to the plot area
  out[#out + 1] = ('<g clip-path="url(#clip-%s)">'):format(escape(a.id))
  for _, s in ipairs(p.series) do
    if s.band then band(out, a, s) end
  end
  for _, s in ipairs(p.series) do series(out, a, s) end
  out[#out + 1] = "</g>"
  out[#out + 1] = ('<rect class="frame" x="%s" y="%s" width="%s" height="%s" fill="none"'
    .. ' stroke="#444444"/>'):format(coord(left), coord(top), coord(width), coord(height))
  out[#out + 1] = "</g>"
end

return M
