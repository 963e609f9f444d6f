--- The public result of a solve: the pose table a caller gets, and what it costs.
--
-- A solve returns a pose table (`position`, `rotation`, `quaternion`, `error`, `iterations`,
-- `refine_iterations`) built from the pipeline's candidates (`tagpose.core.pipeline`) at the
-- end of the solve (`tagpose.result.finish`, the one caller of `new`). What a
-- robot often does not read is made only when it is first read, by the pose's metatable:
--
-- * `alternative`, the other minimum's pose table (nil where there is one minimum);
-- * `confidence` (the branch probability) and `covariance` (6×6), from `tagpose.uncertainty`
--   (loaded then), with the normal equations of each candidate's last linearisation. A tracked
--   solve sets `confidence` at once (the filter's posterior); a pose that is the only minimum
--   has confidence 1 at once;
-- * `track`, the tracking state this pose starts when it is used as `options.prior`, from
--   `tagpose.track` (loaded then).
--
-- So `pairs(pose)` lists these fields only once read. The metatable holds what they need,
-- copied at the solve (an array, the smallest allocation that holds it): the camera table (read
-- then, as it is then), half the tag side, σ² (or false: the default pooled with the
-- residuals), the tag's side in pixels, the time, the other candidate's pose and error, both
-- candidates' normal equations and residuals, and a checksum of the returned pose: a pose
-- changed in place before these fields are read raises an error instead of giving the
-- uncertainty of a pose that was never solved. With `options.into` the tables, the metatable
-- and the alternative and covariance tables made before are reused: a caller who passes the
-- same table every frame allocates nothing.
-- @module tagpose.result.pose

local rotation = require("tagpose.core.rotation")

local to_nested = rotation.to_nested

local M = {}

-- The slots of a result's metatable. Filled at the solve: CAMERA .. LIN_B (ERR_B false when
-- the pose is the only minimum); READ, false until a field is first read: then a record of
-- what was made (its slots X_...), so that the metatable itself never grows.
local CAMERA, HALF, SIGMA2, SIDE, TIME, FIRST, CHECK = 1, 2, 3, 4, 5, 6, 7
local H_A, H_B = 7, 28 -- H of each candidate: slots 8..28 and 29..49
local SSE_A, SSE_B = 50, 51
local R_B, T_B, Q_B = 51, 60, 63 -- the other candidate: r 52..60, t 61..63, q 64..67
local ERR_B, LIN_B = 68, 69
local READ = 70
local X_ALT, X_ANALYSED = 1, 2
local X_COV_A, X_COV_B, X_TRACK = 11, 12, 13 -- the tables made before, to fill again
-- (the other slots are `tagpose.uncertainty.read`'s, which makes the confidence and covariance
-- straight from this metatable's numbers: the chord factors at 3 and 4, the chord at 5..10,
-- the covariance's factor κ for an estimated σ at 14, the factors of the pose's H at 15..35,
-- σ² at 36)

-- A result's analysis is kept in a record of its own when it has one (an alternative or a track
-- was read, or the result is an `options.into` table solved again: its covariance tables are
-- filled again), else in `shared`, which holds the analysis of one result, `cached`'s, at a time:
-- the common read of a fresh solve's confidence and covariance allocates nothing but the
-- covariance. A result whose analysis `shared` no longer holds is analysed again, into it. The
-- numbers are the same whichever record holds them and however often they are made: the
-- analysis reads only the metatable's numbers, and writes none of them.
local function record()
  return { false, false, 0, 0, 0, 0, 0, 0, 0, 0, false, false, false, 1, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0 }
end
local shared = record()
-- cached[1]: the metatable whose analysis `shared` holds, or false (`new` clears it, reusing it).
-- (In a table: an upvalue set to each new result would have the collector mark every one of them,
-- and what they hold, while it marks.)
local cached = { false }

-- The record of what was made on read, of its own (made at the first need; one table, at its
-- size).
local function made(mt)
  local x = mt[READ]
  if not x then
    x = record()
    mt[READ] = x
  end
  return x
end

local lazy = {} -- the modules the fields made on read need, loaded with them
local cand_a, cand_b -- the records the track takes, rebuilt from a metatable

local CHANGED = "tagpose: a pose was changed in place after its solve: read its alternative, "
  .. "confidence, covariance and track before changing it (or copy it)"

-- The checksum of a pose table's position and quaternion.
local function checksum(p)
  local t, q = p.position, p.quaternion
  return t.x + t.y + t.z + q.w + q.x + q.y + q.z
end

-- The candidate record of the returned pose (from its table, checked) and of the other (from
-- the metatable), with their H and residuals.
local function candidates(mt)
  if not cand_a then
    local pipeline = require("tagpose.core.pipeline")
    cand_a, cand_b = pipeline.candidate(), pipeline.candidate()
  end
  local p = mt[FIRST]
  local sum = checksum(p)
  if sum ~= mt[CHECK] then
    error(CHANGED, 3)
  end
  local a, b = cand_a, cand_b
  local r, R, q, t = a.r, p.rotation, p.quaternion, p.position
  r[1], r[2], r[3] = R[1][1], R[1][2], R[1][3]
  r[4], r[5], r[6] = R[2][1], R[2][2], R[2][3]
  r[7], r[8], r[9] = R[3][1], R[3][2], R[3][3]
  a.tx, a.ty, a.tz, a.qw, a.qx, a.qy, a.qz = t.x, t.y, t.z, q.w, q.x, q.y, q.z
  a.sse, b.sse = mt[SSE_A], mt[SSE_B]
  local na, nb = a.normal, b.normal
  for i = 1, 21 do na[i], nb[i] = mt[H_A + i], mt[H_B + i] end
  r = b.r
  for i = 1, 9 do r[i] = mt[R_B + i] end
  b.tx, b.ty, b.tz = mt[T_B + 1], mt[T_B + 2], mt[T_B + 3]
  b.qw, b.qx, b.qy, b.qz = mt[Q_B + 1], mt[Q_B + 2], mt[Q_B + 3], mt[Q_B + 4]
  return a, mt[ERR_B] and b or nil
end

-- The branch analysis of a result, once (again only when `shared` was taken by another since):
-- σ², the chord factors, the chord and the pose's factors into its record, both confidences
-- unless a tracker set them. Returns the record.
local function analyse(mt)
  local x = mt[READ]
  if x then
    if x[X_ANALYSED] then return x end
  elseif cached[1] == mt then
    return shared
  else
    x, cached[1] = shared, false
  end
  local read = lazy.read
  if not read then
    read = require("tagpose.uncertainty.read")
    lazy.read = read
  end
  local p = read.analyse(mt, x)
  x[X_ANALYSED] = true
  if x == shared then cached[1] = mt end
  local first = mt[FIRST]
  if rawget(first, "confidence") == nil then
    rawset(first, "confidence", p)
    local alt = x[X_ALT]
    if alt and mt[ERR_B] then rawset(alt, "confidence", 1 - p) end
  end
  return x
end

-- The covariance of the returned pose, or of its alternative (x its analysed record), into the
-- table made before if any.
local function covariance(mt, x, is_alt)
  if x == shared then return lazy.read.covariance(mt, x, is_alt, nil) end
  local slot = is_alt and X_COV_B or X_COV_A
  local cov = lazy.read.covariance(mt, x, is_alt, x[slot] or nil)
  x[slot] = cov
  return cov
end

local spare = setmetatable({}, { __mode = "k" }) -- a result -> an alternative table to reuse

-- The alternative's table, from the metatable (made once, into a table made before if any).
local function alternative(mt)
  local first = mt[FIRST]
  local x = made(mt)
  local alt = x[X_ALT] or spare[first]
  spare[first] = nil
  local conf = rawget(first, "confidence")
  if not alt then
    -- (a new one in one constructor per table: filled key by key, its tables would grow
    -- through a dozen resizes)
    local r = mt
    alt = {
      position = { x = r[T_B + 1], y = r[T_B + 2], z = r[T_B + 3] },
      rotation = { { r[R_B + 1], r[R_B + 2], r[R_B + 3] }, { r[R_B + 4], r[R_B + 5], r[R_B + 6] },
        { r[R_B + 7], r[R_B + 8], r[R_B + 9] } },
      quaternion = { w = r[Q_B + 1], x = r[Q_B + 2], y = r[Q_B + 3], z = r[Q_B + 4] },
      error = r[ERR_B],
      iterations = rawget(first, "iterations"),
      refine_iterations = r[LIN_B] or nil,
      confidence = conf ~= nil and 1 - conf or nil,
    }
    x[X_ALT] = alt
    return setmetatable(alt, mt)
  end
  local p, q, rt = alt.position, alt.quaternion, alt.rotation
  if type(p) ~= "table" then p = {} end
  if type(q) ~= "table" then q = {} end
  if type(rt) ~= "table" then rt = { {}, {}, {} } end
  p.x, p.y, p.z = mt[T_B + 1], mt[T_B + 2], mt[T_B + 3]
  q.w, q.x, q.y, q.z = mt[Q_B + 1], mt[Q_B + 2], mt[Q_B + 3], mt[Q_B + 4]
  local r = mt
  local r1, r2, r3 = rt[1], rt[2], rt[3]
  r1[1], r1[2], r1[3] = r[R_B + 1], r[R_B + 2], r[R_B + 3]
  r2[1], r2[2], r2[3] = r[R_B + 4], r[R_B + 5], r[R_B + 6]
  r3[1], r3[2], r3[3] = r[R_B + 7], r[R_B + 8], r[R_B + 9]
  alt.position, alt.rotation, alt.quaternion = p, rt, q
  alt.error, alt.iterations, alt.refine_iterations = mt[ERR_B], rawget(first, "iterations"),
    mt[LIN_B] or nil
  alt.confidence, alt.covariance = conf ~= nil and 1 - conf or nil, nil
  x[X_ALT] = alt
  return setmetatable(alt, mt)
end

-- __index of a result and of its alternative: the fields made when first read.
local function made_on_read(t, key)
  local mt = getmetatable(t)
  local is_alt = t ~= mt[FIRST]
  if key == "alternative" then
    if is_alt or not mt[ERR_B] then return nil end
    candidates(mt) -- (checks the pose)
    local alt = alternative(mt)
    rawset(t, "alternative", alt)
    return alt
  elseif key == "confidence" then
    analyse(mt)
    -- (not returned as a tail call of rawget: a LuaJIT trace cannot return from a fast
    -- function's tail call through this metamethod's frame, and the read would be interpreted)
    local confidence = rawget(t, key)
    return confidence
  elseif key == "covariance" then
    local cov = covariance(mt, analyse(mt), is_alt)
    rawset(t, "covariance", cov)
    return cov
  elseif key == "track" and not is_alt then
    local a, b = candidates(mt)
    local track = require("tagpose.track")
    local x = made(mt)
    local state = x[X_TRACK] or track.new_state()
    x[X_TRACK] = state
    track.step(nil, a, b, mt[SIDE], mt[TIME] or nil, state)
    rawset(t, "track", state)
    return state
  end
  return nil
end

-- A pose table of a candidate: new (one constructor per table), or `into` filled in place.
local function pose_table(c, err, iterations, refine_iterations, into)
  local r = c.r
  if not into then
    return {
      position = { x = c.tx, y = c.ty, z = c.tz },
      rotation = { { r[1], r[2], r[3] }, { r[4], r[5], r[6] }, { r[7], r[8], r[9] } },
      quaternion = { w = c.qw, x = c.qx, y = c.qy, z = c.qz },
      error = err,
      iterations = iterations,
      refine_iterations = refine_iterations,
    }
  end
  local p = into.position
  if type(p) ~= "table" then
    p = {}
    into.position = p
  end
  p.x, p.y, p.z = c.tx, c.ty, c.tz
  local rt = into.rotation
  if type(rt) ~= "table" then
    rt = {}
    into.rotation = rt
  end
  to_nested(r, rt)
  local qt = into.quaternion
  if type(qt) ~= "table" then
    qt = {}
    into.quaternion = qt
  end
  qt.w, qt.x, qt.y, qt.z = c.qw, c.qx, c.qy, c.qz
  into.error, into.iterations, into.refine_iterations = err, iterations, refine_iterations
  local alt = rawget(into, "alternative")
  if alt then spare[into] = alt end
  into.alternative, into.confidence, into.covariance, into.track = nil, nil, nil, nil
  into.warning = nil
  return into
end

--- The result of a solve from its candidates: the pose `a`, the other minimum `b` (or nil),
-- with the fields above made on read.
-- @tparam table ctx the solve's context (`tagpose.result.context`): its `camera` (kept for the
--   fields made on read), `half` (half the tag side), `time` (false: none), `into` (false: a
--   new table), `seed` and `work` (solveQuad's iterations, and for the refined method the
--   linearisations spent on a)
-- @tparam table a the pose's candidate (`r`, `tx`, `ty`, `tz`, `qw`, `qx`, `qy`, `qz`, `sse`,
--   `normal`: H in its first 21 numbers)
-- @tparam number ea its RMS reprojection error (px)
-- @tparam ?table b the other minimum's candidate (its `linearisations` spent on it), or nil
-- @tparam ?number eb its error
-- @tparam ?number sigma2 σ² (px²), or nil: the default pooled with a's residuals
-- @tparam number side the tag's side in pixels
-- @treturn table the pose
function M.new(ctx, a, ea, b, eb, sigma2, side)
  local w, camera, half, time, into = ctx.work, ctx.camera, ctx.half, ctx.time, ctx.into
  local lb = b and b.linearisations
  local result = pose_table(a, ea, w.iterations, not ctx.seed and w.linearisations or nil,
    into or nil)
  local count = b and 2 or 1
  b = b or a
  -- (the checksum of the pose table, from the numbers it was just filled with)
  local na, nb, r, sum = a.normal, b.normal, b.r, a.tx + a.ty + a.tz + a.qw + a.qx + a.qy + a.qz
  local mt = into and getmetatable(result) -- (a new table has none)
  if not (mt and mt.__index == made_on_read) then
    -- (one constructor: the array part is allocated once, at its size)
    setmetatable(result, { camera, half, sigma2 or false, side, time or false, result, sum,
      na[1], na[2], na[3], na[4], na[5], na[6], na[7], na[8], na[9], na[10], na[11], na[12],
      na[13], na[14], na[15], na[16], na[17], na[18], na[19], na[20], na[21],
      nb[1], nb[2], nb[3], nb[4], nb[5], nb[6], nb[7], nb[8], nb[9], nb[10], nb[11], nb[12],
      nb[13], nb[14], nb[15], nb[16], nb[17], nb[18], nb[19], nb[20], nb[21],
      a.sse, b.sse, r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], b.tx, b.ty, b.tz,
      b.qw, b.qx, b.qy, b.qz, count == 2 and eb, lb or false, false, __index = made_on_read })
    if count == 1 then result.confidence = 1 end
    return result
  end
  -- (an `into` table solved again keeps a record of its own: the tables read before are filled
  -- again)
  if cached[1] == mt then cached[1] = false end
  local x = made(mt)
  if x[X_ALT] then spare[result] = x[X_ALT] end
  x[X_ALT], x[X_ANALYSED] = false, false
  mt[CAMERA], mt[HALF], mt[SIGMA2], mt[SIDE], mt[TIME], mt[FIRST], mt[CHECK] =
    camera, half, sigma2 or false, side, time or false, result, sum
  for i = 1, 21 do mt[H_A + i], mt[H_B + i] = na[i], nb[i] end
  mt[SSE_A], mt[SSE_B] = a.sse, b.sse
  for i = 1, 9 do mt[R_B + i] = r[i] end
  mt[T_B + 1], mt[T_B + 2], mt[T_B + 3] = b.tx, b.ty, b.tz
  mt[Q_B + 1], mt[Q_B + 2], mt[Q_B + 3], mt[Q_B + 4] = b.qw, b.qx, b.qy, b.qz
  mt[ERR_B], mt[LIN_B] = count == 2 and eb, lb or false
  if count == 1 then result.confidence = 1 end
  return result
end

--- Set the branch confidence of a result (a tracker's) instead of the single frame's.
-- @tparam table result a result of `new`
-- @tparam number confidence the pose's; its alternative's is the complement
-- @treturn table result
function M.set_confidence(result, confidence)
  rawset(result, "confidence", confidence)
  return result
end

return M
