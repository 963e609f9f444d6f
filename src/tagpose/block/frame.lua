--- Blocks: the record of one frame — its detections solved as single tags (both poses of each,
-- as block candidates), the frame's corner noise, and what may change while the frame is
-- solved (`up` and `floor` when found with "auto", the priors' weights).
--
-- A detection record: `{index = its place in the caller's array, px = flat pixels,
-- half = half its tag's side, place = where its tag is on the block (`tagpose.block.body`; for
-- a symmetric block the identity place, its own frame), cands = {candidate, ...}, best_sse}`;
-- a candidate: `{r = flat block → camera rotation R·Qᵀ, x, y, z = the block centre it implies,
-- t - R·Qᵀ·p, for the tag pose (R, t) at the place (Q, p), sse = the tag's squared error (px²),
-- depth = the standard deviation of its depth per pixel of corner noise}`.
--
-- The frame record: `settings` (`tagpose.block.options`, read only), `body` (the block,
-- `tagpose.block.body`), the packed camera `C`, `half_block`, `block_size`, `dets`, `skipped`
-- (`{index =, reason =}` each), `first_reason`, the noise (`sigma2` px², `noise_sse`,
-- `noise_dof`, and for the F-test `n` and `frame_sse`), `up` and `floor` (those in use),
-- `prior_w` and `floor_w` (the priors' weights, px per radian and px per length unit),
-- `default_up`.
-- @module tagpose.block.frame

local args = require("tagpose.core.args")
local body_model = require("tagpose.block.body")
local cube = require("tagpose.rigid.cube")
local lsq = require("tagpose.core.lsq")
local pipeline = require("tagpose.core.pipeline")
local rotation = require("tagpose.core.rotation")

local sqrt, abs, max = math.sqrt, math.abs, math.max
local mul_t = rotation.multiply_transpose
local IDENTITY = cube.ROTATIONS[1]

local M = {}

require("tagpose.core.compat").interpret_module()

--- Floor of the corner noise variance estimate (px²).
M.NOISE_FLOOR = 0.01
--- When tracking, the noise estimate carries the earlier frames' evidence with this weight per
-- frame (`previous.noise`), so that a frame of few tags is not judged by its own noise alone.
M.NOISE_MEMORY = 0.8
--- Default standard deviation of a resting block's centre height from its level above
-- `options.floor` (× block_size).
M.FLOOR_TOLERANCE = 0.02

local work = pipeline.new() -- the single-tag pipeline's workspace

local function unpack_normal(N)
  return N[1], N[2], N[3], N[4], N[5], N[6], N[7], N[8], N[9], N[10], N[11], N[12], N[13],
    N[14], N[15], N[16], N[17], N[18], N[19], N[20], N[21]
end

-- A block candidate from a tag's candidate pose at a place on the block (see the module's
-- header).
local function candidate(cand, place)
  local flat = { cand.r[1], cand.r[2], cand.r[3], cand.r[4], cand.r[5], cand.r[6], cand.r[7],
    cand.r[8], cand.r[9] }
  -- (a tag's own frame is a symmetric block's: R·Iᵀ is R)
  local r = place.r == IDENTITY and flat or mul_t(flat, place.r, {})
  local px, py, pz = place.x, place.y, place.z
  return {
    r = r,
    x = cand.tx - (r[1] * px + r[2] * py + r[3] * pz),
    y = cand.ty - (r[4] * px + r[5] * py + r[6] * pz),
    z = cand.tz - (r[7] * px + r[8] * py + r[9] * pz),
    sse = cand.sse,
    -- the tag's own candidate, for its uncertainty (`tagpose.uncertainty`'s record; no
    -- quaternions: pipeline.tag does not order the candidates, so they are stale)
    tag = { r = flat, tx = cand.tx, ty = cand.ty, tz = cand.tz, sse = cand.sse,
      normal = { unpack_normal(cand.normal) } },
  }
end

-- Solve one detection's corners (read into px) as a tag: its block candidates, or nil and why.
local function solve_tag(px, camera, place, half)
  local w = work
  for k = 1, 8 do w.px[k] = px[k] end
  local ok, why = pipeline.tag(w, camera, half)
  if not ok then return nil, why end
  local cands = { candidate(w.first, place) }
  if w.count == 2 then cands[2] = candidate(w.second, place) end
  return cands
end

local function skip(fr, i, reason, counts)
  fr.skipped[#fr.skipped + 1] = { index = i, reason = reason }
  if counts then fr.first_reason = fr.first_reason or ("detection " .. i .. ": " .. reason) end
end

-- Add detection i to the frame: solved, or skipped with its reason.
local function add(fr, i, det, camera)
  -- a detection that is not one (a detector's glitch) is reported, not raised: the frame's
  -- other tags still make blocks
  if type(det) ~= "table" then
    return skip(fr, i, "block: table {id =, corners =} expected, got " .. type(det), true)
  end
  local px = {}
  local finite, why = args.read_corners(det.corners, px, fr.settings.opencv)
  if not finite then
    return skip(fr, i, "block: " .. (why:match("^corner ") and why or "corners: " .. why), true)
  end
  local place, half = body_model.place(fr.body, det.id)
  if not place then return skip(fr, i, half) end
  if finite ~= true then
    return skip(fr, i, "tagpose: corner " .. finite .. " is not finite", true)
  end
  local cands
  cands, why = solve_tag(px, camera, place, half)
  if not cands then return skip(fr, i, why, true) end
  -- the relative depth error per pixel of corner noise: 1 / apparent size (px), from the
  -- quadrilateral's area (half the cross product of its diagonals)
  local area = 0.5 * abs((px[5] - px[1]) * (px[8] - px[4]) - (px[7] - px[3]) * (px[6] - px[2]))
  local relative = 1 / sqrt(max(area, 1))
  local best = cands[1].sse
  for a = 1, #cands do
    local c = cands[a]
    c.depth = sqrt(c.x * c.x + c.y * c.y + c.z * c.z) * relative
    if c.sse < best then best = c.sse end
  end
  fr.dets[#fr.dets + 1] = { index = i, px = px, cands = cands, place = place, best_sse = best,
    half = half }
end

--- A frame's record with its detections solved.
-- @tparam table settings the options read (`tagpose.block.options.read`)
-- @tparam {table,...} detections the caller's array of `{id =, corners =}`
-- @tparam table camera a checked camera
-- @tparam table body the block (`tagpose.block.body.new`)
-- @treturn table the frame record (see the module's header)
function M.new(settings, detections, camera, body)
  local block_size = body.block_size
  local fr = { settings = settings, body = body, C = lsq.pack(camera),
    half_block = 0.5 * block_size, block_size = block_size, dets = {}, skipped = {},
    up = settings.up, floor = settings.floor, default_up = { 0, -1, 0 } }
  for i = 1, #detections do add(fr, i, detections[i], camera) end
  -- the corner noise: the single fits' squared errors (2 degrees of freedom each), and those
  -- of earlier frames when tracking, fading by NOISE_MEMORY a frame
  local noise = 0
  for s = 1, #fr.dets do noise = noise + 0.5 * fr.dets[s].best_sse end
  local noise_sse, noise_dof = 2 * noise, 2 * #fr.dets
  if settings.noise_sse then
    noise_sse = noise_sse + M.NOISE_MEMORY * settings.noise_sse
    noise_dof = noise_dof + M.NOISE_MEMORY * settings.noise_dof
  end
  local sigma2 = max(noise_sse / max(noise_dof, 1), M.NOISE_FLOOR)
  fr.noise_sse, fr.noise_dof, fr.sigma2 = noise_sse, noise_dof, sigma2
  -- (the F-test's second degrees of freedom, 2n, rounded down to even)
  fr.n, fr.frame_sse = math.floor(0.5 * noise_dof), noise_sse
  fr.prior_w = fr.up and sqrt(sigma2) / settings.up_tolerance or 0
  fr.floor_w = sqrt(sigma2) / (settings.floor_tolerance or M.FLOOR_TOLERANCE * block_size)
  return fr
end

return M
