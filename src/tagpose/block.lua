--- Blocks: the pose of cubes from the tags on their faces.
--
-- A block is a cube of side `block_size` carrying a tag (black square of side `tag_size`) on
-- its faces. Its frame has the origin at the cube's centre and the axes along the face normals
-- (`tagpose.cube` lists the faces and the tag frame on each). By default every face carries a
-- tag of any id, centred on the face, its z axis pointing into the block; the faces cannot be
-- told apart, so a block's rotation is defined up to the cube's 24 symmetries and a canonical
-- one is returned (below). With `options.faces` (tag id → face) the block frame is absolute.
--
-- The pipeline, per frame:
--
-- 1. every detection is solved alone (`tagpose.solve`, refined): one or two candidate poses
--    (the planar ambiguity), each implying a block centre `t + R·(0, 0, block_size/2)` and a
--    block rotation (the tag's own, or `R·R_fᵀ` for a known face `f`);
-- 2. grouping: from every candidate as a seed, the other detections with a candidate whose
--    centre agrees across the line of sight (`PERP_GATE`; along it single tags are poor,
--    `ALONG_GATE`) and whose rotation agrees modulo the cube's symmetries (`ROTATION_GATE`) are
--    assigned the face their candidate implies;
-- 3. joint fit: Levenberg-Marquardt over the block's six pose parameters with all `4k` corners
--    (`tagpose.rigid`), from the seed's pose. While the joint fit's error exceeds the sum of its
--    members' own best single-tag fits by more than the frame's corner noise explains (an
--    F-test at level `ALPHA`, or `MERGE_FLOOR`), the member with the largest excess is
--    reassigned to the face that fits it best, or dropped. The hypothesis with the most
--    members, then the lowest error, becomes a block; its tags leave the pool, and the rest are
--    grouped again. Faces that are not coplanar leave no planar ambiguity: a block seen with
--    two or more faces has one pose;
-- 4. a block seen with one face keeps both candidates: the one chosen is the better-fitting,
--    unless `options.up` (an upright or tipped block has a face axis along gravity) or, without
--    up, the previous frame's block (tracking) says otherwise; the other is `alternative`.
--    With `up`, every fit holds the block's nearest face axis along it (`up_tolerance`), and
--    with `options.floor` a resting block's centre at its height (`floor_tolerance`);
-- 5. canonical orientation (when faces are indistinguishable): block z is the face axis
--    closest to up (`options.up`, default the camera's -y, `(0, -1, 0)`), block x the
--    remaining face axis closest to the direction from the camera to the block's centre,
--    y = z × x. A block tracked from the previous frame instead takes the equivalent nearest
--    to its previous rotation, so its orientation does not jump between symmetric frames.
--
-- Lengths are in the unit of `tag_size`, angles in radians, errors in pixels.
-- @module tagpose.block

local compat = require("tagpose.compat")
local args = require("tagpose.args")
local camera_model = require("tagpose.camera")
local rotation = require("tagpose.rotation")
local rigid = require("tagpose.rigid")
local cube = require("tagpose.cube")

local is_finite, is_positive, describe = compat.is_finite, args.is_positive, args.describe
local sqrt, abs, max, huge, rad = math.sqrt, math.abs, math.max, math.huge, math.rad
local ROTATIONS, INVERSE, FACES = cube.ROTATIONS, cube.INVERSE, cube.FACES

local M = {}

--- Grouping gate across the line of sight: implied centres closer than this (× block_size).
M.PERP_GATE = 0.3
--- Grouping gate along the line of sight (× block_size), where a single tag's depth is poor...
M.ALONG_GATE = 1.2
--- ... or wider, `ALONG_K` standard deviations of the difference of the two tags' depths
-- (each estimated as distance · σ / apparent size, σ the frame's corner noise).
M.ALONG_K = 5
--- Grouping gate on rotation: candidates whose block frames differ by less than this, modulo
-- the cube's symmetries (radians).
M.ROTATION_GATE = rad(60)
--- Tags make one block while the joint fit's squared error exceeds the sum of their own
-- single-tag fits' by at most `MERGE_FLOOR` px² per extra tag...
M.MERGE_FLOOR = 1
--- ... or by an amount the frame's corner noise explains: the F-test of the excess against the
-- single fits' errors passes at level `ALPHA`.
M.ALPHA = 3e-4
--- Floor of the corner noise variance estimate (px²).
M.NOISE_FLOOR = 0.01
--- When tracking, the noise estimate carries the earlier frames' evidence with this weight per
-- frame (`previous.noise`), so that a frame of few tags is not judged by its own noise alone.
M.NOISE_MEMORY = 0.8
--- Default standard deviation (radians) of a block's tilt from `options.up`.
M.UP_TOLERANCE = rad(2)
--- Default standard deviation of a resting block's centre height from its level above
-- `options.floor` (× block_size).
M.FLOOR_TOLERANCE = 0.02
--- Default `floor_tolerance` with `floor = "auto"`, × block_size: about how well one block
-- seen with two faces shows the floor (its centre to ~0.7 mm, mostly along the line of sight,
-- for the lab's blocks and camera).
M.AUTO_FLOOR_TOLERANCE = 0.01
--- A block whose centre is further than this from every level (× block_size) is taken not to
-- rest on the floor or on a block: the floor prior is not applied to it (its cost is capped).
M.FLOOR_GATE = 0.3
--- Tracking gate: a block is the previous frame's block when their centres are closer than
-- this (× block_size).
M.TRACK_GATE = 0.75
--- Tracking: a block seen with one face keeps the candidate nearest its previous rotation
-- when that is within this angle (radians, modulo the symmetries)...
M.TRACK_ANGLE = rad(20)
--- ... and its squared error exceeds the better candidate's by less than `TRACK_K·σ²`.
M.TRACK_K = 25
--- A hypothesis whose start is within this angle (radians, modulo the symmetries) of the
-- result of a fitted one over the same tags is not fitted again.
M.TWIN_ANGLE = rad(10)
--- Two blocks whose centres are closer than this (× block_size) are one cube: the later found
-- (fewer faces, or a larger error) is dropped and its tags reported in `skipped`.
M.OVERLAP = 0.5
--- Bound on the linearisations of one joint fit.
M.MAX_ITERATIONS = 20

local IDENTITY = ROTATIONS[1]

-- scratch, reused by every call and never handed out
local points, pixels = {}, {} -- the joint fit's body points and pixels
local fit_r, best_r, cand_r = {}, {}, {} -- rotations under way
local prior = {} -- the up prior handed to rigid.fit
local work = {} -- 3×3 products

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

-- (3×3 algebra is unrolled, in tagpose.rotation: LuaJIT makes a trace of every hot loop, and a
-- frame's many tiny loops would fill its trace cache)
local mul, mul_t, t_mul = rotation.multiply, rotation.multiply_transpose,
  rotation.transpose_multiply

local function copy9(src, dst)
  dst[1], dst[2], dst[3], dst[4], dst[5], dst[6], dst[7], dst[8], dst[9] = src[1], src[2],
    src[3], src[4], src[5], src[6], src[7], src[8], src[9]
  return dst
end

-- ------------------------------------------------------------------------------------------
-- Arguments

-- A direction {x, y, z} or {1, 2, 3}, made unit; or nil and the misuse.
local function read_direction(v, name)
  if type(v) ~= "table" then
    return nil, name .. ": table {x =, y =, z =} expected, got " .. type(v)
  end
  local x, y, z = v.x, v.y, v.z
  if x == nil then x, y, z = v[1], v[2], v[3] end
  if not (is_finite(x) and is_finite(y) and is_finite(z)) then
    return nil, name .. ": three finite numbers expected"
  end
  local n = sqrt(x * x + y * y + z * z)
  if not (n > 0) then return nil, name .. ": non-zero vector expected" end
  return { x / n, y / n, z / n }
end

-- A flat rotation from a nested one when it is one of the cube's rotations; or nil.
local function cube_rotation(m)
  if type(m) ~= "table" then return nil end
  local flat = {}
  for i = 1, 3 do
    local row = m[i]
    if type(row) ~= "table" then return nil end
    for j = 1, 3 do
      if not is_finite(row[j]) then return nil end
      flat[(i - 1) * 3 + j] = row[j]
    end
  end
  local k, angle = cube.nearest(flat)
  if angle > 1e-6 then return nil end
  return ROTATIONS[k]
end

-- options.faces: id → face name or nested cube rotation; as id → flat R_f. Or nil, misuse.
local function read_faces(faces)
  local out = {}
  for id, f in pairs(faces) do
    if type(f) == "string" then
      if not FACES[f] then
        return nil, "options.faces[" .. tostring(id) .. "]: face '+x', '-x', '+y', '-y', '+z' "
          .. "or '-z' expected, got string " .. f
      end
      out[id] = FACES[f].rotation
    else
      local r = cube_rotation(f)
      if not r then
        return nil, "options.faces[" .. tostring(id) .. "]: face name or 3x3 rotation of the "
          .. "cube (the tag frame in the block frame) expected"
      end
      out[id] = r
    end
  end
  return out
end

-- The previous frame's blocks: an array of {position, rotation or quaternion, id, ...}.
local function read_previous(previous)
  if type(previous) ~= "table" then
    return nil, "options.previous: array of blocks expected, got " .. type(previous)
  end
  local out = {}
  for i = 1, #previous do
    local b = previous[i]
    local p = type(b) == "table" and b.position
    if type(p) ~= "table" or not (is_finite(p.x) and is_finite(p.y) and is_finite(p.z)) then
      return nil, "options.previous[" .. i .. "]: block with a finite position expected"
    end
    local r
    if type(b.rotation) == "table" and type(b.rotation[1]) == "table"
      and type(b.rotation[2]) == "table" and type(b.rotation[3]) == "table" then
      r = rotation.from_nested(b.rotation)
      for k = 1, 9 do
        if not is_finite(r[k]) then r = nil break end
      end
    end
    if not r and type(b.quaternion) == "table" then
      local q = b.quaternion
      if is_finite(q.w) and is_finite(q.x) and is_finite(q.y) and is_finite(q.z)
        and q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z > 0 then
        r = rotation.from_quaternion(q.w, q.x, q.y, q.z)
      end
    end
    if not r then
      return nil, "options.previous[" .. i .. "]: block with a finite rotation expected"
    end
    out[i] = { x = p.x, y = p.y, z = p.z, r = r, id = b.id,
      decided = b.orientation ~= nil and b.orientation ~= "error" }
  end
  return out, previous.next_id
end

-- the scalar options: name, check, what the check expects
local SCALAR_OPTIONS = {
  "up_tolerance", is_positive, "positive number",
  "floor", is_finite, "finite number",
  "floor_tolerance", is_positive, "positive number",
  "max_iterations", args.is_count, "positive integer",
}

local function read_options(options)
  local o = { faces = nil, up = nil, previous = nil, up_tolerance = M.UP_TOLERANCE,
    floor = nil, floor_tolerance = nil, max_iterations = M.MAX_ITERATIONS }
  if options == nil then return o end
  if type(options) ~= "table" then return nil, "options table expected, got " .. type(options) end
  local problem
  if options.up == "auto" then
    o.auto_up = true
  elseif options.up ~= nil then
    o.up, problem = read_direction(options.up, "options.up")
    if not o.up then return nil, problem .. " (or 'auto')" end
  end
  if options.faces ~= nil then
    if type(options.faces) ~= "table" then
      return nil, "options.faces: table (tag id -> face) expected, got " .. type(options.faces)
    end
    o.faces, problem = read_faces(options.faces)
    if not o.faces then return nil, problem end
  end
  if options.previous ~= nil then
    o.previous, problem = read_previous(options.previous)
    if not o.previous then return nil, problem end
    o.next_id = problem
    local noise = options.previous.noise
    if noise ~= nil then
      if type(noise) ~= "table" or not (is_finite(noise.sse) and noise.sse >= 0
        and is_finite(noise.dof) and noise.dof >= 0) then
        return nil, "options.previous.noise: {sse =, dof =} (finite, >= 0) expected"
      end
      o.noise_sse, o.noise_dof = noise.sse, noise.dof
    end
  end
  for i = 1, #SCALAR_OPTIONS, 3 do
    local name, ok, what = SCALAR_OPTIONS[i], SCALAR_OPTIONS[i + 1], SCALAR_OPTIONS[i + 2]
    local v = options[name]
    if name == "floor" and v == "auto" then
      o.auto_floor, v = true, nil
    elseif name == "floor" and v ~= nil then
      what = what .. " (or 'auto')"
    end
    if v ~= nil then
      if not ok(v) then
        return nil, "options." .. name .. ": " .. what .. " expected, got " .. describe(v)
      end
      o[name] = v
    end
  end
  if o.floor and not o.up then return nil, "options.floor: needs options.up (a vector)" end
  if o.auto_floor and not (o.up or o.auto_up) then
    return nil, "options.floor: 'auto' needs options.up (a vector or 'auto')"
  end
  return o
end

-- ------------------------------------------------------------------------------------------
-- Candidates

-- A candidate of a detection from a tag pose: its block rotation `r` (flat), its centre and the
-- tag's squared error.
local function candidate(pose, face_r, half_block)
  local flat = rotation.from_nested(pose.rotation)
  local p = pose.position
  local c = {
    r = face_r and mul_t(flat, face_r, {}) or flat,
    x = p.x + half_block * flat[3], y = p.y + half_block * flat[6], z = p.z + half_block * flat[9],
    sse = 4 * pose.error * pose.error,
  }
  return c
end

-- Does candidate b of another detection agree with the block of candidate a? Returns a distance
-- (smaller is better) and, when the faces are not known, the index of the face rotation G of b
-- in a's block frame (b's tag frame written in a's block frame); or nil.
local function agree(a, b, faces, block_size, sigma)
  local dx, dy, dz = b.x - a.x, b.y - a.y, b.z - a.z
  local d2 = dx * dx + dy * dy + dz * dz
  local pg, ag = M.PERP_GATE * block_size, M.ALONG_GATE * block_size
  -- along the line of sight, what the two tags' depths allow (distance · σ / apparent size)
  local sa, sb = a.depth * sigma, b.depth * sigma
  local spread = M.ALONG_K * sqrt(sa * sa + sb * sb)
  if spread > ag then ag = spread end
  if d2 > pg * pg + ag * ag then return nil end
  local mx, my, mz = a.x + b.x, a.y + b.y, a.z + b.z
  local along = (dx * mx + dy * my + dz * mz) / sqrt(mx * mx + my * my + mz * mz)
  local perp2 = d2 - along * along
  if perp2 > pg * pg or abs(along) > ag then return nil end
  local k, angle
  if faces then
    -- known faces: the block frames must agree themselves
    angle = rotation.angle(a.r, b.r)
  else
    k, angle = cube.nearest(t_mul(a.r, b.r, work))
  end
  if angle > M.ROTATION_GATE then return nil end
  return sqrt(perp2) / pg + angle / M.ROTATION_GATE, k
end

-- The four corners of a tag on the face G (tag → block rotation) into `points` from point
-- `first`: X = G·c + (block_size/2)·n, n = -G·e_z.
local function face_points(g, half, half_block, first)
  -- the face centre n·B/2 and the tag's half axes x·h, y·h
  local nx, ny, nz = -g[3] * half_block, -g[6] * half_block, -g[9] * half_block
  local xx, xy, xz, yx, yy, yz = g[1] * half, g[4] * half, g[7] * half, g[2] * half,
    g[5] * half, g[8] * half
  local o = 3 * first - 3
  -- c1 = (-h, +h), c2 = (+h, +h), c3 = (+h, -h), c4 = (-h, -h)
  points[o + 1], points[o + 2], points[o + 3] = nx - xx + yx, ny - xy + yy, nz - xz + yz
  points[o + 4], points[o + 5], points[o + 6] = nx + xx + yx, ny + xy + yy, nz + xz + yz
  points[o + 7], points[o + 8], points[o + 9] = nx + xx - yx, ny + xy - yy, nz + xz - yz
  points[o + 10], points[o + 11], points[o + 12] = nx - xx - yx, ny - xy - yy, nz - xz - yz
end

-- ------------------------------------------------------------------------------------------
-- The frame

-- Fill `pixels` and `points` for the members of a hypothesis.
local function load_members(h, dets, half, half_block)
  for m = 1, #h.members do
    local d = dets[h.members[m]]
    local px, o = d.px, 8 * m - 8
    pixels[o + 1], pixels[o + 2], pixels[o + 3], pixels[o + 4] = px[1], px[2], px[3], px[4]
    pixels[o + 5], pixels[o + 6], pixels[o + 7], pixels[o + 8] = px[5], px[6], px[7], px[8]
    face_points(h.g[m], half, half_block, 4 * (m - 1) + 1)
  end
end

-- The priors for a block pose: the signed block axis closest to up held along it (with
-- options.up), and, when `plane` is set and options.floor is given, the centre's height held at
-- the nearest resting level. Returns the prior (or nil) and the capped cost of a level beyond
-- the gate.
local function set_prior(r, x, y, z, ctx, plane)
  local up = ctx.up
  if not up then return nil, 0 end
  -- the block axis (column of r) most (anti-)parallel to up
  local ux, uy, uz = up[1], up[2], up[3]
  local d1 = r[1] * ux + r[4] * uy + r[7] * uz
  local d2 = r[2] * ux + r[5] * uy + r[8] * uz
  local d3 = r[3] * ux + r[6] * uy + r[9] * uz
  prior[1], prior[2], prior[3] = 0, 0, 0
  if abs(d1) >= abs(d2) and abs(d1) >= abs(d3) then
    prior[1] = d1 < 0 and -1 or 1
  elseif abs(d2) >= abs(d3) then
    prior[2] = d2 < 0 and -1 or 1
  else
    prior[3] = d3 < 0 and -1 or 1
  end
  prior[4], prior[5], prior[6], prior[7] = up[1], up[2], up[3], ctx.prior_w
  prior[8], prior[9], prior[10], prior[11], prior[12] = up[1], up[2], up[3], 0, 0
  local penalty = 0
  if plane and ctx.floor then
    -- resting levels: up·c = -floor + B/2 + k·B
    local B = ctx.block_size
    local h = up[1] * x + up[2] * y + up[3] * z
    local base = -ctx.floor + 0.5 * B
    local level = base + B * math.floor((h - base) / B + 0.5)
    local gate = M.FLOOR_GATE * B
    if abs(h - level) <= gate then
      prior[11], prior[12] = level, ctx.floor_w
    else
      penalty = (ctx.floor_w * gate) ^ 2
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
local function consistent(total, k, ctx)
  if total <= M.MERGE_FLOOR * (k - 1) then return true end
  local a, n, S = 3 * (k - 1), ctx.n, ctx.frame_sse
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

-- A resting block: the fit of the n members loaded in `points` and `pixels`, from the pose in
-- fit_r and tx, ty, tz (of cost `cost`, pixel error `sum`), held at the level above
-- options.floor nearest it. Returns the pose (in fit_r), the cost with the capped penalty of a
-- level beyond the gate, and the pixel error; the cost is math.huge when the fit fails.
local function rest(n, tx, ty, tz, cost, sum, camera, ctx)
  local level, penalty = set_prior(fit_r, tx, ty, tz, ctx, true)
  if level[12] > 0 then
    local c
    tx, ty, tz, c = rigid.fit(camera, points, pixels, 4 * n, fit_r, tx, ty, tz,
      ctx.max_iterations, level)
    if not (c < huge) then return tx, ty, tz, huge, sum end
    cost, sum = c, 0
    for m = 1, n do
      sum = sum + rigid.cost(camera, points, pixels, 4 * m - 3, 4 * m, fit_r, tx, ty, tz)
    end
  end
  return tx, ty, tz, cost + penalty, sum
end

-- Jointly fit a hypothesis (members, faces g, start pose); while the fit is not consistent
-- with its members' single fits, reassign the worst member to the face that fits it best, or
-- drop it. Fills h.r, h.x, h.y, h.z, h.sse (pixels only), h.cost.
local function fit_hypothesis(h, dets, camera, half, half_block, ctx)
  local start = h.start
  local tx, ty, tz = start.x, start.y, start.z
  copy9(start.r, fit_r)
  local last_reassigned = nil
  for _ = 1, 8 do
    local n = #h.members
    load_members(h, dets, half, half_block)
    local pr = set_prior(fit_r, tx, ty, tz, ctx, false)
    local cost
    tx, ty, tz, cost = rigid.fit(camera, points, pixels, 4 * n, fit_r, tx, ty, tz,
      ctx.max_iterations, pr)
    if not (cost < huge) then
      h.cost = huge
      return h
    end
    -- each member's excess over its own best fit
    local total, sum, worst, worst_m, worst_sse = 0, 0, -huge, nil, 0
    for m = 1, n do
      local sse = rigid.cost(camera, points, pixels, 4 * m - 3, 4 * m, fit_r, tx, ty, tz)
      local excess = sse - dets[h.members[m]].best_sse
      total, sum = total + excess, sum + sse
      if excess > worst then worst, worst_m, worst_sse = excess, m, sse end
    end
    if n == 1 or consistent(total, n, ctx) then
      if ctx.floor then
        tx, ty, tz, cost, sum = rest(n, tx, ty, tz, cost, sum, camera, ctx)
        if not (cost < huge) then
          h.cost = huge
          return h
        end
      end
      h.r = copy9(fit_r, h.r or {})
      h.x, h.y, h.z = tx, ty, tz
      h.sse, h.cost = sum, cost
      return h
    end
    -- another face may explain the worst member (its gating candidate was the flipped one)
    local reassigned = false
    if not ctx.faces and worst_m ~= last_reassigned then
      local m = worst_m
      local best_k, best_sse = nil, worst_sse
      for k = 1, 24 do
        face_points(ROTATIONS[k], half, half_block, 4 * m - 3)
        local s = rigid.cost(camera, points, pixels, 4 * m - 3, 4 * m, fit_r, tx, ty, tz)
        if s < best_sse then best_k, best_sse = k, s end
      end
      if best_k and ROTATIONS[best_k] ~= h.g[m] and best_sse < 0.5 * worst_sse then
        h.g[m] = ROTATIONS[best_k]
        reassigned, last_reassigned = true, m
      end
    end
    if not reassigned then
      table.remove(h.members, worst_m)
      table.remove(h.g, worst_m)
      table.remove(h.cands, worst_m)
      last_reassigned = nil
    end
  end
  h.cost = huge
  return h
end

-- For every candidate a of every detection s (key 2s + a), the other detections with a candidate
-- that agrees with it: links[key][j] = {G, score, b} for the best such candidate b. Computed
-- once a frame, each pair of candidates once.
local function link_all(dets, block_size, faces, sigma)
  local links = {}
  for s = 1, #dets do
    for a = 1, #dets[s].cands do links[2 * s + a] = {} end
  end
  for s = 1, #dets do
    local ds = dets[s]
    for j = s + 1, #dets do
      local dj = dets[j]
      for a = 1, #ds.cands do
        local ca, row_a = ds.cands[a], links[2 * s + a]
        for b = 1, #dj.cands do
          local score, k = agree(ca, dj.cands[b], faces, block_size, sigma)
          if score then
            -- j seen from s's candidate a, and s seen from j's candidate b
            local link = row_a[j]
            if not link or score < link[2] then
              row_a[j] = { faces and dj.face_r or ROTATIONS[k], score, b }
            end
            local row_b = links[2 * j + b]
            link = row_b[s]
            if not link or score < link[2] then
              row_b[s] = { faces and ds.face_r or ROTATIONS[INVERSE[k]], score, a }
            end
          end
        end
      end
    end
  end
  return links
end

-- The hypothesis seeded by candidate a of detection s among the free detections.
local function hypothesis(s, a, dets, free, links, faces)
  local h = { members = { s }, g = { faces and dets[s].face_r or IDENTITY }, cands = { a },
    score = { 0 }, start = dets[s].cands[a] }
  local row = links[2 * s + a]
  for j = 1, #dets do
    local link = row[j]
    if link and free[j] then
      local best_g, best_score, best_b = link[1], link[2], link[3]
      -- one tag per face: the closer claim keeps it
      local clash = nil
      for m = 1, #h.members do
        local gm = h.g[m]
        if gm[3] == best_g[3] and gm[6] == best_g[6] and gm[9] == best_g[9] then clash = m end
      end
      if not clash then
        local m = #h.members + 1
        h.members[m], h.g[m], h.cands[m], h.score[m] = j, best_g, best_b, best_score
      elseif clash > 1 and best_score < h.score[clash] then
        h.members[clash], h.g[clash], h.cands[clash], h.score[clash] = j, best_g, best_b,
          best_score
      end
    end
  end
  return h
end

-- Are the detections of a list all free?
local function all_free(list, free)
  for i = 1, #list do
    if not free[list[i]] then return false end
  end
  return true
end

-- An already fitted hypothesis over the same detections whose result is where this one's start
-- is (its fit would only repeat that one), or nil.
local function twin_of(h, fitted, faces)
  local n = #h.gated
  for i = 1, #fitted do
    local f = fitted[i]
    if #f.gated == n and f.cost < huge then
      local same = true
      for k = 1, n do
        local found = false
        for m = 1, n do
          if f.gated[m] == h.gated[k] then found = true end
        end
        if not found then same = false end
      end
      if same then
        local _, angle
        if faces then
          angle = rotation.angle(f.r, h.start.r)
        else
          _, angle = cube.nearest(t_mul(f.r, h.start.r, work))
        end
        if angle < M.TWIN_ANGLE then return f end
      end
    end
  end
  return nil
end

-- Is hypothesis a better than b: more faces, then the lower error.
local function better(a, b)
  if not b then return true end
  local na, nb = #a.members, #b.members
  if na ~= nb then return na > nb end
  return a.cost < b.cost
end

-- Angle between rotation r and the nearest symmetric equivalent of ref (or ref itself when the
-- faces are known).
local function symmetric_angle(r, ref, faces)
  if faces then return rotation.angle(r, ref) end
  local _, angle = cube.nearest(t_mul(r, ref, work))
  return angle
end

-- The previous block nearest a centre within the tracking gate, or nil.
local function nearest_previous(previous, x, y, z, gate)
  if not previous then return nil end
  local best, best_d = nil, gate * gate
  for i = 1, #previous do
    local p = previous[i]
    local d = (p.x - x) ^ 2 + (p.y - y) ^ 2 + (p.z - z) ^ 2
    if d < best_d then best, best_d = p, d end
  end
  return best
end

-- A one-face block: choose between the detection's candidates. Returns the hypothesis and the
-- other one (or nil), and what decided.
local function single(s, dets, camera, half, half_block, ctx)
  local d = dets[s]
  local hs = {}
  for a = 1, #d.cands do
    local c = d.cands[a]
    local h = { members = { s }, g = { ctx.faces and d.face_r or IDENTITY }, cands = { a },
      start = c }
    if ctx.up then
      fit_hypothesis(h, dets, camera, half, half_block, ctx)
    else
      h.r, h.x, h.y, h.z, h.sse, h.cost = c.r, c.x, c.y, c.z, c.sse, c.sse
    end
    if h.cost < huge then hs[#hs + 1] = h end
  end
  if #hs == 0 then return nil end
  if #hs == 1 then return hs[1], nil, ctx.up and "up" or "error" end
  local first, second = hs[1], hs[2]
  local how = "error"
  if ctx.up then
    -- both fitted with the up prior: the lower total cost
    how = "up"
    if second.cost < first.cost then first, second = second, first end
  elseif second.cost < first.cost then
    first, second = second, first
  end
  -- without up, a decided orientation of the previous frame continues (up, where given, is
  -- the stronger evidence)
  local prev = not ctx.up and (nearest_previous(ctx.previous, first.x, first.y, first.z,
    M.TRACK_GATE * ctx.block_size)
    or nearest_previous(ctx.previous, second.x, second.y, second.z, M.TRACK_GATE * ctx.block_size))
  if prev and prev.decided then
    local a1 = symmetric_angle(first.r, prev.r, ctx.faces)
    local a2 = symmetric_angle(second.r, prev.r, ctx.faces)
    if a2 < a1 and a2 < M.TRACK_ANGLE and second.cost - first.cost < M.TRACK_K * ctx.sigma2 then
      first, second = second, first
      how = "track"
    elseif a1 <= a2 and a1 < M.TRACK_ANGLE then
      how = "track"
    end
  end
  return first, second, how
end

-- ------------------------------------------------------------------------------------------
-- Results

local function pose_table(r, x, y, z, err)
  local w, qx, qy, qz = rotation.to_quaternion(r)
  return {
    position = { x = x, y = y, z = z },
    rotation = rotation.to_nested(r),
    quaternion = { w = w, x = qx, y = qy, z = qz },
    error = err,
  }
end

-- The returned rotation of a block: canonical, or continued from the previous frame.
local function output_rotation(r, x, y, z, ctx, prev, out)
  if ctx.faces then return copy9(r, out) end
  if prev then return cube.closest(r, prev.r, out) end
  local up = ctx.up or ctx.default_up
  return cube.canonical(r, up[1], up[2], up[3], x, y, z, out)
end

local function finite_block(r, x, y, z, err)
  local s = x + y + z + err + r[1] + r[2] + r[3] + r[4] + r[5] + r[6] + r[7] + r[8] + r[9]
  return s == s and s > -huge and s < huge
end

-- up = 'auto': the face axis nearest the camera's -y of each block found with two or more
-- faces (each block resting on a face has one along gravity), summed with weights by faces;
-- nil when there is none.
local function frame_up(found, guess)
  local ux, uy, uz, any = 0, 0, 0, false
  for i = 1, #found do
    local h = found[i].h
    local n = #h.members
    if n > 1 then
      local r = h.r
      local d1 = r[1] * guess[1] + r[4] * guess[2] + r[7] * guess[3]
      local d2 = r[2] * guess[1] + r[5] * guess[2] + r[8] * guess[3]
      local d3 = r[3] * guess[1] + r[6] * guess[2] + r[9] * guess[3]
      local k, d = 3, d3
      if abs(d1) >= abs(d2) and abs(d1) >= abs(d3) then
        k, d = 1, d1
      elseif abs(d2) >= abs(d3) then
        k, d = 2, d2
      end
      local w = d < 0 and -n or n
      ux, uy, uz, any = ux + w * r[k], uy + w * r[3 + k], uz + w * r[6 + k], true
    end
  end
  if not any then return nil end
  local norm = sqrt(ux * ux + uy * uy + uz * uz)
  if not (norm > 0) then return nil end
  return { ux / norm, uy / norm, uz / norm }
end

-- floor = 'auto': the camera's height above the floor from the blocks found with two or more
-- faces (but the `except`-th), each taken to rest at the level (0 on the floor, 1 on one block,
-- ...) nearest its height above the lowest of them, weighted by faces; nil when there is none.
local function frame_floor(found, up, B, except)
  local low = huge
  for i = 1, #found do
    local h = found[i].h
    if #h.members > 1 and i ~= except then
      local height = up[1] * h.x + up[2] * h.y + up[3] * h.z
      if height < low then low = height end
    end
  end
  if low == huge then return nil end
  local sum, weight = 0, 0
  for i = 1, #found do
    local h = found[i].h
    local n = #h.members
    if n > 1 and i ~= except then
      local height = up[1] * h.x + up[2] * h.y + up[3] * h.z
      local k = math.floor((height - low) / B + 0.5)
      if abs(height - low - k * B) <= M.FLOOR_GATE * B then
        sum, weight = sum + n * (0.5 * B + k * B - height), weight + n
      end
    end
  end
  return sum / weight
end

-- orders for table.sort (module-level: a closure made per call stops LuaJIT's compiler)
local function first_smaller(a, b) return a[1] < b[1] end
local function nearer(a, b)
  return a.h.x ^ 2 + a.h.y ^ 2 + a.h.z ^ 2 < b.h.x ^ 2 + b.h.y ^ 2 + b.h.z ^ 2
end
local function smaller_id(a, b) return a.id < b.id end

-- Match the blocks to the previous frame's (least total centre distance within the gate, by
-- exhaustive search for small counts, greedily beyond) and set their ids.
local function assign_ids(blocks, previous, next_id, gate)
  local n = #blocks
  local used = {}
  local pairs_list = {}
  for i = 1, n do
    local p = blocks[i].position
    for j = 1, #previous do
      local q = previous[j]
      local d = sqrt((p.x - q.x) ^ 2 + (p.y - q.y) ^ 2 + (p.z - q.z) ^ 2)
      if d < gate then pairs_list[#pairs_list + 1] = { d, i, j } end
    end
  end
  table.sort(pairs_list, first_smaller)
  local match = {}
  for _, pr in ipairs(pairs_list) do
    local i, j = pr[2], pr[3]
    if not match[i] and not used[j] then match[i], used[j] = j, true end
  end
  return match, next_id
end

--- Solve the poses of the blocks whose tags one frame shows.
-- @tparam {table,...} detections array of `{id = n, corners = {...}}`, `corners` as
--   `tagpose.solve` takes them (four points `{u, v}` or `{x =, y =}` in detection order, pixels)
-- @tparam table camera `{fx =, fy =, cx =, cy =}` in pixels, optionally `distortion` and
--   `model` (see `tagpose.camera`)
-- @tparam number tag_size side of the tags' black squares (> 0); lengths come out in its unit
-- @tparam number block_size side of the cube (> `tag_size`)
-- @tparam[opt] table options
--
--   - `up`: a vector `{x =, y =, z =}` (or `{x, y, z}`) in the camera frame pointing up
--     (against gravity), when known: a block resting on a face has a face axis along it, which
--     decides between the two poses of a block seen with one face and steadies every fit; it
--     also sets the canonical z. Default: none (and `(0, -1, 0)` for the canonical choice).
--     `"auto"`: when the frame has blocks seen with two or more faces, up is their face axis
--     nearest the camera's -y, used for the blocks seen with one face (this assumes that all
--     the blocks in view rest on a face, on the floor or on each other, and that the camera is
--     rolled and pitched by less than 45 degrees);
--   - `up_tolerance`: standard deviation of a block's tilt from `up`, radians (default 2°);
--   - `floor` (needs `up`): the height of the camera's centre above the floor the blocks rest
--     on, when known: a block resting on the floor or on other blocks has its centre at
--     `block_size/2 + k·block_size` above it, which fixes the depth a single tag measures
--     poorly. It helps only when known to about a millimetre: a height error moves a centre
--     along the line of sight by the error over the sine of the ray's angle below horizontal.
--     A block further than 0.3 block from every level is left free;
--     `"auto"` (with `up`, a vector or `"auto"`): when the frame has blocks seen with two or
--     more faces, the floor is where they rest (each at the level nearest its height above the
--     lowest), used for the blocks seen with one face and, for each of those blocks, the floor
--     the others show (this assumes that all the blocks in view rest on the floor or on each
--     other);
--   - `floor_tolerance`: standard deviation of a resting centre's height from its level, in
--     length units (default `block_size / 50`; `block_size / 100` with `floor = "auto"`);
--   - `previous`: the blocks returned for the previous frame: a block found again keeps its
--     `id` and the symmetric frame nearest its previous rotation, and a one-face block keeps
--     the candidate that continues a decided orientation;
--   - `faces`: a table tag id → face (`"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`, or the
--     nested 3×3 tag → block rotation, one of the cube's) when the faces can be told apart: the
--     block frame is then absolute and detections with other ids are skipped;
--   - `max_iterations`: bound on the linearisations of one joint fit (default 20).
-- @treturn {table,...} blocks, nearest first (sorted by `id` when tracking), each
--   `{id =, position = {x, y, z}, rotation = {{...}, {...}, {...}}, quaternion = {w, x, y, z},
--   raw_rotation = {{...}, ...}, error = px, tags = {i, ...}, faces = k, tag_faces = {"+x",
--   ...}, orientation = "faces"|"up"|"track"|"error", alternative = {position, rotation,
--   quaternion, error} or nil}`; the array's field `skipped` lists the detections not used,
--   `{index = i, reason = string}`, `next_id` the id a new block would take, and `noise`
--   the corner noise evidence `{sse =, dof =}` (px², degrees of freedom) carried to the next
--   frame, `up` (`{x =, y =, z =}`) and `floor` the up and floor used (given or found with
--   `"auto"`; nil when none)
-- @return nil, string when no detection gives a tag pose (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
--   (`detections` not a table, the camera, the sizes, the options; a malformed detection
--   inside the array is skipped instead, with its reason)
-- @usage
-- local blocks = tagpose.block.solve({{id = 0, corners = c1}, {id = 0, corners = c2}},
--   camera, 0.024, 0.055, {up = {x = 0, y = -0.9, z = -0.4}})
-- for _, b in ipairs(blocks) do print(b.id, b.position.x, b.position.y, b.position.z) end
function M.solve(detections, camera, tag_size, block_size, options)
  if type(detections) ~= "table" then
    arg_error(1, "array of detections expected, got " .. type(detections))
  end
  local problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  if not is_positive(tag_size) then
    arg_error(3, "positive number expected for tag_size, got " .. describe(tag_size))
  end
  if not is_positive(block_size) then
    arg_error(4, "positive number expected for block_size, got " .. describe(block_size))
  end
  if not (block_size > tag_size) then
    arg_error(4, "block_size must exceed tag_size, got " .. block_size .. " <= " .. tag_size)
  end
  local ctx
  ctx, problem = read_options(options)
  if not ctx then arg_error(5, problem) end
  local faces = ctx.faces

  local tagpose = require("tagpose")
  local half, half_block = 0.5 * tag_size, 0.5 * block_size
  local skipped, dets = {}, {}
  local noise, first_reason = 0, nil
  for i = 1, #detections do
    local det = detections[i]
    -- a detection that is not one (a detector's glitch) is reported, not raised: the frame's
    -- other tags still make blocks
    local malformed = nil
    if type(det) ~= "table" then
      malformed = "table {id =, corners =} expected, got " .. type(det)
    else
      local ok, why = args.read_corners(det.corners, work)
      if not ok then malformed = why:match("^corner ") and why or "corners: " .. why end
    end
    local face_r = not malformed and faces and faces[det.id]
    if malformed then
      skipped[#skipped + 1] = { index = i, reason = "block: " .. malformed }
      first_reason = first_reason or ("detection " .. i .. ": block: " .. malformed)
    elseif faces and not face_r then
      skipped[#skipped + 1] = { index = i,
        reason = "block: tag id " .. tostring(det.id) .. " is on no face of options.faces" }
    else
      local pose, why = tagpose.solve(det.corners, camera, tag_size)
      if not pose then
        skipped[#skipped + 1] = { index = i, reason = why }
        first_reason = first_reason or ("detection " .. i .. ": " .. why)
      else
        local d = { index = i, px = {}, cands = { candidate(pose, face_r, half_block) },
          face_r = face_r }
        local q = d.px
        args.read_corners(det.corners, q)
        if pose.alternative then
          d.cands[2] = candidate(pose.alternative, face_r, half_block)
        end
        -- the relative depth error per pixel of corner noise: 1 / apparent size (px), from the
        -- quadrilateral's area (half the cross product of its diagonals)
        local area = 0.5 * abs((q[5] - q[1]) * (q[8] - q[4]) - (q[7] - q[3]) * (q[6] - q[2]))
        local relative = 1 / sqrt(max(area, 1))
        for a = 1, #d.cands do
          local c = d.cands[a]
          c.depth = sqrt(c.x * c.x + c.y * c.y + c.z * c.z) * relative
        end
        d.best_sse = d.cands[1].sse
        if d.cands[2] and d.cands[2].sse < d.best_sse then d.best_sse = d.cands[2].sse end
        noise = noise + 0.5 * d.best_sse
        dets[#dets + 1] = d
      end
    end
  end
  if #dets == 0 and first_reason then
    return nil, "block: no detection gives a tag pose (" .. first_reason .. ")"
  end
  -- the corner noise: the single fits' squared errors (2 degrees of freedom each), and those
  -- of earlier frames when tracking, fading by NOISE_MEMORY a frame
  local noise_sse, noise_dof = 2 * noise, 2 * #dets
  if ctx.noise_sse then
    noise_sse = noise_sse + M.NOISE_MEMORY * ctx.noise_sse
    noise_dof = noise_dof + M.NOISE_MEMORY * ctx.noise_dof
  end
  local sigma2 = max(noise_sse / max(noise_dof, 1), M.NOISE_FLOOR)
  ctx.sigma2 = sigma2
  -- (the F-test's second degrees of freedom, 2n, rounded down to even)
  ctx.n, ctx.frame_sse = math.floor(0.5 * noise_dof), noise_sse
  ctx.prior_w = ctx.up and sqrt(sigma2) / ctx.up_tolerance or 0
  ctx.floor_w = sqrt(sigma2) / (ctx.floor_tolerance or M.FLOOR_TOLERANCE * block_size)
  ctx.block_size = block_size
  ctx.default_up = { 0, -1, 0 }

  -- grouping and joint fits, the best hypothesis first
  local free = {}
  for s = 1, #dets do free[s] = true end
  local found = {}
  local remaining = #dets
  -- hypotheses by seed (kept while all their tags are free) and those fitted this frame
  local cache, fitted = {}, {}
  local links = link_all(dets, block_size, faces, sqrt(sigma2))
  while remaining > 0 do
    local best = nil
    for s = 1, #dets do
      if free[s] then
        for a = 1, #dets[s].cands do
          local key = 2 * s + a
          local h = cache[key]
          if not (h and all_free(h.gated, free)) then
            h = hypothesis(s, a, dets, free, links, faces)
            local gated = {}
            for m = 1, #h.members do gated[m] = h.members[m] end
            h.gated = gated
            if #gated > 1 then
              local twin = twin_of(h, fitted, faces)
              if twin then
                h = twin
              else
                fit_hypothesis(h, dets, camera, half, half_block, ctx)
                fitted[#fitted + 1] = h
              end
            end
            cache[key] = h
          end
          if #h.members > 1 and h.cost < huge and better(h, best) then best = h end
        end
      end
    end
    local h, other, how
    if best then
      h, how = best, "faces"
    elseif ctx.auto_up or ctx.auto_floor then
      -- up = 'auto', floor = 'auto': the blocks found with two or more faces (all of them,
      -- now) show them
      if ctx.auto_up then
        ctx.up = frame_up(found, ctx.default_up)
        ctx.prior_w = ctx.up and sqrt(sigma2) / ctx.up_tolerance or 0
      end
      if ctx.auto_floor and ctx.up then
        ctx.floor_w = sqrt(sigma2)
          / (ctx.floor_tolerance or M.AUTO_FLOOR_TOLERANCE * block_size)
        -- each block with two or more faces rests on the floor the others show
        for i = 1, #found do
          local g = found[i].h
          ctx.floor = frame_floor(found, ctx.up, block_size, i)
          if ctx.floor then
            load_members(g, dets, half, half_block)
            copy9(g.r, fit_r)
            local x, y, z, cost, sse = rest(#g.members, g.x, g.y, g.z, g.cost, g.sse, camera, ctx)
            if cost < huge then
              copy9(fit_r, g.r)
              g.x, g.y, g.z, g.cost, g.sse = x, y, z, cost, sse
            end
          end
        end
        -- and those with one face on the floor all of them show
        ctx.floor = frame_floor(found, ctx.up, block_size)
      end
      ctx.auto_up, ctx.auto_floor = false, false
    else
      -- no two tags make a block: each free tag is one (the best-fitting first)
      local s = nil
      for k = 1, #dets do
        if free[k] and (not s or dets[k].best_sse < dets[s].best_sse) then s = k end
      end
      h, other, how = single(s, dets, camera, half, half_block, ctx)
      if not h then
        free[s] = false
        remaining = remaining - 1
        skipped[#skipped + 1] = { index = dets[s].index,
          reason = "block: no pose puts the tag in front of the camera" }
      end
    end
    if h then
      for m = 1, #h.members do
        free[h.members[m]] = false
        remaining = remaining - 1
      end
      found[#found + 1] = { h = h, other = other, how = how }
    end
  end

  -- results: finite, and no two cubes in one place (found in order of faces, then error: a
  -- later block within OVERLAP of an earlier one is a tag that did not fit it, such as the
  -- same tag detected twice)
  local blocks = {}
  local overlap2 = (M.OVERLAP * block_size) ^ 2
  for _, f in ipairs(found) do
    local h = f.h
    local n = #h.members
    local err = sqrt(h.sse / (4 * n))
    local reason = nil
    if not finite_block(h.r, h.x, h.y, h.z, err) then
      reason = "block: the fit is not finite"
    else
      for k = 1, #blocks do
        local o = blocks[k].h
        if (o.x - h.x) ^ 2 + (o.y - h.y) ^ 2 + (o.z - h.z) ^ 2 < overlap2 then
          local list = {}
          for m = 1, #o.members do list[m] = dets[o.members[m]].index end
          reason = "block: the tag does not fit the block of detection(s) "
            .. table.concat(list, ", ") .. " in its place"
        end
      end
    end
    if reason then
      for m = 1, n do
        skipped[#skipped + 1] = { index = dets[h.members[m]].index, reason = reason }
      end
    else
      blocks[#blocks + 1] = f
      f.err = err
    end
  end
  local match, next_id = {}, 1
  if ctx.previous then
    next_id = ctx.next_id
    if not is_finite(next_id) then
      next_id = 0
      for _, p in ipairs(ctx.previous) do
        if is_finite(p.id) and p.id > next_id then next_id = p.id end
      end
      next_id = next_id + 1
    end
    local pseudo = {}
    for i, f in ipairs(blocks) do
      pseudo[i] = { position = { x = f.h.x, y = f.h.y, z = f.h.z } }
    end
    match = assign_ids(pseudo, ctx.previous, next_id, M.TRACK_GATE * block_size)
  else
    table.sort(blocks, nearer)
  end
  local out = {}
  for i, f in ipairs(blocks) do
    local h = f.h
    local prev = match[i] and ctx.previous[match[i]]
    local r = output_rotation(h.r, h.x, h.y, h.z, ctx, prev, best_r)
    local b = pose_table(r, h.x, h.y, h.z, f.err)
    b.raw_rotation = rotation.to_nested(h.r)
    local tags, tag_faces = {}, {}
    -- each tag's face in the returned frame: G' = rᵀ·raw·G
    local rel = t_mul(r, h.r, {})
    for m = 1, #h.members do
      tags[m] = dets[h.members[m]].index
      tag_faces[m] = cube.face_of(mul(rel, h.g[m], cand_r))
    end
    b.tags, b.tag_faces, b.faces, b.orientation = tags, tag_faces, #h.members, f.how
    if f.other then
      local o = f.other
      local orr = output_rotation(o.r, o.x, o.y, o.z, ctx, prev, best_r)
      local oerr = sqrt(o.sse / 4)
      if finite_block(orr, o.x, o.y, o.z, oerr) then
        b.alternative = pose_table(orr, o.x, o.y, o.z, oerr)
      end
    end
    if prev and is_finite(prev.id) then
      b.id = prev.id
    else
      b.id = next_id
      next_id = next_id + 1
    end
    out[i] = b
  end
  if ctx.previous then
    table.sort(out, smaller_id)
  end
  out.skipped = skipped
  out.next_id = next_id
  out.noise = { sse = noise_sse, dof = noise_dof }
  -- the up and floor used (given, or found with "auto"), nil for none
  local up = ctx.up
  out.up = up and { x = up[1], y = up[2], z = up[3] } or nil
  out.floor = ctx.floor
  return out
end

-- solve drives the pipeline through loops over a few tags and blocks whose bodies branch a lot
-- and call much: on LuaJIT their traces outgrow the machine-code area (512 KB by default), which
-- is then flushed and refilled every hundred frames or so. Left to the interpreter (the kernels
-- it calls still compile their own loops) it runs about three times faster there. Whether the VM
-- can do that is compat's to know (`compat.interpret`; a no-op on PUC Lua).
compat.interpret(M.solve)

return M
