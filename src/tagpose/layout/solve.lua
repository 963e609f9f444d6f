--- The pose of a layout (a rigid body carrying tags) from one frame's detections.
--
-- 1. Every detection of a tag of the layout is solved alone (the refined single-tag solve): one
--    or two poses (the planar ambiguity), each implying a body pose `R_b = R·Qᵀ`,
--    `t_b = t - R_b·p` for the tag placed at `(Q, p)` on the body. These are the starts. A tag
--    that cannot be solved alone (seen nearly edge-on, its noisy corners not a convex
--    quadrilateral) still joins the joint fit with its corners, when another tag gives starts.
-- 2. One tag seen: its candidates are the body's minima (the same least-squares problem), so
--    that a layout seen by one tag has the pose and uncertainty `tagpose.solve` gives the tag.
-- 3. Otherwise the joint fit (`tagpose.layout.fit`: least squares over every corner through the
--    lens) runs from the start that fits all the corners best. With only tags in one plane it
--    runs from every start (the `PLANE_STARTS` that fit best: two distant tags on one wall have
--    several minima, and the best start alone often leads to a worse one) and from the best
--    minimum mirrored about the line of sight to the tags' centroid (the planar ambiguity of
--    the plane); the best minimum is the pose, the best other distinct one its `alternative`.
--
-- The uncertainty (`tagpose.uncertainty`), σ being `options.sigma`, else the fit's residuals
-- (`8n - 6` degrees of freedom for n tags, 2 for one), topped up with
-- `tagpose.uncertainty.DEFAULT_SIGMA` to the degrees of freedom they lack
-- (`tagpose.uncertainty.noise`: two tags or more have enough and are judged by their own), the
-- covariances then taking the factor κ that makes their 95 % ellipsoid hold 95 % with σ²
-- estimated (`tagpose.uncertainty.ellipsoid`):
--
-- - one tag seen: the tag's own — its branch probability and covariance as `tagpose.solve`
--   gives them, the covariance moved from the tag to the body origin;
-- - tags in one plane: `σ²·H⁻¹` of each minimum's normal equations, and the confidence of the
--   two minima's Laplace evidence (their squared errors and the log-determinants of their
--   normal equations);
-- - tags on planes at an angle: `σ²·H⁻¹`, confidence 1.
--
-- Lengths are in the layout's unit, angles in radians, errors in pixels.
-- @module tagpose.layout.solve

local rotation = require("tagpose.core.rotation")
local args = require("tagpose.core.args")
local compat = require("tagpose.core.compat")
local fit = require("tagpose.layout.fit")
local minima = require("tagpose.layout.minima")
local pipeline = require("tagpose.core.pipeline")
local uncertainty = require("tagpose.uncertainty")

local sqrt, cos, huge = math.sqrt, math.cos, math.huge
local mul_t = rotation.multiply_transpose

local M = {}

--- Tags whose normals are within this angle (radians) of one another...
M.COPLANAR_ANGLE = math.rad(10)
--- ... and whose centres lie within this distance (× the largest tag side) of one plane leave
-- the view ambiguous: both branches are fit.
M.COPLANAR_DISTANCE = 0.1
--- Two minima closer than this angle (radians) are one.
M.TWIN_ANGLE = 1e-6
--- A minimum of a one-tag view whose tag rotation is within this angle (radians) of one of the
-- tag's own candidates is on its branch (the uncertainty is then the tag's).
M.SAME_BRANCH = math.rad(5)
--- Default bound on the linearisations of one joint fit.
M.MAX_ITERATIONS = 20

-- scratch, reused by every call and never handed out
local points, pixels = {}, {}
local corners = {}
local start_r, start_t = {}, {} -- the starts: flat rotations (9 each), translations (3 each)
local r_a, r_b = {}, {}
local normal_a, normal_b = {}, {}

local work = pipeline.new() -- the single-tag pipeline's workspace

-- One detection's corners (read into `corners`) solved alone: its candidate poses (copies:
-- `{r = flat, tx, ty, tz}`, the better first, the other minimum second when there is one), or
-- nil and why.
local function solve_tag(camera, size)
  local w = work
  for k = 1, 8 do w.px[k] = corners[k] end
  local ok, why = pipeline.tag(w, camera, 0.5 * size)
  if not ok then return nil, why end
  local out = {}
  for k = 1, w.count do
    local c = k == 1 and w.first or w.second
    local r = {}
    for i = 1, 9 do r[i] = c.r[i] end
    local N = c.normal
    out[k] = { r = r, tx = c.tx, ty = c.ty, tz = c.tz, sse = c.sse,
      linearisations = c.linearisations, normal = { N[1], N[2], N[3],
      N[4], N[5], N[6], N[7], N[8], N[9], N[10], N[11], N[12], N[13], N[14], N[15], N[16], N[17],
      N[18], N[19], N[20], N[21] } }
  end
  return out
end

-- σ² of the covariances and confidences, options.sigma² or the fit's residuals topped up with
-- the default; and κ, the factor on the covariances (1 for a given σ).
local function noise(sse, n, sigma)
  return uncertainty.noise(sse, sigma, n > 1 and 8 * n - 6 or 2)
end

-- Are the used tags all in one plane (normals and centres)?
local function coplanar(used, n)
  if n < 2 then return true end
  local t = used[1].tag
  local nx, ny, nz = t.r[3], t.r[6], t.r[9]
  local size = t.size
  for i = 2, n do
    local s = used[i].tag.size
    if s > size then size = s end
  end
  local limit, gate = M.COPLANAR_DISTANCE * size, cos(M.COPLANAR_ANGLE)
  for i = 2, n do
    local o = used[i].tag
    local c = nx * o.r[3] + ny * o.r[6] + nz * o.r[9]
    if c < 0 then c = -c end
    if c < gate then return false end
    local d = nx * (o.x - t.x) + ny * (o.y - t.y) + nz * (o.z - t.z)
    if d < 0 then d = -d end
    if d > limit then return false end
  end
  return true
end

-- The start of the other minimum of tags in one plane: the pose (r, t) mirrored about the line
-- of sight v to the tags' centroid c, R' = (I - 2 v vᵀ)·R·(I - 2 n nᵀ) (n the plane's normal in
-- the body), which keeps c and the plane's points' lines of sight; into out, and t'.
local function mirror(used, n, r, tx, ty, tz, out)
  local cx, cy, cz = 0, 0, 0
  for i = 1, n do
    local t = used[i].tag
    cx, cy, cz = cx + t.x / n, cy + t.y / n, cz + t.z / n
  end
  local t1 = used[1].tag.r
  local n1, n2, n3 = t1[3], t1[6], t1[9]
  -- c in the camera, and v
  local px = r[1] * cx + r[2] * cy + r[3] * cz + tx
  local py = r[4] * cx + r[5] * cy + r[6] * cz + ty
  local pz = r[7] * cx + r[8] * cy + r[9] * cz + tz
  local d = sqrt(px * px + py * py + pz * pz)
  local v1, v2, v3 = px / d, py / d, pz / d
  -- R·(I - 2 n nᵀ): each row minus 2 (row·n) nᵀ; then (I - 2 v vᵀ) on the left
  local m = {}
  for row = 0, 6, 3 do
    local k = 2 * (r[row + 1] * n1 + r[row + 2] * n2 + r[row + 3] * n3)
    m[row + 1], m[row + 2], m[row + 3] = r[row + 1] - k * n1, r[row + 2] - k * n2,
      r[row + 3] - k * n3
  end
  for col = 1, 3 do
    local a, b, c = m[col], m[3 + col], m[6 + col]
    local k = 2 * (v1 * a + v2 * b + v3 * c)
    out[col], out[3 + col], out[6 + col] = a - k * v1, b - k * v2, c - k * v3
  end
  return px - (out[1] * cx + out[2] * cy + out[3] * cz),
    py - (out[4] * cx + out[5] * cy + out[6] * cz),
    pz - (out[7] * cx + out[8] * cy + out[9] * cz)
end

-- Add the body pose implied by a tag pose as start number k.
local function add_start(k, cand, tag)
  local o = 9 * (k - 1)
  local rb = mul_t(cand.r, tag.r, r_a)
  for i = 1, 9 do start_r[o + i] = rb[i] end
  local x, y, z = tag.x, tag.y, tag.z
  o = 3 * (k - 1)
  start_t[o + 1] = cand.tx - (rb[1] * x + rb[2] * y + rb[3] * z)
  start_t[o + 2] = cand.ty - (rb[4] * x + rb[5] * y + rb[6] * z)
  start_t[o + 3] = cand.tz - (rb[7] * x + rb[8] * y + rb[9] * z)
end

-- The start k into r (flat) and its translation.
local function get_start(k, r)
  local o = 9 * (k - 1)
  for i = 1, 9 do r[i] = start_r[o + i] end
  o = 3 * (k - 1)
  return start_t[o + 1], start_t[o + 2], start_t[o + 3]
end

-- The usable detections: those of tags of the layout with four finite corners, each solved
-- alone for the starts; a tag that cannot be solved alone (seen nearly edge-on, its noisy
-- corners not a convex quadrilateral) is a passenger: its corners join the joint fit, it gives
-- no start. The others go into skipped with their reason. Fills points, pixels and the starts.
local function gather(detections, camera, tags, skipped, opencv)
  local used, n, starts = {}, 0, 0
  local first_of = {}
  for i = 1, #detections do
    local d = detections[i]
    local reason, tag, pose, passenger
    if type(d) ~= "table" then
      reason = "layout: detection is not a table {id =, corners =}"
    else
      tag = tags[d.id]
      local ok, why = args.read_corners(d.corners, corners, opencv)
      if not tag then
        reason = "layout: tag id " .. tostring(d.id) .. " is not in the layout"
      elseif not ok then
        reason = "layout: " .. why
      elseif ok ~= true then
        reason = "layout: corner " .. ok .. " is not finite"
      elseif first_of[d.id] then
        reason = "layout: tag id " .. tostring(d.id) .. " is detected twice (detection "
          .. first_of[d.id] .. " is used)"
      else
        pose, reason = solve_tag(camera, tag.size)
        passenger = not pose
      end
    end
    if pose or passenger then
      n = n + 1
      first_of[d.id] = i
      used[n] = { index = i, id = d.id, tag = tag, pose = pose, reason = reason }
      local o = 8 * (n - 1)
      for k = 1, 8 do pixels[o + k] = corners[k] end
      local p, q = tag.points, 12 * (n - 1)
      for k = 1, 12 do points[q + k] = p[k] end
      for k = 1, pose and #pose or 0 do
        starts = starts + 1
        add_start(starts, pose[k], tag)
      end
    else
      skipped[#skipped + 1] = { index = i, id = type(d) == "table" and d.id or nil,
        reason = reason }
    end
  end
  return used, n, starts
end

local function by_index(a, b) return a.index < b.index end

-- The public pose table of a minimum (its covariance set by `uncertain`).
local function result(r, x, y, z, sse, k, npts)
  local w, qx, qy, qz = rotation.to_quaternion(r)
  return {
    position = { x = x, y = y, z = z },
    rotation = rotation.to_nested(r),
    quaternion = { w = w, x = qx, y = qy, z = qz },
    error = sqrt(sse / npts),
    iterations = k,
  }
end

-- Covariances and confidences of the body (minimum a) and its alternative (minimum b, or nil),
-- σ² s2 and the covariances' factor kappa: see the module's header.
local function uncertain(n, body, alt, a, b, s2, kappa)
  local c2 = kappa * s2
  if n == 1 then
    local ta, tb = a.tag, b and b.tag
    uncertainty.assess(ta, tb, s2)
    body.covariance = uncertainty.move(uncertainty.from_normal(ta.normal, c2, kappa * ta.k,
      ta.chord), a.x - ta.tx, a.y - ta.ty, a.z - ta.tz)
    body.confidence = ta.confidence
    if b then
      alt.covariance = uncertainty.move(uncertainty.from_normal(tb.normal, c2, kappa * tb.k,
        tb.chord), b.x - tb.tx, b.y - tb.ty, b.z - tb.tz)
      alt.confidence = tb.confidence
    end
    return
  end
  local ld_a, ld_b
  body.covariance, ld_a = uncertainty.from_normal(a.normal, c2, 0)
  body.confidence = 1
  if b then
    alt.covariance, ld_b = uncertainty.from_normal(b.normal, c2, 0)
    body.confidence = uncertainty.probability((b.sse - a.sse) / (2 * s2) + 0.5 * (ld_b - ld_a))
    alt.confidence = 1 - body.confidence
  end
end

local finite = minima.finite

-- The used tags' indices and ids, and the skipped detections, on the body.
local function finish(body, used, n, skipped)
  local list, ids = {}, {}
  for i = 1, n do
    list[i], ids[i] = used[i].index, used[i].id
  end
  body.tags, body.ids, body.skipped = list, ids, skipped
  return body
end

-- A minimum of one tag seen alone: the body pose its candidate c implies.
local function tag_minimum(c, k)
  local r = {}
  local x, y, z = get_start(k, r)
  return { r = r, x = x, y = y, z = z, sse = c.sse, k = c.linearisations, tag = c }
end

-- One tag seen: its candidates (starts 1 and 2) are the minima.
local function one_tag(used, skipped, o)
  local pose = used[1].pose
  local a = tag_minimum(pose[1], 1)
  local b = pose[2] and tag_minimum(pose[2], 2)
  local body = result(a.r, a.x, a.y, a.z, a.sse, a.k, 4)
  local alt = b and result(b.r, b.x, b.y, b.z, b.sse, b.k, 4)
  uncertain(1, body, alt, a, b, noise(a.sse, 1, o.sigma))
  body.alternative = alt
  return finish(body, used, 1, skipped)
end

--- Solve a layout's pose from one frame's detections.
-- @tparam table detections array of `{id =, corners =}`
-- @tparam table camera a checked camera
-- @tparam table tags read tags by id (`tagpose.rigid.model.read_tag`)
-- @tparam table o the options: `sigma`, `max_iterations`, `opencv` (the corners in OpenCV's
--   order)
-- @treturn table the body (see `tagpose.layout.solve`)
-- @return nil, string when no detection gives a body pose
function M.solve(detections, camera, tags, o)
  local skipped = {}
  local used, n, starts = gather(detections, camera, tags, skipped, o.opencv)
  if starts == 0 then
    -- no tag solved alone: the passengers are skipped with their reasons
    for i = 1, n do
      local u = used[i]
      skipped[#skipped + 1] = { index = u.index, id = u.id, reason = u.reason }
    end
    table.sort(skipped, by_index)
    local why = skipped[1] and skipped[1].reason
    return nil, "layout: no detection gives a pose of a tag of the layout"
      .. (why and " (detection " .. skipped[1].index .. ": " .. why .. ")" or "")
  end
  local npts = 4 * n
  if n == 1 then return one_tag(used, skipped, o) end
  local max_it = o.max_iterations or M.MAX_ITERATIONS
  local plane = coplanar(used, n)
  local found = minima.find(camera, points, pixels, npts, starts, get_start, max_it, plane)
  if plane and found[1] then
    -- the other branch of the whole plane: the best minimum mirrored about the line of sight
    local m = found[1]
    local bx, by, bz = mirror(used, n, m.r, m.x, m.y, m.z, r_b)
    minima.keep(found, camera, points, pixels, npts, r_b, bx, by, bz, max_it)
  end
  if not found[1] then return nil, "layout: the joint fit put a corner behind the camera" end
  -- the best minimum, and where the view is ambiguous (tags in one plane) the best other one,
  -- each fit on from where it stopped, with its normal equations
  local m = found[1]
  for i = 1, 9 do r_a[i] = m.r[i] end
  local ax, ay, az, cost_a, k_a, sse_a = fit.fit(camera, points, pixels, npts, r_a, m.x, m.y, m.z,
    max_it, nil, normal_a)
  if not (cost_a < huge and finite(r_a, ax, ay, az, sse_a)) then
    return nil, "layout: the joint fit put a corner behind the camera"
  end
  k_a = k_a + m.k
  local other = plane and found[2] or nil
  local bx, by, bz, cost_b, k_b, sse_b
  if other then
    for i = 1, 9 do r_b[i] = other.r[i] end
    bx, by, bz, cost_b, k_b, sse_b = fit.fit(camera, points, pixels, npts, r_b, other.x, other.y,
      other.z, max_it, nil, normal_b)
    k_b = k_b + other.k
    if not (cost_b < huge and finite(r_b, bx, by, bz, sse_b))
      or rotation.angle(r_a, r_b) < M.TWIN_ANGLE then
      other = nil
    end
  end
  local a = { r = r_a, x = ax, y = ay, z = az, sse = sse_a, k = k_a, normal = normal_a }
  local b = other and { r = r_b, x = bx, y = by, z = bz, sse = sse_b, k = k_b,
    normal = normal_b }
  if b and b.sse < a.sse then a, b = b, a end
  local body = result(a.r, a.x, a.y, a.z, a.sse, a.k, npts)
  local alt = b and result(b.r, b.x, b.y, b.z, b.sse, b.k, npts)
  uncertain(n, body, alt, a, b, noise(a.sse, n, o.sigma))
  body.alternative = alt
  return finish(body, used, n, skipped)
end

compat.interpret(M.solve)

return M
