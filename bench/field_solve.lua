-- The field benchmark's tagpose side: every view of a set drawn by bench/make_field.lua solved
-- with tagpose.layout.solve against the field map, the camera put on the field with
-- tagpose.transform.inverse, and compared with the truth.
--
--   lua5.4 bench/field_solve.lua DIR [--map PATH] [--sigma PX]
--
-- Writes DIR/tagpose.csv (frame,tags,x,y,z,qw,qx,qy,qz,error,confidence,ax,ay,az,
-- alt_confidence: the camera → field pose, its alternative's position when the view is
-- ambiguous) and prints the camera position error (median, p95, views more than 0.5 m off)
-- against DIR/truth.csv, the time of layout.solve plus transform.inverse (os.clock; the first
-- views include LuaJIT's compiling), and what the bodies report of the planar ambiguity in the
-- views of one tag or of tags in one plane.
-- bench/field_opencv.py DIR prints them beside OpenCV's.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")
local transform = require("tagpose.transform")
local log = require("tagpose.tools.log")
local map = dofile((arg[0]:match("^(.*)/[^/]*$") or ".") .. "/field_map.lua")

local sqrt, floor, clock = math.sqrt, math.floor, os.clock
local format = string.format

local USAGE = "usage: lua bench/field_solve.lua DIR [--map PATH] [--sigma PX]"

-- The rows of a CSV table read whole by tagpose.tools.log (log.read_corners or log.read_csv),
-- and its problems: a row that could not be read is an error here, not a view left out.
local function checked(path, rows, problems)
  if not rows then error(problems, 0) end
  if problems[1] then
    error(format("%s:%d: %s", path, problems[1].line, problems[1].reason), 0)
  end
  return rows
end

local function percentile(sorted, p)
  local x = p * (#sorted - 1) + 1
  local i = floor(x)
  if i >= #sorted then return sorted[#sorted] end
  return sorted[i] + (x - i) * (sorted[i + 1] - sorted[i])
end

-- The views of DIR/corners.csv: frame -> detections, and the frames in order.
local function read_views(dir)
  local frames, order = {}, {}
  for _, row in ipairs(checked(dir .. "/corners.csv", log.read_corners(dir .. "/corners.csv"))) do
    local f = row.frame
    if not frames[f] then
      frames[f] = {}
      order[#order + 1] = f
    end
    local d = frames[f]
    d[#d + 1] = { id = row.tag, corners = row.corners }
  end
  return frames, order
end

-- Are the tags of a view in one plane of the map (normals within 10°, centres within 1 cm of
-- the first tag's plane)? From WPILib's frame, not tagpose's.
local function one_plane(field, dets)
  local t = field.tags[dets[1].id]
  local nx, ny, nz = map.normal(t)
  for i = 2, #dets do
    local o = field.tags[dets[i].id]
    local ox, oy, oz = map.normal(o)
    if nx * ox + ny * oy + nz * oz < math.cos(math.rad(10)) then return false end
    if math.abs(nx * (o.x - t.x) + ny * (o.y - t.y) + nz * (o.z - t.z)) > 0.01 then
      return false
    end
  end
  return true
end

local function distance(p, t)
  return sqrt((p.x - t.x) ^ 2 + (p.y - t.y) ^ 2 + (p.z - t.z) ^ 2)
end

-- What the body says of the planar ambiguity, tallied: views (of one tag, or of tags in one
-- plane), those with an alternative, bodies > 0.5 m off and their alternatives within 0.5 m,
-- bodies nearer the truth than their alternative and the sum of their confidences; and
-- alternatives in the other views.
local function tally(a, ambiguous, body, cam, alt, t)
  if not ambiguous then
    if alt then a.elsewhere = a.elsewhere + 1 end
    return
  end
  a.views = a.views + 1
  if not alt then return end
  local e, ea = distance(cam.position, t), distance(alt.position, t)
  a.reported = a.reported + 1
  a.confidence = a.confidence + body.confidence
  if e <= ea then a.right = a.right + 1 end
  if e > 0.5 then
    a.far = a.far + 1
    if ea <= 0.5 then a.saved = a.saved + 1 end
  end
end

local function main(argv)
  local dir = argv[1]
  if not dir then error(USAGE, 0) end
  local o = { map = "bench/field/2024-crescendo.json" }
  local i = 2
  while argv[i] do
    local key = argv[i]:match("^%-%-(.+)$")
    if not (key == "map" or key == "sigma") or not argv[i + 1] then error(USAGE, 0) end
    o[key] = key == "sigma" and tonumber(argv[i + 1]) or argv[i + 1]
    i = i + 2
  end
  local camera, info = assert(tagpose.calibration.read(dir .. "/camera.lua"))
  local field = map.read(o.map)
  local layout = map.layout(field, info.tag_size)
  local frames, order = read_views(dir)
  local truth = {}
  -- read_csv: rows, header, problems; or nil, why
  local rows, refused, problems = log.read_csv(dir .. "/truth.csv")
  for _, row in ipairs(checked(dir .. "/truth.csv", rows, rows and problems or refused)) do
    truth[row.frame] = row
  end
  local out = assert(io.open(dir .. "/tagpose.csv", "w"))
  out:write("frame,tags,x,y,z,qw,qx,qy,qz,error,confidence,ax,ay,az,alt_confidence\n")
  local errors, failed, total_time = {}, 0, 0
  local single, plane = {}, {}
  for _, a in ipairs({ single, plane }) do
    a.views, a.reported, a.right, a.confidence, a.far, a.saved, a.elsewhere = 0, 0, 0, 0, 0, 0, 0
  end
  local options = { sigma = o.sigma }
  for _, f in ipairs(order) do
    local t0 = clock()
    local body, why = tagpose.layout.solve(frames[f], camera, layout, options)
    local cam = body and transform.inverse(body)
    local alt = body and body.alternative and transform.inverse(body.alternative)
    total_time = total_time + (clock() - t0)
    if not cam then
      failed = failed + 1
      io.stderr:write(format("frame %d: %s\n", f, tostring(why)))
    else
      local p, q = cam.position, cam.quaternion
      local ap = alt and alt.position or { x = 0 / 0, y = 0 / 0, z = 0 / 0 }
      out:write(format("%d,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.6g,%.6g,%.17g,%.17g,"
        .. "%.17g,%.6g\n", f, #frames[f], p.x, p.y, p.z, q.w, q.x, q.y, q.z, body.error,
        body.confidence, ap.x, ap.y, ap.z, alt and alt.confidence or 0))
      errors[#errors + 1] = distance(p, truth[f])
      local n = #frames[f]
      tally(n == 1 and single or plane, n == 1 or one_plane(field, frames[f]), body, cam, alt,
        truth[f])
    end
  end
  out:close()
  table.sort(errors)
  local far = 0
  for _, e in ipairs(errors) do
    if e > 0.5 then far = far + 1 end
  end
  print(format("tagpose %s: %d views, %d solved; camera position error median %.4f m, p95 "
    .. "%.4f m, %d views > 0.5 m off; %.0f us per view (layout.solve + transform.inverse)",
    dir, #order, #order - failed, percentile(errors, 0.5), percentile(errors, 0.95), far,
    1e6 * total_time / #order))
  for _, k in ipairs({ { "one tag", single }, { "tags in one plane", plane } }) do
    local a = k[2]
    print(format("  views of %s: %d, %d with an alternative (mean confidence %.3f, the body "
      .. "nearer the truth in %.3f); %d bodies > 0.5 m off, their alternative within 0.5 m in %d",
      k[1], a.views, a.reported, a.reported > 0 and a.confidence / a.reported or 0,
      a.reported > 0 and a.right / a.reported or 0, a.far, a.saved))
  end
  print(format("  views of tags in several planes with an alternative: %d", plane.elsewhere))
end

local ok, err = pcall(main, arg)
if not ok then
  io.stderr:write(tostring(err), "\n")
  os.exit(2)
end
