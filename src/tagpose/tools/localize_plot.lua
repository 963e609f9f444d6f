--- The field from above as SVG, for the `--svg` of `tagpose-localize`: the map's tags, the
-- estimated path with its 95 % position ellipses, the odometry beside it, the tags rejected
-- marked. Pure: the functions return text and numbers, no I/O.
--
-- Frames and units: the field's (the map's: x, y on the floor, z up), metres, angles in
-- radians (degrees only in the drawing's labels). The drawing has one scale for x and y, x to
-- the right and y up; SVG coordinates are CSS pixels.
--
-- Inputs:
--
-- - `tags`: the localizer's read map (`loc.tags`, `tagpose.rigid.model.read`'s): `{ids =
--   {id, ...}, [id] = {x =, y =, z =, r = {9}, size =, ...}}`, `r` the flat, row-major
--   tag → field rotation (tag frame: x right, y down, z into the tag). A tag is drawn as a
--   segment along its face (its x axis on the floor), a tick on the side it faces and its id.
-- - `rows`: the localizer's results in time order, of which only `time`, `position.x`,
--   `position.y`, `yaw`, `covariance[1][1]`, `[1][2]`, `[2][2]` (x and y first: m²), `tags`
--   (the ids used) and `rejected` (`{{id =, why =}, ...}`) are read (`tags` and `rejected` may
--   be nil), so a caller may keep just those. Rows whose position is not finite are not drawn.
--   A tag rejected in some rows is drawn in another colour with those rows' count and the
--   count of rows that saw it (used or rejected).
-- - `odometry` (optional): samples `{t, x, y, yaw}` in time order, in the odometry's own frame
--   (never reset, say). It is drawn in the field through the rigid motion (2D rotation and
--   translation) that best aligns it with the path: least squares over the rows' times within
--   the odometry's span (the odometry interpolated linearly there), in closed form (`align`).
--
-- The arithmetic (`align`, `ellipse`, the field's bounds and scale) lives in
-- `tagpose.tools.localize_geometry`; `align`, `ellipse` and `CHI2_95` are reachable here too.
--
-- Every part is a `<g class=...>` group with `data-` attributes that say what it holds (`tags`:
-- `data-count`, `data-rejected`; each `tag`: `data-id`, `data-rejected` rows; `path`:
-- `data-points`, `data-runs`; `ellipses`: `data-count`, each `ellipse` its `data-time`,
-- semi-axes `data-a` >= `data-b` (m) and `data-angle` (the major axis from the field's x, degrees);
-- `odometry`: `data-points`, `data-rotation` (degrees), `data-dx`, `data-dy`, `data-rms` (m),
-- `data-pairs`), so a test or a script can count what a drawing shows.
-- @module tagpose.tools.localize_plot

local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")
local geometry = require("tagpose.tools.localize_geometry")
local scale = require("tagpose.tools.plot.scale")
local svg = require("tagpose.tools.plot.svg")

local sqrt, cos, sin, deg = math.sqrt, math.cos, math.sin, math.deg
local floor, ceil, max, huge = math.floor, math.ceil, math.max, math.huge
local format, concat = string.format, table.concat
local is_finite = compat.is_finite
local escape, coord, label = svg.escape, svg.coord, scale.label
local has_position = geometry.has_position

local FONT = svg.FONT

local M = {}

--- χ² of 2 degrees of freedom below which 95 % of the mass lies: `-2 ln 0.05` (5.991;
-- `localize_geometry.CHI2_95`, which `ellipse` reads).
M.CHI2_95 = geometry.CHI2_95
--- An ellipse every this many seconds of rows.
M.ELLIPSE_EVERY = 0.5
--- The path is broken where two rows are further apart in time, s.
M.GAP = 1.0
--- Room around the tags and the path, m.
M.MARGIN = 0.6
--- The drawing's largest plot area's width, px (the field is scaled to fit it, one scale for x
-- and y)...
M.MAX_WIDTH = 1100
--- ... and its height, px.
M.MAX_HEIGHT = 700

M.COLOURS = { path = "#1f77b4", ellipse = "#1f77b4", odometry = "#ff7f0e", tag = "#333333",
  rejected = "#d62728", field = "#888888" }

local COLOURS = M.COLOURS

-- A number for a data attribute.
local function num(v)
  local s = format("%.6g", v)
  if s == "-0" then s = "0" end
  return s
end

--- The 95 % ellipse of a 2×2 position covariance: `localize_geometry.ellipse`.
-- @function ellipse
M.ellipse = geometry.ellipse

--- The rigid motion that best aligns the odometry with the path: `localize_geometry.align`.
-- @function align
M.align = geometry.align

-- The count of rows that rejected each id, of rows that saw it (used or rejected), and the
-- ids rejected that are not on the map.
local function rejections(tags, rows)
  local count, seen, absent = {}, {}, {}
  for _, r in ipairs(rows) do
    if r.tags then
      for _, id in ipairs(r.tags) do seen[id] = (seen[id] or 0) + 1 end
    end
    if r.rejected then
      for _, j in ipairs(r.rejected) do
        local id = j.id
        if id ~= nil then
          count[id] = (count[id] or 0) + 1
          seen[id] = (seen[id] or 0) + 1
          if not tags[id] and not absent[id] then
            absent[id] = true
            absent[#absent + 1] = id
          end
        end
      end
    end
  end
  table.sort(absent, function(a, b) return tostring(a) < tostring(b) end)
  return count, seen, absent
end

local function sx(a, x) return a.left + (x - a.x0) * a.s end
local function sy(a, y) return a.top + (a.y1 - y) * a.s end

-- The grid, the ticks and their labels in metres on both axes (one step for both).
local function axes(out, a)
  local xt, step, decimals = scale.ticks(a.x0, a.x1, max(2, floor(a.width / 60)))
  local yt = scale.ticks(a.y0, a.y1, max(1, (a.y1 - a.y0) / step))
  out[#out + 1] = '<g class="axes" stroke="#e6e6e6" stroke-width="1">'
  for _, v in ipairs(xt) do
    local x = coord(sx(a, v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(x,
      coord(a.top), x, coord(a.top + a.height))
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(x, coord(a.top + a.height), x, coord(a.top + a.height + 4))
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="middle" stroke="none"'
      .. ' fill="#333333">%s</text>'):format(x, coord(a.top + a.height + 6 + FONT),
      label(v, decimals))
  end
  for _, v in ipairs(yt) do
    local y = coord(sy(a, v))
    out[#out + 1] = ('<line class="grid" x1="%s" y1="%s" x2="%s" y2="%s"/>'):format(
      coord(a.left), y, coord(a.left + a.width), y)
    out[#out + 1] = ('<line class="tick" x1="%s" y1="%s" x2="%s" y2="%s" stroke="#444444"/>')
      :format(coord(a.left - 4), y, coord(a.left), y)
    out[#out + 1] = ('<text class="tick-label" x="%s" y="%s" text-anchor="end" stroke="none"'
      .. ' fill="#333333">%s</text>'):format(coord(a.left - 7), coord(sy(a, v) + 0.35 * FONT),
      label(v, decimals))
  end
  out[#out + 1] = "</g>"
  out[#out + 1] = ('<text class="axis-label" x="%s" y="%s" text-anchor="middle">x (m)</text>')
    :format(coord(a.left + a.width / 2), coord(a.top + a.height + 12 + 2 * FONT))
  out[#out + 1] = ('<text class="axis-label" x="%s" y="%s" text-anchor="middle"'
    .. ' transform="rotate(-90 %s %s)">y (m)</text>'):format(coord(a.left - 40),
    coord(a.top + a.height / 2), coord(a.left - 40), coord(a.top + a.height / 2))
end

-- The tags: a segment along each face (its true width, at least 14 px), a tick on the side it
-- faces, its id beyond the tick (and the rows that rejected it / that saw it).
local function draw_tags(out, a, tags, count, seen)
  local rejected = 0
  for _, id in ipairs(tags.ids) do
    if count[id] then rejected = rejected + 1 end
  end
  out[#out + 1] = ('<g class="tags" data-count="%d" data-rejected="%d" stroke-linecap="round">')
    :format(#tags.ids, rejected)
  for _, id in ipairs(tags.ids) do
    local t = tags[id]
    local r = t.r
    -- along the face: the tag's x on the floor; the side it faces: -z (z goes into the tag)
    local ux, uy = r[1], r[4]
    local nu = sqrt(ux * ux + uy * uy)
    if nu < 1e-9 then ux, uy, nu = 1, 0, 1 end
    ux, uy = ux / nu, uy / nu
    local fx, fy = -r[3], -r[6]
    local nf = sqrt(fx * fx + fy * fy)
    local flat = nf < 0.2 -- a tag on the floor or a ceiling faces no side
    if flat then fx, fy = -uy, ux else fx, fy = fx / nf, fy / nf end
    local cx, cy = sx(a, t.x), sy(a, t.y)
    local half = max(0.5 * (t.size or 0) * a.s, 7)
    local dx, dy = ux * half, -uy * half
    local ex, ey = fx, -fy -- on the page
    local n = count[id]
    local colour = escape(n and COLOURS.rejected or COLOURS.tag)
    local text = tostring(id)
    if n then text = format("%s ×%d/%d", text, n, seen[id]) end
    local lx, ly = cx + ex * 18, cy + ey * 18 + 0.35 * FONT
    local anchor = ex > 0.5 and "start" or ex < -0.5 and "end" or "middle"
    if anchor == "middle" and ey > 0 then ly = ly + 0.4 * FONT end
    out[#out + 1] = ('<g class="tag" data-id="%s" data-rejected="%d" data-seen="%d" stroke="%s"'
      .. ' fill="%s">'):format(escape(id), n or 0, seen[id] or 0, colour, colour)
    out[#out + 1] = ("<title>tag %s: seen in %d rows%s</title>"):format(escape(id), seen[id] or 0,
      n and format(", rejected in %d", n) or "")
    out[#out + 1] = ('<line x1="%s" y1="%s" x2="%s" y2="%s" stroke-width="4"/>'):format(
      coord(cx - dx), coord(cy - dy), coord(cx + dx), coord(cy + dy))
    if not flat then
      out[#out + 1] = ('<line x1="%s" y1="%s" x2="%s" y2="%s" stroke-width="1.5"/>'):format(
        coord(cx), coord(cy), coord(cx + ex * 8), coord(cy + ey * 8))
    end
    out[#out + 1] = ('<text x="%s" y="%s" text-anchor="%s" stroke="#ffffff" stroke-width="3"'
      .. ' paint-order="stroke" font-weight="%s">%s</text>'):format(coord(lx), coord(ly), anchor,
      n and "bold" or "normal", escape(text))
    out[#out + 1] = "</g>"
  end
  out[#out + 1] = "</g>"
end

-- The path: polylines broken at gaps in time, a circle at its start and a square at its end.
local function draw_path(out, a, rows)
  local runs, run, last, points = {}, nil, nil, 0
  local first_xy, last_xy
  for _, r in ipairs(rows) do
    if has_position(r) then
      if not run or r.time - last > M.GAP then
        run = {}
        runs[#runs + 1] = run
      end
      local x, y = sx(a, r.position.x), sy(a, r.position.y)
      run[#run + 1] = coord(x) .. "," .. coord(y)
      points = points + 1
      last = r.time
      first_xy = first_xy or { x, y }
      last_xy = { x, y }
    end
  end
  out[#out + 1] = ('<g class="path" data-points="%d" data-runs="%d" stroke="%s" fill="none"'
    .. ' stroke-width="1.6" stroke-linejoin="round">'):format(points, #runs,
    escape(COLOURS.path))
  for _, pts in ipairs(runs) do
    if #pts == 1 then
      local x, y = pts[1]:match("^(.-),(.*)$")
      out[#out + 1] = ('<circle cx="%s" cy="%s" r="1.5" fill="%s"/>'):format(x, y,
        escape(COLOURS.path))
    else
      out[#out + 1] = '<polyline points="' .. concat(pts, " ") .. '"/>'
    end
  end
  if first_xy then
    out[#out + 1] = svg.marker("circle", first_xy[1], first_xy[2], COLOURS.path)
    out[#out + 1] = svg.marker("square", last_xy[1], last_xy[2], COLOURS.path)
  end
  out[#out + 1] = "</g>"
  return points
end

-- The 95 % ellipses of the rows, one every `every` seconds.
local function draw_ellipses(out, a, rows, every)
  local lines, next_time = {}, -huge
  for _, r in ipairs(rows) do
    local c = r.covariance
    if has_position(r) and r.time >= next_time and c and c[1] and c[2] and is_finite(c[1][1])
      and is_finite(c[1][2]) and is_finite(c[2][2]) then
      next_time = r.time + every
      local ea, eb, angle = M.ellipse(c[1][1], c[1][2], c[2][2])
      local cx, cy = coord(sx(a, r.position.x)), coord(sy(a, r.position.y))
      lines[#lines + 1] = ('<ellipse class="ellipse" data-time="%s" data-a="%s" data-b="%s"'
        .. ' data-angle="%s" cx="%s" cy="%s" rx="%s" ry="%s" transform="rotate(%s %s %s)"/>')
        :format(num(r.time), num(ea), num(eb), num(deg(angle)), cx, cy, num(ea * a.s),
        num(eb * a.s), num(-deg(angle)), cx, cy)
    end
  end
  out[#out + 1] = ('<g class="ellipses" data-count="%d" stroke="%s" stroke-width="0.8"'
    .. ' fill="%s" fill-opacity="0.18">'):format(#lines, escape(COLOURS.ellipse),
    escape(COLOURS.ellipse))
  for _, l in ipairs(lines) do out[#out + 1] = l end
  out[#out + 1] = "</g>"
  return #lines
end

-- The odometry through the alignment, dashed.
local function draw_odometry(out, a, odometry, al)
  local c, s = cos(al.theta), sin(al.theta)
  local pts = {}
  for _, o in ipairs(odometry) do
    local x, y = o[2], o[3]
    if is_finite(x) and is_finite(y) then
      pts[#pts + 1] = coord(sx(a, c * x - s * y + al.x)) .. ","
        .. coord(sy(a, s * x + c * y + al.y))
    end
  end
  out[#out + 1] = ('<g class="odometry" data-points="%d" data-rotation="%s" data-dx="%s"'
    .. ' data-dy="%s" data-rms="%s" data-pairs="%d" stroke="%s" fill="none" stroke-width="1.4"'
    .. ' stroke-dasharray="6 4" clip-path="url(#clip-field)">'):format(#pts,
    num(deg(al.theta)), num(al.x), num(al.y), num(al.rms), al.pairs, escape(COLOURS.odometry))
  if #pts > 1 then out[#out + 1] = '<polyline points="' .. concat(pts, " ") .. '"/>' end
  out[#out + 1] = "</g>"
  return #pts
end

local function check(tags, rows, odometry, options)
  if type(tags) ~= "table" or type(tags.ids) ~= "table" then
    return 1, "map tags {ids = {...}, [id] = tag} expected, got " .. args.describe(tags)
  end
  for _, id in ipairs(tags.ids) do
    local t = tags[id]
    if type(t) ~= "table" or type(t.r) ~= "table" or not (is_finite(t.x) and is_finite(t.y)) then
      return 1, "tags[" .. tostring(id) .. "]: a read tag {x =, y =, r =, size =} expected"
    end
  end
  if type(rows) ~= "table" then return 2, "rows table expected, got " .. type(rows) end
  for i, r in ipairs(rows) do
    if type(r) ~= "table" then return 2, "rows[" .. i .. "]: table expected, got " .. type(r) end
  end
  if odometry ~= nil then
    if type(odometry) ~= "table" then
      return 3, "odometry table expected, got " .. type(odometry)
    end
    for i, o in ipairs(odometry) do
      if type(o) ~= "table" or not is_finite(o[1]) then
        return 3, "odometry[" .. i .. "]: {t, x, y, yaw} expected"
      end
    end
  end
  if options ~= nil then
    if type(options) ~= "table" then return 4, "options table expected, got " .. type(options) end
    local e = options.ellipse_every
    if e ~= nil and not args.is_positive(e) then
      return 4, "options.ellipse_every: positive number expected, got " .. args.describe(e)
    end
    if options.title ~= nil and type(options.title) ~= "string" then
      return 4, "options.title: string expected, got " .. type(options.title)
    end
  end
  return nil
end

--- The field from above as an SVG document (see the module's header).
-- @tparam table tags the map's read tags (`loc.tags`)
-- @tparam {table,...} rows the localizer's results in time order
-- @tparam[opt] {table,...} odometry samples `{t, x, y, yaw}` in time order, any frame
-- @tparam[opt] table options `{title = string, ellipse_every = s (ELLIPSE_EVERY)}`
-- @treturn string the SVG document
-- @treturn table what it shows: `{tags =, rejected_tags =, points =, ellipses =, odometry =
--   align's table or nil, odometry_note = string or nil (why none is drawn)}`
-- @raise `bad argument #n to 'svg' (...)` when an argument is not of that shape
-- @usage
-- local text = localize_plot.svg(loc.tags, rows, odometry, {title = "drive 3"})
function M.svg(tags, rows, odometry, options)
  local n, problem = check(tags, rows, odometry, options)
  if n then args.raise(n, "svg", problem, 2) end
  options = options or {}
  local count, seen, absent = rejections(tags, rows)
  local al, why
  if odometry and #odometry > 0 then al, why = M.align(rows, odometry) end
  local x0, x1, y0, y1 = geometry.bounds(tags, rows, M.MARGIN)
  local a = geometry.frame(x0, x1, y0, y1, M.MAX_WIDTH, M.MAX_HEIGHT)
  local margin = 16
  a.left = margin + 52
  local width = ceil(a.left + a.width + margin)
  -- the title and the legend
  local head = {}
  local top = margin + svg.TITLE_FONT
  head[#head + 1] = ('<text class="title" x="%s" y="%s" font-size="%d" font-weight="bold">%s'
    .. '</text>'):format(coord(margin), coord(top), svg.TITLE_FONT,
    escape(options.title or "The field from above"))
  top = top + 10
  local entries = {
    { label = "estimated path (start ○, end □)", colour = COLOURS.path },
    { label = format("95 %% position ellipse, every %s s", num(options.ellipse_every
      or M.ELLIPSE_EVERY)), colour = COLOURS.ellipse, dash = "2 2" },
  }
  entries[#entries + 1] = { label = "tag (id; tick: the side it faces)", colour = COLOURS.tag }
  entries[#entries + 1] = { label = "tag rejected (×rows rejected/rows seen)",
    colour = COLOURS.rejected }
  if al then
    entries[#entries + 1] = { label = format("odometry, moved onto the path by the best rigid"
      .. " fit (rotated %.1f°, shifted %.2f, %.2f m; rms %.3f m over %d times)", deg(al.theta),
      al.x, al.y, al.rms, al.pairs), colour = COLOURS.odometry, dash = "6 4" }
  end
  local legend, legend_height = svg.legend(entries, margin, top, width - 2 * margin)
  for _, l in ipairs(legend) do head[#head + 1] = l end
  top = top + legend_height
  local notes = {}
  if why then notes[#notes + 1] = "odometry not drawn: no row within its times" end
  if #absent > 0 then
    local parts = {}
    for _, id in ipairs(absent) do parts[#parts + 1] = format("%s ×%d", tostring(id), count[id]) end
    notes[#notes + 1] = "rejected, not on the map: " .. concat(parts, ", ")
  end
  if #rows == 0 then notes[#notes + 1] = "no estimate" end
  for _, note in ipairs(notes) do
    top = top + FONT + 6
    head[#head + 1] = ('<text class="note" x="%s" y="%s" fill="#555555">%s</text>'):format(
      coord(margin), coord(top), escape(note))
  end
  a.top = top + 18
  local height = ceil(a.top + a.height + 16 + 2 * FONT + margin)
  local body = {}
  body[#body + 1] = ('<rect class="field" x="%s" y="%s" width="%s" height="%s" fill="#fbfbf7"'
    .. ' stroke="none"/>'):format(coord(a.left), coord(a.top), coord(a.width), coord(a.height))
  axes(body, a)
  body[#body + 1] = ('<rect class="field-outline" data-x0="%s" data-x1="%s" data-y0="%s"'
    .. ' data-y1="%s" data-scale="%s" x="%s" y="%s" width="%s" height="%s" fill="none"'
    .. ' stroke="%s" stroke-width="1.2"/>'):format(num(a.x0), num(a.x1), num(a.y0), num(a.y1),
    num(a.s), coord(a.left), coord(a.top), coord(a.width), coord(a.height),
    escape(COLOURS.field))
  local shown = { tags = #tags.ids, rejected_tags = 0, odometry = al, odometry_note = why }
  for _, id in ipairs(tags.ids) do
    if count[id] then shown.rejected_tags = shown.rejected_tags + 1 end
  end
  if al then draw_odometry(body, a, odometry, al) end
  shown.ellipses = draw_ellipses(body, a, rows, options.ellipse_every or M.ELLIPSE_EVERY)
  shown.points = draw_path(body, a, rows)
  draw_tags(body, a, tags, count, seen)
  local out = {
    '<?xml version="1.0" encoding="UTF-8"?>',
    ('<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="%d" height="%d"'
      .. ' viewBox="0 0 %d %d" font-family="DejaVu Sans, Arial, sans-serif" font-size="%d">')
      :format(width, height, width, height, FONT),
    "<title>" .. escape(options.title or "The field from above") .. "</title>",
    ('<defs><clipPath id="clip-field"><rect x="%s" y="%s" width="%s" height="%s"/></clipPath>'
      .. '</defs>'):format(coord(a.left), coord(a.top), coord(a.width), coord(a.height)),
    '<rect width="100%" height="100%" fill="#ffffff"/>',
  }
  for _, part in ipairs({ head, body }) do
    for _, l in ipairs(part) do out[#out + 1] = l end
  end
  out[#out + 1] = "</svg>"
  out[#out + 1] = ""
  return concat(out, "\n"), shown
end

return M
