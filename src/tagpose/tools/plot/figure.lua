--- The layout of a figure: panels in columns under a title and a legend, sharing the
-- horizontal axis (see `tagpose.tools.plot.figure`, which this is).
-- @module tagpose.tools.plot.figure

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local scale = require("tagpose.tools.plot.scale")
local svg = require("tagpose.tools.plot.svg")

local floor, ceil, max, huge = math.floor, math.ceil, math.max, math.huge
local concat = table.concat
local is_finite = compat.is_finite
local escape, coord = svg.escape, svg.coord

local FONT, CHAR, TITLE_FONT = svg.FONT, svg.CHAR, svg.TITLE_FONT

local M = {}

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
  if p.height ~= nil and not (is_finite(p.height) and p.height >= 20) then
    return where .. ".height: number >= 20 expected, got " .. args.describe(p.height)
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

-- the shared horizontal range: the union of the series' finite x, with 1 % of room at either
-- end (so that a point at an end is drawn whole)
local function x_range(fig)
  local xlo, xhi = huge, -huge
  for _, column in ipairs(fig.columns) do
    for _, p in ipairs(column) do
      for _, s in ipairs(p.series) do xlo, xhi = scale.range_of(s.x, xlo, xhi) end
    end
  end
  if xlo > xhi then xlo, xhi = 0, 1 end
  if xhi - xlo < 1e-12 then return xlo - 1, xhi + 1 end
  local pad = 0.01 * (xhi - xlo)
  return xlo - pad, xhi + pad
end

-- what the horizontal axis's labels count from: 0, or for values far from 0 beside their
-- span (the times of a clock since 1970: 1700000000 to 1700000010) a round number at or
-- below the first tick, a multiple of the power of ten above the span, so that the labels
-- stay short
local function x_offset(x0, x1, first)
  local span = x1 - x0
  if not (span > 0) or math.max(math.abs(x0), math.abs(x1)) < 1e4 * span then return 0 end
  local unit = 10 ^ ceil(math.log(span) / math.log(10))
  return floor(first / unit) * unit
end

-- the title and the legend above the panels: their SVG lines and the panels' top
local function head(fig, margin, width)
  local top = margin
  local lines = {}
  if fig.title then
    top = top + TITLE_FONT
    lines[#lines + 1] = ('<text class="title" x="%s" y="%s" font-size="%d" font-weight="bold">%s'
      .. '</text>'):format(coord(margin), coord(top), TITLE_FONT, escape(fig.title))
    top = top + 10
  end
  local legend_lines, legend_height = svg.legend(fig.legend or {}, margin, top, width - 2 * margin)
  for _, l in ipairs(legend_lines) do lines[#lines + 1] = l end
  return lines, top + legend_height + 22
end

-- the widest tick label of a column's panels, in characters
local function label_chars(column, panel_height)
  local n = 1
  for _, p in ipairs(column) do
    local _, _, ticks, decimals = scale.panel_range(p, p.height or panel_height)
    for _, v in ipairs(ticks) do n = max(n, #scale.label(v, decimals)) end
  end
  return n
end

-- draw the panels of every column into body, their clip paths into defs; returns the counts
local function columns(fig, defs, body, l)
  local panels, series = 0, 0
  for c, column in ipairs(fig.columns) do
    -- room for the widest tick label in this column
    local cell_left = l.margin + (c - 1) * (l.cell + l.gutter)
    local left = cell_left + label_chars(column, l.panel_height) * CHAR + 10
    local plot_width = cell_left + l.cell - left
    local ptop = l.top
    for r, p in ipairs(column) do
      panels = panels + 1
      series = series + #p.series
      local id = tostring(p.name or (c .. "-" .. r)):gsub("[^%w_%-]", "_")
      local height = p.height or l.panel_height
      defs[#defs + 1] = ('<clipPath id="clip-%s"><rect x="%s" y="%s" width="%s" height="%s"/>'
        .. '</clipPath>'):format(id, coord(left), coord(ptop), coord(plot_width), coord(height))
      svg.panel(body, p, { id = id, left = left, top = ptop, width = plot_width,
        height = height, x0 = l.x0, x1 = l.x1, x_ticks = l.x_ticks,
        x_decimals = l.x_decimals, x_offset = l.x_offset, bottom = r == #column })
      ptop = ptop + height + l.below
    end
  end
  return panels, series
end

--- `tagpose.tools.plot.figure` (documented there).
-- @tparam table fig
-- @treturn string the SVG document
-- @treturn table `{panels = n, series = n}`
function M.figure(fig)
  local problem = check_figure(fig)
  if problem then args.raise(1, "figure", problem, 2) end
  local width = fig.width or 1000
  local l = { panel_height = fig.panel_height or 150, margin = 16, gutter = 30 }
  local ncol = #fig.columns
  l.x0, l.x1 = x_range(fig)
  l.cell = (width - 2 * l.margin - (ncol - 1) * l.gutter) / ncol
  local head_lines
  head_lines, l.top = head(fig, l.margin, width)
  -- each panel's height (its own, or panel_height) and below it its tick labels and gap
  l.below = 2 * FONT + 30
  local tallest = 0
  for _, column in ipairs(fig.columns) do
    local h = 0
    for _, p in ipairs(column) do h = h + (p.height or l.panel_height) + l.below end
    tallest = max(tallest, h)
  end
  local height = l.top + tallest + 2
  local x_ticks, _, x_decimals = scale.ticks(l.x0, l.x1, max(2, floor(l.cell / 70)))
  l.x_ticks, l.x_decimals = x_ticks, x_decimals
  l.x_offset = x_offset(l.x0, l.x1, x_ticks[1])
  local defs, body = { "<defs>" }, {}
  local panels, series = columns(fig, defs, body, l)
  local out = {
    '<?xml version="1.0" encoding="UTF-8"?>',
    ('<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="%d" height="%d"'
      .. ' viewBox="0 0 %d %d" font-family="DejaVu Sans, Arial, sans-serif" font-size="%d"'
      .. ' data-panels="%d" data-series="%d">'):format(ceil(width), ceil(height), ceil(width),
      ceil(height), FONT, panels, series),
    "<title>" .. escape(fig.title or "tagpose plot") .. "</title>",
    '<rect width="100%" height="100%" fill="#ffffff"/>',
  }
  defs[#defs + 1] = "</defs>"
  for _, part in ipairs({ defs, head_lines, body }) do
    for _, line in ipairs(part) do out[#out + 1] = line end
  end
  out[#out + 1] = "</svg>"
  out[#out + 1] = ""
  return concat(out, "\n"), { panels = panels, series = series }
end

return M
