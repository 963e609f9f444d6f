--- The report of a calibration (`tagpose.layout.calibrate`): what was used, what each tag's
-- correction is, how well the result fits, and what could not be placed.
--
-- A report is
--
--     {
--       tags = {[id] = {
--         observations =, outliers =, rms =,       -- detections used, down-weighted, px
--         shift = {x =, y =, z =}, distance =,     -- calibrated - nominal centre, body frame
--         in_plane =, normal =,                    -- the shift in the tag's plane, along its z
--         angle =, axis = {x =, y =, z =},          -- the turn from the nominal pose (body)
--         turn =, tilt =,                          -- about the tag's normal (signed), of it
--       }},
--       unplaced = {{id =, reason =}, ...},        -- tags that could not be placed, by id
--       frames = {total =, used =, single =, unknown =, failed =, elsewhere =},
--       detections = {total =, used =, skipped =, outliers =},
--       rms_start =, rms =, sigma =,               -- px: before, after, corner noise
--       reference =, alignment =,                  -- the gauge: tag held fixed, RMS move
--       iterations =, stages =, mended =, converged =,
--     }
--
-- Lengths in the layout's unit, angles in radians (`turn` positive anticlockwise about the
-- tag's z, i.e. clockwise as the camera sees the tag), pixels for residuals.
-- @module tagpose.layout.report

local rotation = require("tagpose.core.rotation")
local compat = require("tagpose.core.compat")

local sqrt, max = math.sqrt, math.max
local atan2 = compat.atan2

local M = {}

-- The correction of a tag from its nominal pose (n) to its calibrated one (c).
local function correction(n, c, entry)
  local dx, dy, dz = c.x - n.x, c.y - n.y, c.z - n.z
  local r = n.r
  -- the shift in the nominal tag frame: rᵀ·d
  local s1 = r[1] * dx + r[4] * dy + r[7] * dz
  local s2 = r[2] * dx + r[5] * dy + r[8] * dz
  local s3 = r[3] * dx + r[6] * dy + r[9] * dz
  entry.shift = { x = dx, y = dy, z = dz }
  entry.distance = sqrt(dx * dx + dy * dy + dz * dz)
  entry.in_plane, entry.normal = sqrt(s1 * s1 + s2 * s2), s3
  -- the turn, in the body frame (c.r·n.rᵀ) and in the tag frame (n.rᵀ·c.r)
  local wx, wy, wz = rotation.to_rotation_vector(rotation.multiply_transpose(c.r, r))
  local angle = sqrt(wx * wx + wy * wy + wz * wz)
  local ax, ay, az = 1, 0, 0
  if angle > 0 then ax, ay, az = wx / angle, wy / angle, wz / angle end
  entry.angle, entry.axis = angle, { x = ax, y = ay, z = az }
  local w, _, _, qz = rotation.to_quaternion(rotation.transpose_multiply(r, c.r))
  entry.turn = 2 * atan2(qz, w)
  -- the angle between the normals, from its sine and cosine (acos loses it near 0)
  local a1, a2, a3, b1, b2, b3 = r[3], r[6], r[9], c.r[3], c.r[6], c.r[9]
  local x1, x2, x3 = a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1
  entry.tilt = atan2(sqrt(x1 * x1 + x2 * x2 + x3 * x3), a1 * b1 + a2 * b2 + a3 * b3)
  return entry
end

local function reason_for(id, d)
  if d.placed[id] then return nil end
  if d.seen[id] == 0 then
    if d.single_seen[id] then
      return "seen only in frames without another tag of the layout"
    end
    return "never seen in the log"
  end
  return "never seen together with the tags linked to the reference tag "
    .. tostring(d.reference)
end

--- Build the report.
-- @tparam table d what the calibration gathered: `P` (the bundle problem, residuals at the
--   result in `P.s`), `order` (the placed ids by slot), `tags` (the nominal layout, read),
--   `poses` (id → calibrated `{r, x, y, z}`), `seen`, `single_seen`, `placed`, `reference`,
--   `counts`, `weights` (per observation), `outlier_weight`, `sigma` (given, or nil),
--   `sigma_robust`, `iterations`, `stages`, `mended`, `alignment`, `rms_start`, `converged`
-- @treturn table the report
function M.build(d)
  local P = d.P
  local per = {}
  local sse_all, sse_in, n_in, outliers = 0, 0, 0, 0
  for i = 1, #d.order do per[i] = { n = 0, out = 0, sse = 0, n_in = 0 } end
  for o = 1, #P.of do
    local t = per[P.ot[o]]
    local s = P.s[o]
    t.n = t.n + 1
    sse_all = sse_all + s
    if d.weights[o] < d.outlier_weight then
      t.out = t.out + 1
      outliers = outliers + 1
    else
      t.sse, t.n_in = t.sse + s, t.n_in + 1
      sse_in, n_in = sse_in + s, n_in + 1
    end
  end
  local tags, unplaced = {}, {}
  for _, id in ipairs(d.tags.ids) do
    local why = reason_for(id, d)
    if why then unplaced[#unplaced + 1] = { id = id, reason = why } end
  end
  for i, id in ipairs(d.order) do
    local t = per[i]
    tags[id] = correction(d.tags[id], d.poses[id], {
      observations = t.n, outliers = t.out,
      rms = t.n_in > 0 and sqrt(t.sse / (8 * t.n_in)) or 0,
    })
  end
  local nobs = #P.of
  local dof = 8 * n_in - 6 * P.nframes - 6 * (P.ntags - 1)
  local c = d.counts
  return {
    tags = tags,
    unplaced = unplaced,
    frames = { total = c.total, used = c.used, single = c.single, unknown = c.unknown,
      failed = c.failed, elsewhere = c.elsewhere },
    detections = { total = c.detections, used = nobs, skipped = c.skipped,
      outliers = outliers },
    rms_start = d.rms_start,
    rms = sqrt(sse_all / (8 * nobs)),
    sigma = d.sigma or sqrt(sse_in / max(dof, 1)),
    sigma_robust = d.sigma_robust,
    reference = d.reference,
    alignment = d.alignment,
    iterations = d.iterations,
    stages = d.stages,
    mended = d.mended,
    converged = d.converged,
  }
end

return M
