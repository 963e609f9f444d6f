--- A result's confidence and covariance in passes of locals: what `tagpose.result.pose` makes
-- on read, on PUC Lua. The same arithmetic as `tagpose.uncertainty`'s `assess` and
-- `covariance` (and `tagpose.uncertainty.matrix`'s factors, inverse and table), operation for
-- operation, so the numbers are the same to the bit; only where they are kept differs: in
-- locals instead of candidate records and scratch arrays, read straight from the result's own
-- arrays. Nothing is kept between two calls, so no number depends on what was read before. (On
-- LuaJIT, whose traces do not take this many live locals, the two functions are
-- `tagpose.uncertainty.read_jit`'s.)
--
-- It reads the array part of a result's metatable, laid out by `tagpose.result.pose`: half the
-- tag side at 2, σ² (or false) at 3, the pose table at 6, its checksum at 7, H of each
-- candidate (21 numbers, `tagpose.core.lsq`'s layout) at 8..28 and 29..49, their residual sums
-- at 50 and 51, the other candidate's flat rotation at 52..60, its position at 61..63, its
-- quaternion at 64..67 and its error (false: the pose is the only minimum) at 68; it writes none
-- of them. It writes the record `x` of what was made on read (the same module's slots): the
-- chord factors at 3 and 4, the chord at 5..10, κ at 14, the factors of the pose's H at 15..35
-- and σ² at 36.
-- @module tagpose.uncertainty.read

local compat = require("tagpose.core.compat")
local uncertainty = require("tagpose.uncertainty")
local model = require("tagpose.uncertainty.model")

local sqrt, log, huge = math.sqrt, math.log, math.huge
local atan2 = compat.atan2
local lookup = model.lookup

local M = {}

-- the slots of the metatable and of the record (`tagpose.result.pose`)
local SIGMA2, FIRST, CHECK, SSE_A, SSE_B, ERR_B = 3, 6, 7, 50, 51, 68
local X_K_A, X_K_B, X_KAPPA, X_SIGMA2 = 3, 4, 14, 36

local CHANGED = "tagpose: a pose was changed in place after its solve: read its alternative, "
  .. "confidence, covariance and track before changing it (or copy it)"

-- as in `tagpose.uncertainty` and `tagpose.uncertainty.matrix`
local FACE_ON, DECIDED = 1e-3, 40
local SINGULAR, TINY = 1e-12, 1e-200

-- The LDLᵀ factors of a packed H (its 21 numbers): ln det H, then the pivots and multipliers
-- by columns, d1, l21 .. l61, d2, l32 .. l62, d3, l43 .. l63, d4, l54, l64, d5, l65, d6
-- (`tagpose.uncertainty.matrix.factor`).
local function factor(a11, a12, a13, a14, a15, a16, a22, n8, n9, n10, n11, a33, n13, n14, n15,
                      a44, n17, n18, a55, n20, a66)
  local d1 = a11
  if not (d1 > SINGULAR * a11) then d1 = SINGULAR * a11 + TINY end
  local e21, e31, e41, e51, e61 = a12, a13, a14, a15, a16
  local l21, l31, l41, l51, l61 = e21 / d1, e31 / d1, e41 / d1, e51 / d1, e61 / d1
  local d2 = a22 - l21 * e21
  if not (d2 > SINGULAR * a22) then d2 = SINGULAR * a22 + TINY end
  local e32, e42, e52, e62 = n8 - l31 * e21, n9 - l41 * e21, n10 - l51 * e21, n11 - l61 * e21
  local l32, l42, l52, l62 = e32 / d2, e42 / d2, e52 / d2, e62 / d2
  local d3 = a33 - l31 * e31 - l32 * e32
  if not (d3 > SINGULAR * a33) then d3 = SINGULAR * a33 + TINY end
  local e43 = n13 - l41 * e31 - l42 * e32
  local e53 = n14 - l51 * e31 - l52 * e32
  local e63 = n15 - l61 * e31 - l62 * e32
  local l43, l53, l63 = e43 / d3, e53 / d3, e63 / d3
  local d4 = a44 - l41 * e41 - l42 * e42 - l43 * e43
  if not (d4 > SINGULAR * a44) then d4 = SINGULAR * a44 + TINY end
  local e54 = n17 - l51 * e41 - l52 * e42 - l53 * e43
  local e64 = n18 - l61 * e41 - l62 * e42 - l63 * e43
  local l54, l64 = e54 / d4, e64 / d4
  local d5 = a55 - l51 * e51 - l52 * e52 - l53 * e53 - l54 * e54
  if not (d5 > SINGULAR * a55) then d5 = SINGULAR * a55 + TINY end
  local e65 = n20 - l61 * e51 - l62 * e52 - l63 * e53 - l64 * e54
  local l65 = e65 / d5
  local d6 = a66 - l61 * e61 - l62 * e62 - l63 * e63 - l64 * e64 - l65 * e65
  if not (d6 > SINGULAR * a66) then d6 = SINGULAR * a66 + TINY end
  return log(d1 * d2 * d3) + log(d4 * d5 * d6), d1, l21, l31, l41, l51, l61, d2, l32, l42, l52,
    l62, d3, l43, l53, l63, d4, l54, l64, d5, l65, d6
end

--- The branch analysis of a result, into its record x (the arithmetic of `assess`, the
-- noise's σ² and κ when none was given): the chord factors, the chord, κ, the pose's factors
-- and σ². The pose is checked against its checksum first.
-- @tparam table mt the result's metatable
-- @tparam table x its record of what was made on read
-- @treturn number the pose's confidence (1 when it is the only minimum)
-- @raise when the pose was changed in place after its solve
function M.analyse(mt, x)
  local p = mt[FIRST]
  local t, q, R = p.position, p.quaternion, p.rotation
  local tx, ty, tz, qw, qx, qy, qz = t.x, t.y, t.z, q.w, q.x, q.y, q.z
  if tx + ty + tz + qw + qx + qy + qz ~= mt[CHECK] then error(CHANGED, 4) end
  local sigma2, kappa = mt[SIGMA2], 1
  if not sigma2 then sigma2, kappa = uncertainty.noise(mt[SSE_A]) end
  x[X_SIGMA2], x[X_KAPPA] = sigma2, kappa
  if not mt[ERR_B] then
    x[X_K_A], x[X_K_B] = 0, 0
    x[5], x[6], x[7], x[8], x[9], x[10] = 0, 0, 0, 0, 0, 0
    return 1
  end
  local ld_a, d1, l21, l31, l41, l51, l61, d2, l32, l42, l52, l62, d3, l43, l53, l63, d4, l54,
    l64, d5, l65, d6 = factor(mt[8], mt[9], mt[10], mt[11], mt[12], mt[13], mt[14], mt[15],
    mt[16], mt[17], mt[18], mt[19], mt[20], mt[21], mt[22], mt[23], mt[24], mt[25], mt[26],
    mt[27], mt[28])
  x[15], x[16], x[17], x[18], x[19], x[20], x[21], x[22], x[23], x[24], x[25], x[26], x[27],
    x[28], x[29], x[30], x[31], x[32], x[33], x[34], x[35] = d1, l21, l31, l41, l51, l61, d2,
    l32, l42, l52, l62, d3, l43, l53, l63, d4, l54, l64, d5, l65, d6
  local ld_b, f1, m21, m31, m41, m51, m61, f2, m32, m42, m52, m62, f3, m43, m53, m63, f4, m54,
    m64, f5, m65, f6 = factor(mt[29], mt[30], mt[31], mt[32], mt[33], mt[34], mt[35], mt[36],
    mt[37], mt[38], mt[39], mt[40], mt[41], mt[42], mt[43], mt[44], mt[45], mt[46], mt[47],
    mt[48], mt[49])
  local dc = (mt[SSE_B] - mt[SSE_A]) / sigma2
  -- Laplace: each basin's mass exp(-χ²/2) (2π)³ det(H/σ²)^(-1/2), σ cancels in the ratio
  local L = 0.5 * dc + 0.5 * (ld_b - ld_a)
  local ka, kb = 0, 0
  if not (L > DECIDED or L < -DECIDED) then
    local shape = 0
    -- the tilts (the component of the tag's normal across the line of sight, `tilt`)
    local an1, an2, an3 = R[1][3], R[2][3], R[3][3]
    local ant = sqrt(tx * tx + ty * ty + tz * tz)
    local u1, u2, u3 = tx / ant, ty / ant, tz / ant
    local anl = an1 * u1 + an2 * u2 + an3 * u3
    local a1, a2, a3 = an1 - anl * u1, an2 - anl * u2, an3 - anl * u3
    local sa = sqrt(a1 * a1 + a2 * a2 + a3 * a3)
    local btx, bty, btz = mt[61], mt[62], mt[63]
    local bn1, bn2, bn3 = mt[54], mt[57], mt[60]
    local bnt = sqrt(btx * btx + bty * bty + btz * btz)
    u1, u2, u3 = btx / bnt, bty / bnt, btz / bnt
    local bnl = bn1 * u1 + bn2 * u2 + bn3 * u3
    local b1, b2, b3 = bn1 - bnl * u1, bn2 - bnl * u2, bn3 - bnl * u3
    local sb = sqrt(b1 * b1 + b2 * b2 + b3 * b3)
    -- each one's separation from the other's tilt along its own (`separation`), its variance
    -- by forward substitution in its factors (`tagpose.uncertainty.matrix.variance`)
    local p1, p2, p3 = a1 / sa, a2 / sa, a3 / sa
    local sep = sa - (b1 * p1 + b2 * p2 + b3 * p3)
    local k = -anl / ant
    local y1 = an2 * p3 - an3 * p2
    local y2 = an3 * p1 - an1 * p3 - l21 * y1
    local y3 = an1 * p2 - an2 * p1 - l31 * y1 - l32 * y2
    local y4 = k * p1 - l41 * y1 - l42 * y2 - l43 * y3
    local y5 = k * p2 - l51 * y1 - l52 * y2 - l53 * y3 - l54 * y4
    local y6 = k * p3 - l61 * y1 - l62 * y2 - l63 * y3 - l64 * y4 - l65 * y5
    local var = sigma2 * (y1 * y1 / d1 + y2 * y2 / d2 + y3 * y3 / d3 + y4 * y4 / d4
      + y5 * y5 / d5 + y6 * y6 / d6)
    if sep < 0 then sep = 0 end
    if var < 1e-300 then var = 1e-300 end
    local d2a = sep * sep / var
    p1, p2, p3 = b1 / sb, b2 / sb, b3 / sb
    sep = sb - (a1 * p1 + a2 * p2 + a3 * p3)
    k = -bnl / bnt
    y1 = bn2 * p3 - bn3 * p2
    y2 = bn3 * p1 - bn1 * p3 - m21 * y1
    y3 = bn1 * p2 - bn2 * p1 - m31 * y1 - m32 * y2
    y4 = k * p1 - m41 * y1 - m42 * y2 - m43 * y3
    y5 = k * p2 - m51 * y1 - m52 * y2 - m53 * y3 - m54 * y4
    y6 = k * p3 - m61 * y1 - m62 * y2 - m63 * y3 - m64 * y4 - m65 * y5
    var = sigma2 * (y1 * y1 / f1 + y2 * y2 / f2 + y3 * y3 / f3 + y4 * y4 / f4 + y5 * y5 / f5
      + y6 * y6 / f6)
    if sep < 0 then sep = 0 end
    if var < 1e-300 then var = 1e-300 end
    local d2b = sep * sep / var
    if sa > FACE_ON and sb > FACE_ON and d2a > 0 and d2b > 0 and d2a < huge and d2b < huge then
      -- the basins' shapes, and the tilt prior (uniform in angle: density ∝ 1 / sin θ)
      local phi_a, va = lookup(d2a, dc)
      local phi_b, vb = lookup(d2b, -dc)
      shape, ka, kb = phi_a - phi_b + log(sb / sa), (va - 1) / d2a, (vb - 1) / d2b
    end
    L = L + shape
    if not (L == L) then L = 0 end
  end
  x[X_K_A], x[X_K_B] = ka, kb
  if ka ~= 0 or kb ~= 0 then
    -- the chord from the pose to the other, qb qa⁻¹ and tb - ta (`tagpose.uncertainty.chord`)
    local bw, bx, by, bz, ax, ay, az = mt[64], mt[65], mt[66], mt[67], -qx, -qy, -qz
    local w = bw * qw - bx * ax - by * ay - bz * az
    local cx = bw * ax + bx * qw + by * az - bz * ay
    local cy = bw * ay - bx * az + by * qw + bz * ax
    local cz = bw * az + bx * ay - by * ax + bz * qw
    if w < 0 then w, cx, cy, cz = -w, -cx, -cy, -cz end
    local s = sqrt(cx * cx + cy * cy + cz * cz)
    local f = 2
    if s > 1e-12 then f = 2 * atan2(s, w) / s end
    x[5], x[6], x[7], x[8], x[9], x[10] = f * cx, f * cy, f * cz, mt[61] - tx, mt[62] - ty,
      mt[63] - tz
  else
    x[5], x[6], x[7], x[8], x[9], x[10] = 0, 0, 0, 0, 0, 0
  end
  return uncertainty.probability(L)
end

-- The covariance `s H⁻¹ + k d dᵀ` from H's factors (`tagpose.uncertainty.matrix`'s inverse
-- and table), into out or a new table.
local function fill(out, s, k, c1, c2, c3, c4, c5, c6, _, d1, l21, l31, l41, l51, l61, d2, l32,
                    l42, l52, l62, d3, l43, l53, l63, d4, l54, l64, d5, l65, d6)
  local i21 = -l21
  local i31 = -(l31 + l32 * i21)
  local i41 = -(l41 + l42 * i21 + l43 * i31)
  local i51 = -(l51 + l52 * i21 + l53 * i31 + l54 * i41)
  local i61 = -(l61 + l62 * i21 + l63 * i31 + l64 * i41 + l65 * i51)
  local i32 = -l32
  local i42 = -(l42 + l43 * i32)
  local i52 = -(l52 + l53 * i32 + l54 * i42)
  local i62 = -(l62 + l63 * i32 + l64 * i42 + l65 * i52)
  local i43 = -l43
  local i53 = -(l53 + l54 * i43)
  local i63 = -(l63 + l64 * i43 + l65 * i53)
  local i54 = -l54
  local i64 = -(l64 + l65 * i54)
  local i65 = -l65
  local r1, r2, r3, r4, r5, r6 = 1 / d1, 1 / d2, 1 / d3, 1 / d4, 1 / d5, 1 / d6
  local h11 = r1 + i21 * i21 * r2 + i31 * i31 * r3 + i41 * i41 * r4 + i51 * i51 * r5
    + i61 * i61 * r6
  local h12 = i21 * r2 + i31 * i32 * r3 + i41 * i42 * r4 + i51 * i52 * r5 + i61 * i62 * r6
  local h13 = i31 * r3 + i41 * i43 * r4 + i51 * i53 * r5 + i61 * i63 * r6
  local h14 = i41 * r4 + i51 * i54 * r5 + i61 * i64 * r6
  local h15 = i51 * r5 + i61 * i65 * r6
  local h16 = i61 * r6
  local h22 = r2 + i32 * i32 * r3 + i42 * i42 * r4 + i52 * i52 * r5 + i62 * i62 * r6
  local h23 = i32 * r3 + i42 * i43 * r4 + i52 * i53 * r5 + i62 * i63 * r6
  local h24 = i42 * r4 + i52 * i54 * r5 + i62 * i64 * r6
  local h25 = i52 * r5 + i62 * i65 * r6
  local h26 = i62 * r6
  local h33 = r3 + i43 * i43 * r4 + i53 * i53 * r5 + i63 * i63 * r6
  local h34 = i43 * r4 + i53 * i54 * r5 + i63 * i64 * r6
  local h35 = i53 * r5 + i63 * i65 * r6
  local h36 = i63 * r6
  local h44 = r4 + i54 * i54 * r5 + i64 * i64 * r6
  local h45 = i54 * r5 + i64 * i65 * r6
  local h46 = i64 * r6
  local h55 = r5 + i65 * i65 * r6
  local h56 = i65 * r6
  local h66 = r6
  -- in the contract's order: position (the last three of H's order) first
  local c11 = s * h44 + k * (c4 * c4)
  local c12 = s * h45 + k * (c4 * c5)
  local c13 = s * h46 + k * (c4 * c6)
  local c14 = s * h14 + k * (c1 * c4)
  local c15 = s * h24 + k * (c2 * c4)
  local c16 = s * h34 + k * (c3 * c4)
  local c22 = s * h55 + k * (c5 * c5)
  local c23 = s * h56 + k * (c5 * c6)
  local c24 = s * h15 + k * (c1 * c5)
  local c25 = s * h25 + k * (c2 * c5)
  local c26 = s * h35 + k * (c3 * c5)
  local c33 = s * h66 + k * (c6 * c6)
  local c34 = s * h16 + k * (c1 * c6)
  local c35 = s * h26 + k * (c2 * c6)
  local c36 = s * h36 + k * (c3 * c6)
  local c44 = s * h11 + k * (c1 * c1)
  local c45 = s * h12 + k * (c1 * c2)
  local c46 = s * h13 + k * (c1 * c3)
  local c55 = s * h22 + k * (c2 * c2)
  local c56 = s * h23 + k * (c2 * c3)
  local c66 = s * h33 + k * (c3 * c3)
  if out == nil then
    return { { c11, c12, c13, c14, c15, c16 }, { c12, c22, c23, c24, c25, c26 },
      { c13, c23, c33, c34, c35, c36 }, { c14, c24, c34, c44, c45, c46 },
      { c15, c25, c35, c45, c55, c56 }, { c16, c26, c36, c46, c56, c66 } }
  end
  local row = out[1]
  row[1], row[2], row[3], row[4], row[5], row[6] = c11, c12, c13, c14, c15, c16
  row = out[2]
  row[1], row[2], row[3], row[4], row[5], row[6] = c12, c22, c23, c24, c25, c26
  row = out[3]
  row[1], row[2], row[3], row[4], row[5], row[6] = c13, c23, c33, c34, c35, c36
  row = out[4]
  row[1], row[2], row[3], row[4], row[5], row[6] = c14, c24, c34, c44, c45, c46
  row = out[5]
  row[1], row[2], row[3], row[4], row[5], row[6] = c15, c25, c35, c45, c55, c56
  row = out[6]
  row[1], row[2], row[3], row[4], row[5], row[6] = c16, c26, c36, c46, c56, c66
  return out
end

--- The covariance of an analysed result's pose, or of its alternative (`analyse` first): κσ²
-- H⁻¹ and the chord term (`tagpose.uncertainty.covariance`), from the pose's factors kept by
-- `analyse` (or H factored here: the alternative's, or the only minimum's).
-- @tparam table mt the result's metatable
-- @tparam table x its record, analysed
-- @tparam boolean is_alt the alternative's
-- @tparam[opt] table out a nested 6×6 to fill (nil: a new one)
-- @treturn table the covariance
-- @raise when the pose was changed in place after its solve
function M.covariance(mt, x, is_alt, out)
  local p = mt[FIRST]
  local t, q = p.position, p.quaternion
  if t.x + t.y + t.z + q.w + q.x + q.y + q.z ~= mt[CHECK] then error(CHANGED, 4) end
  local kappa = x[X_KAPPA]
  local s = kappa * x[X_SIGMA2]
  if is_alt then
    local k = kappa * x[X_K_B]
    local c1, c2, c3, c4, c5, c6 = 0, 0, 0, 0, 0, 0
    if k == 0 then
      k = 0
    else
      c1, c2, c3, c4, c5, c6 = -1 * x[5], -1 * x[6], -1 * x[7], -1 * x[8], -1 * x[9], -1 * x[10]
    end
    return fill(out, s, k, c1, c2, c3, c4, c5, c6, factor(mt[29], mt[30], mt[31], mt[32],
      mt[33], mt[34], mt[35], mt[36], mt[37], mt[38], mt[39], mt[40], mt[41], mt[42], mt[43],
      mt[44], mt[45], mt[46], mt[47], mt[48], mt[49]))
  end
  if not mt[ERR_B] then
    return fill(out, s, 0, 0, 0, 0, 0, 0, 0, factor(mt[8], mt[9], mt[10], mt[11], mt[12],
      mt[13], mt[14], mt[15], mt[16], mt[17], mt[18], mt[19], mt[20], mt[21], mt[22], mt[23],
      mt[24], mt[25], mt[26], mt[27], mt[28]))
  end
  local k = kappa * x[X_K_A]
  local c1, c2, c3, c4, c5, c6 = 0, 0, 0, 0, 0, 0
  if k == 0 then
    k = 0
  else
    c1, c2, c3, c4, c5, c6 = x[5], x[6], x[7], x[8], x[9], x[10]
  end
  return fill(out, s, k, c1, c2, c3, c4, c5, c6, 0, x[15], x[16], x[17], x[18], x[19], x[20],
    x[21], x[22], x[23], x[24], x[25], x[26], x[27], x[28], x[29], x[30], x[31], x[32], x[33],
    x[34], x[35])
end

-- On LuaJIT, whose traces do not take these passes of locals: the same two functions in the
-- form they do take (`tagpose.uncertainty.read_jit`).
if compat.jit then
  local slots = require("tagpose.uncertainty.read_jit")
  M.analyse, M.covariance = slots.analyse, slots.covariance
end

return M
