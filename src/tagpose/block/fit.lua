--- Blocks: the joint fit of a hypothesis and the test that keeps its tags together.
--
-- A hypothesis's pose is fitted to all its members' corners at once (`tagpose.rigid`, from
-- the seed's pose), each member's tag at its place on the block (`tagpose.block.body`; its
-- corners by `tagpose.rigid.model.corners`). While the joint fit's error exceeds the sum of its
-- members' own best single-tag fits by more than the frame's corner noise explains
-- (`consistent`: an F-test at level `ALPHA`, or `MERGE_FLOOR`), the member with the largest
-- excess is moved to the place that fits it best (a symmetric block's), or dropped. With
-- `up`, every fit holds the block's face axis nearest up along it; with a floor, a resting
-- block's centre at its level (`rest`). A block seen with one face keeps both candidates
-- (`single`). Lengths are in the tag size's unit, errors in pixels.
-- @module tagpose.block.fit

local rigid = require("tagpose.rigid")
local cube = require("tagpose.rigid.cube")
local model = require("tagpose.rigid.model")
local group = require("tagpose.block.group")
local identity = require("tagpose.block.identity")

local abs, huge = math.abs, math.huge
local corners = model.corners

local M = {}

require("tagpose.core.compat").interpret_module()

--- Tags make one block while the joint fit's squared error exceeds the sum of their own
-- single-tag fits' by at most `MERGE_FLOOR` px² per extra tag...
M.MERGE_FLOOR = 1
--- ... or by an amount the frame's corner noise explains: the F-test of the excess against the
-- single fits' errors passes at level `ALPHA`.
M.ALPHA = 3e-4
--- A block whose centre is further than this from every level (× block_size) is taken not to
-- rest on the floor or on a block: the floor prior is not applied to it (its cost is capped).
M.FLOOR_GATE = 0.3
--- Tracking: a block seen with one face keeps the candidate nearest its previous rotation
-- when that is within this angle (radians, modulo the symmetries)...
M.TRACK_ANGLE = math.rad(20)
--- ... and its squared error exceeds the better candidate's by less than `TRACK_K·σ²`.
M.TRACK_K = 25

-- scratch, reused by every fit and never handed out
local points, pixels = {}, {} -- the joint fit's body points and pixels
local body = { r = {} } -- the pose under way
local prior = rigid.prior() -- the priors handed to rigid.fit

local function copy9(src, dst)
  dst[1], dst[2], dst[3], dst[4], dst[5], dst[6], dst[7], dst[8], dst[9] = src[1], src[2],
    src[3], src[4], src[5], src[6], src[7], src[8], src[9]
  return dst
end

-- Fill `pixels` and `points` for the members of a hypothesis.
local function load_members(fr, h)
  local dets = fr.dets
  for m = 1, #h.members do
    local d = dets[h.members[m]]
    local px, o, half = d.px, 8 * m - 8, d.half
    pixels[o + 1], pixels[o + 2], pixels[o + 3], pixels[o + 4] = px[1], px[2], px[3], px[4]
    pixels[o + 5], pixels[o + 6], pixels[o + 7], pixels[o + 8] = px[5], px[6], px[7], px[8]
    local p = h.places[m]
    corners(p.r, p.x, p.y, p.z, half, points, 12 * m - 11)
  end
end

-- The priors for the block pose in `body`: the signed block axis closest to up held along it
-- (with an up), and, when `plane` is set and a floor is known, the centre's height held at the
-- nearest resting level. Returns the prior (or nil) and the capped cost of a level beyond the
-- gate.
local function set_prior(fr, plane)
  local up = fr.up
  if not up then return nil, 0 end
  local r = body.r
  local k, d = cube.nearest_axis(r, up[1], up[2], up[3])
  local sign = d < 0 and -1 or 1
  prior.axis_x, prior.axis_y, prior.axis_z = k == 1 and sign or 0, k == 2 and sign or 0,
    k == 3 and sign or 0
  prior.up_x, prior.up_y, prior.up_z, prior.axis_weight = up[1], up[2], up[3], fr.prior_w
  prior.normal_x, prior.normal_y, prior.normal_z = up[1], up[2], up[3]
  prior.level, prior.plane_weight = 0, 0
  local penalty = 0
  if plane and fr.floor then
    -- resting levels: up·c = -floor + B/2 + k·B
    local B = fr.block_size
    local h = up[1] * body.tx + up[2] * body.ty + up[3] * body.tz
    local base = -fr.floor + 0.5 * B
    local level = base + B * math.floor((h - base) / B + 0.5)
    local gate = M.FLOOR_GATE * B
    if abs(h - level) <= gate then
      prior.level, prior.plane_weight = level, fr.floor_w
    else
      penalty = ((fr.floor_w * gate) * (fr.floor_w * gate))
    end
  end
  return prior, penalty
end

-- Is the joint fit of k tags consistent with their single fits? Its excess `total` (px²)
-- over their single-tag errors is tested against the frame's noise: under the hypothesis
-- (one block) `(total / 6(k-1)) / (S / 2n)` is F-distributed with 6(k-1) and 2n degrees of
-- freedom, S the sum of the n single-tag errors of the frame. With both degrees even, its tail
-- is a binomial sum: P(F ≥ f) = P(Binomial(N, x) < a), a = 3(k-1), N = a + n - 1,
-- x = total / (total + S).
local function consistent(total, k, fr)
  if total <= M.MERGE_FLOOR * (k - 1) then return true end
  local a, n, S = 3 * (k - 1), fr.n, fr.frame_sse
  local N = a + n - 1
  local x = total / (total + S)
  if not (x < 1) then return false end
  -- Σ_{j<a} C(N, j) x^j (1-x)^(N-j), the terms built one from the last
  local term = (1 - x) ^ N
  local p = term
  for j = 1, a - 1 do
    term = term * (N - j + 1) / j * x / (1 - x)
    p = p + term
  end
  return p >= M.ALPHA
end

-- The sum of the members' squared pixel errors at the pose in `body`.
local function members_sse(fr, n)
  local sum = 0
  for m = 1, n do
    sum = sum + rigid.cost(fr.C, points, pixels, 4 * m - 3, 4 * m, body.r, body.tx, body.ty,
      body.tz)
  end
  return sum
end

-- A resting block: the fit of the n members loaded in `points` and `pixels`, from the pose in
-- `body` (of cost `cost`, pixel error `sum`), held at the level above the floor nearest it.
-- Leaves the pose in `body`; returns the cost with the capped penalty of a level beyond the
-- gate, and the pixel error; the cost is math.huge when the fit fails.
local function rest(fr, n, cost, sum)
  local level, penalty = set_prior(fr, true)
  if level.plane_weight > 0 then
    rigid.fit(fr.C, points, pixels, 4 * n, body, fr.settings.max_iterations, level)
    if not (body.cost < huge) then return huge, sum end
    cost, sum = body.cost, members_sse(fr, n)
  end
  return cost + penalty, sum
end

-- Move the worst member m of a hypothesis on a symmetric block to the place (face and turn)
-- that fits it best, when that halves its error; true when it moved.
local function reassign(fr, h, m, worst_sse)
  local best_k, best_sse = nil, worst_sse
  local places, half = fr.body.places, fr.dets[h.members[m]].half
  for k = 1, 24 do
    local p = places[k]
    corners(p.r, p.x, p.y, p.z, half, points, 12 * m - 11)
    local s = rigid.cost(fr.C, points, pixels, 4 * m - 3, 4 * m, body.r, body.tx, body.ty,
      body.tz)
    if s < best_sse then best_k, best_sse = k, s end
  end
  if best_k and places[best_k] ~= h.places[m] and best_sse < 0.5 * worst_sse then
    h.places[m] = places[best_k]
    return true
  end
  return false
end

--- Jointly fit a hypothesis (members, places, start pose); while the fit is not consistent
-- with its members' single fits, move the worst member to the place that fits it best (on a
-- symmetric block), or drop it. Fills `h.r`, `h.x`, `h.y`, `h.z`, `h.sse` (pixels only) and
-- `h.cost`.
-- @tparam table fr the frame record
-- @tparam table h a hypothesis (`tagpose.block.group`)
-- @treturn table h
function M.hypothesis(fr, h)
  local start, dets = h.start, fr.dets
  copy9(start.r, body.r)
  body.tx, body.ty, body.tz = start.x, start.y, start.z
  local last_reassigned = nil
  for _ = 1, 8 do
    local n = #h.members
    load_members(fr, h)
    rigid.fit(fr.C, points, pixels, 4 * n, body, fr.settings.max_iterations, set_prior(fr, false))
    local cost = body.cost
    if not (cost < huge) then
      h.cost = huge
      return h
    end
    -- each member's excess over its own best fit
    local total, sum, worst, worst_m, worst_sse = 0, 0, -huge, nil, 0
    for m = 1, n do
      local sse = rigid.cost(fr.C, points, pixels, 4 * m - 3, 4 * m, body.r, body.tx, body.ty,
        body.tz)
      local excess = sse - dets[h.members[m]].best_sse
      total, sum = total + excess, sum + sse
      if excess > worst then worst, worst_m, worst_sse = excess, m, sse end
    end
    if n == 1 or consistent(total, n, fr) then
      if fr.floor then
        cost, sum = rest(fr, n, cost, sum)
        if not (cost < huge) then
          h.cost = huge
          return h
        end
      end
      h.r = copy9(body.r, h.r or {})
      h.x, h.y, h.z = body.tx, body.ty, body.tz
      h.sse, h.cost, h.fitted = sum, cost, true
      return h
    end
    -- another face may explain the worst member (its gating candidate was the flipped one)
    local moved = false
    if fr.body.symmetric and worst_m ~= last_reassigned then
      moved = reassign(fr, h, worst_m, worst_sse)
      if moved then last_reassigned = worst_m end
    end
    if not moved then
      table.remove(h.members, worst_m)
      table.remove(h.places, worst_m)
      table.remove(h.cands, worst_m)
      last_reassigned = nil
    end
  end
  h.cost = huge
  return h
end

--- Fit a block seen with two or more faces again on the floor the frame shows (`fr.floor`),
-- keeping the new pose when the fit succeeds.
-- @tparam table fr the frame record
-- @tparam table h a fitted hypothesis
function M.refit_on_floor(fr, h)
  load_members(fr, h)
  copy9(h.r, body.r)
  body.tx, body.ty, body.tz = h.x, h.y, h.z
  local cost, sse = rest(fr, #h.members, h.cost, h.sse)
  if cost < huge then
    copy9(body.r, h.r)
    h.x, h.y, h.z, h.cost, h.sse = body.tx, body.ty, body.tz, cost, sse
  end
end

--- The normal equations of a fitted hypothesis at its pose (pixels and the priors it was
-- fitted with), for its covariance.
-- @tparam table fr the frame record
-- @tparam table h a fitted hypothesis
-- @tparam {number,...} out filled (`tagpose.rigid.normal`)
-- @treturn number the cost at the pose (`math.huge` when a point is behind the camera)
function M.normal(fr, h, out)
  load_members(fr, h)
  copy9(h.r, body.r)
  body.tx, body.ty, body.tz = h.x, h.y, h.z
  local pr = set_prior(fr, fr.floor ~= nil)
  return rigid.normal(fr.C, points, pixels, 4 * #h.members, h.r, h.x, h.y, h.z, pr, out)
end

--- A block seen with one face: its candidates as hypotheses, the one chosen first — the
-- better-fitting, unless up (both fitted with the up prior: the lower total cost) or, without
-- up, the previous frame's decided orientation says otherwise.
-- @tparam table fr the frame record
-- @tparam int s the detection
-- @treturn table the chosen hypothesis (or nil when no candidate is in front of the camera)
-- @treturn table the other (or nil)
-- @treturn string what decided: `"up"`, `"track"` or `"error"`
function M.single(fr, s)
  local d, settings = fr.dets[s], fr.settings
  local hs = {}
  for a = 1, #d.cands do
    local c = d.cands[a]
    local h = group.new(s, d.place, a, c)
    if fr.up then
      M.hypothesis(fr, h)
    else
      h.r, h.x, h.y, h.z, h.sse, h.cost = c.r, c.x, c.y, c.z, c.sse, c.sse
    end
    if h.cost < huge then hs[#hs + 1] = h end
  end
  if #hs == 0 then return nil end
  if #hs == 1 then return hs[1], nil, fr.up and "up" or "error" end
  local first, second = hs[1], hs[2]
  local how = "error"
  if fr.up then how = "up" end
  if second.cost < first.cost then first, second = second, first end
  -- without up, a decided orientation of the previous frame continues (up, where given, is
  -- the stronger evidence)
  if fr.up then return first, second, how end
  local gate = identity.TRACK_GATE * fr.block_size
  local prev = identity.nearest_previous(settings.previous, first.x, first.y, first.z, gate)
    or identity.nearest_previous(settings.previous, second.x, second.y, second.z, gate)
  if prev and prev.decided then
    local a1 = identity.symmetric_angle(first.r, prev.r, fr.body.symmetric)
    local a2 = identity.symmetric_angle(second.r, prev.r, fr.body.symmetric)
    if a2 < a1 and a2 < M.TRACK_ANGLE and second.cost - first.cost < M.TRACK_K * fr.sigma2 then
      first, second = second, first
      how = "track"
    elseif a1 <= a2 and a1 < M.TRACK_ANGLE then
      how = "track"
    end
  end
  return first, second, how
end

return M
