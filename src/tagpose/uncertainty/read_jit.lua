--- A result's confidence and covariance on LuaJIT: `tagpose.uncertainty.read`'s two functions
-- (the same contract, the same record, the same numbers to the bit), in the form LuaJIT's trace
-- compiler takes. `read`'s passes of locals do not compile there: a trace holds at most 127
-- spilled numbers, and a side trace takes over every live local of the trace it leaves. So
-- here each step is a function of its own whose numbers are handed on in arrays (scratch,
-- written and read within one call), H is factored straight from the result's metatable into
-- scratch (`tagpose.uncertainty.matrix`'s factors, slot by slot), no number is live across a
-- call of C (log, a table's allocation: every register is spilled across it), and the
-- analysis opens with a short loop: its trace is where a caller's trace ends, which would
-- otherwise take in the whole read (some 2000 instructions of LuaJIT's IR) and, at the end of
-- a solve in a loop, grow too long to compile and fall back to the interpreter.
--
-- The layout it reads and writes is `tagpose.uncertainty.read`'s (and `tagpose.result.pose`'s):
-- the metatable's σ² (or false) at 3, the pose table at 6, its checksum at 7, H of each
-- candidate at 8..28 and 29..49, their residual sums at 50 and 51, the other candidate's flat
-- rotation at 52..60, position at 61..63, quaternion at 64..67, error (false: one minimum) at
-- 68, none of them written; the record's chord factors at 3 and 4, chord at 5..10, κ at 14, the
-- factors of the pose's H at 15..35 (d1, l21 .. l61, d2, l32 .. l62, d3, l43 .. l63, d4, l54,
-- l64, d5, l65, d6) and σ² at 36.
-- @module tagpose.uncertainty.read_jit

local compat = require("tagpose.core.compat")
local uncertainty = require("tagpose.uncertainty")
local model = require("tagpose.uncertainty.model")

local sqrt, log, huge = math.sqrt, math.log, math.huge
local atan2 = compat.atan2
local lookup, noise, probability = model.lookup, uncertainty.noise, uncertainty.probability
-- (a candidate's tilt, and its separation from the other's, are `tagpose.uncertainty`'s)
local tilt, separation = uncertainty.tilt, uncertainty.separation

local M = {}

-- the slots of the metatable and of the record (`tagpose.result.pose`)
local SIGMA2, FIRST, CHECK, SSE_A, SSE_B, ERR_B = 3, 6, 7, 50, 51, 68
local H_A, H_B = 7, 28
local X_K_A, X_K_B, X_KAPPA, X_SIGMA2 = 3, 4, 14, 36

local CHANGED = "tagpose: a pose was changed in place after its solve: read its alternative, "
  .. "confidence, covariance and track before changing it (or copy it)"

-- as in `tagpose.uncertainty` and `tagpose.uncertainty.matrix`
local FACE_ON, DECIDED = 1e-3, 40
local SINGULAR, TINY = 1e-12, 1e-200

-- scratch, written and read within one call
local factors_a, factors_b = {}, {}
local tilts = {} -- each candidate's normal, sin θ, tilt, n·l and |t| (`tilts_of`)
local across = {} -- sin θ of each candidate, d² of each, Δc (`evidence`)

-- The LDLᵀ factors of the H at mt[o + 1 .. o + 21] into T, in `matrix.factor`'s slots (its
-- table form, operation for operation; ln det H is `logdet`'s).
local function factor(mt, o, T)
  T[1] = mt[o + 1]
  if not (T[1] > SINGULAR * mt[o + 1]) then T[1] = SINGULAR * mt[o + 1] + TINY end
  T[2] = mt[o + 2]
  T[3] = T[2] / T[1]
  T[4] = mt[o + 3]
  T[5] = T[4] / T[1]
  T[6] = mt[o + 4]
  T[7] = T[6] / T[1]
  T[8] = mt[o + 5]
  T[9] = T[8] / T[1]
  T[10] = mt[o + 6]
  T[11] = T[10] / T[1]
  T[12] = mt[o + 7] - T[3] * T[2]
  if not (T[12] > SINGULAR * mt[o + 7]) then T[12] = SINGULAR * mt[o + 7] + TINY end
  T[13] = mt[o + 8] - T[5] * T[2]
  T[14] = T[13] / T[12]
  T[15] = mt[o + 9] - T[7] * T[2]
  T[16] = T[15] / T[12]
  T[17] = mt[o + 10] - T[9] * T[2]
  T[18] = T[17] / T[12]
  T[19] = mt[o + 11] - T[11] * T[2]
  T[20] = T[19] / T[12]
  T[21] = mt[o + 12] - T[5] * T[4] - T[14] * T[13]
  if not (T[21] > SINGULAR * mt[o + 12]) then T[21] = SINGULAR * mt[o + 12] + TINY end
  T[22] = mt[o + 13] - T[7] * T[4] - T[16] * T[13]
  T[23] = T[22] / T[21]
  T[24] = mt[o + 14] - T[9] * T[4] - T[18] * T[13]
  T[25] = T[24] / T[21]
  T[26] = mt[o + 15] - T[11] * T[4] - T[20] * T[13]
  T[27] = T[26] / T[21]
  T[28] = mt[o + 16] - T[7] * T[6] - T[16] * T[15] - T[23] * T[22]
  if not (T[28] > SINGULAR * mt[o + 16]) then T[28] = SINGULAR * mt[o + 16] + TINY end
  T[29] = mt[o + 17] - T[9] * T[6] - T[18] * T[15] - T[25] * T[22]
  T[30] = T[29] / T[28]
  T[31] = mt[o + 18] - T[11] * T[6] - T[20] * T[15] - T[27] * T[22]
  T[32] = T[31] / T[28]
  T[33] = mt[o + 19] - T[9] * T[8] - T[18] * T[17] - T[25] * T[24] - T[30] * T[29]
  if not (T[33] > SINGULAR * mt[o + 19]) then T[33] = SINGULAR * mt[o + 19] + TINY end
  T[34] = mt[o + 20] - T[11] * T[8] - T[20] * T[17] - T[27] * T[24] - T[32] * T[29]
  T[35] = T[34] / T[33]
  T[36] = mt[o + 21] - T[11] * T[10] - T[20] * T[19] - T[27] * T[26] - T[32] * T[31]
    - T[35] * T[34]
  if not (T[36] > SINGULAR * mt[o + 21]) then T[36] = SINGULAR * mt[o + 21] + TINY end
end

-- ln det H from its factors (`matrix.factor`'s value). (Apart from the factors: a call of a C
-- function such as log takes every register, so that every number live across it is spilled.)
local function logdet(T)
  return log(T[1] * T[12] * T[21]) + log(T[28] * T[33] * T[36])
end

-- The chord from the pose to the other, qb qa⁻¹ and tb - ta (`tagpose.uncertainty.chord`), into
-- the record's slots 5..10.
local function chord(mt, x)
  local p = mt[FIRST]
  local t, q = p.position, p.quaternion
  x[8], x[9], x[10] = mt[61] - t.x, mt[62] - t.y, mt[63] - t.z
  local qw, ax, ay, az = q.w, -q.x, -q.y, -q.z
  local bw, bx, by, bz = mt[64], mt[65], mt[66], mt[67]
  local w = bw * qw - bx * ax - by * ay - bz * az
  local cx = bw * ax + bx * qw + by * az - bz * ay
  local cy = bw * ay - bx * az + by * qw + bz * ax
  local cz = bw * az + bx * ay - by * ax + bz * qw
  if w < 0 then w, cx, cy, cz = -w, -cx, -cy, -cz end
  local s = sqrt(cx * cx + cy * cy + cz * cz)
  local f = 2
  if s > 1e-12 then f = 2 * atan2(s, w) / s end
  x[5], x[6], x[7] = f * cx, f * cy, f * cz
end

-- The tilts of the pose and of the other into `tilts`.
local function tilts_of(mt)
  local p = mt[FIRST]
  local t, R = p.position, p.rotation
  local an1, an2, an3 = R[1][3], R[2][3], R[3][3]
  local sa, a1, a2, a3, anl, ant = tilt(an1, an2, an3, t.x, t.y, t.z)
  local bn1, bn2, bn3 = mt[54], mt[57], mt[60]
  local sb, b1, b2, b3, bnl, bnt = tilt(bn1, bn2, bn3, mt[61], mt[62], mt[63])
  local S = tilts
  S[1], S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9] = an1, an2, an3, sa, a1, a2, a3, anl, ant
  S[10], S[11], S[12], S[13], S[14], S[15], S[16], S[17], S[18] = bn1, bn2, bn3, sb, b1, b2, b3,
    bnl, bnt
end

-- The pose's factors into the record, for its covariance.
local function keep(x, F)
  x[15], x[16], x[17], x[18], x[19], x[20] = F[1], F[3], F[5], F[7], F[9], F[11]
  x[21], x[22], x[23], x[24], x[25] = F[12], F[14], F[16], F[18], F[20]
  x[26], x[27], x[28], x[29], x[30], x[31], x[32] = F[21], F[23], F[25], F[27], F[28], F[30],
    F[32]
  x[33], x[34], x[35] = F[33], F[35], F[36]
end

-- The tilts, the factors of each H (the pose's into the record) and each one's separation
-- from the other's tilt along its own: the Laplace log-odds returned, the rest into `across`.
-- (Each step a function of its own, its values handed on in arrays: a guard's snapshot holds
-- every live local of the frames below it, which would stay in registers or spill slots.)
local function evidence(mt, x, sigma2)
  tilts_of(mt)
  local S, Fa, Fb = tilts, factors_a, factors_b
  factor(mt, H_A, Fa)
  keep(x, Fa)
  local d2a = separation(S[1], S[2], S[3], Fa, sigma2, S[4], S[5], S[6], S[7], S[8], S[9],
    S[14], S[15], S[16])
  factor(mt, H_B, Fb)
  local d2b = separation(S[10], S[11], S[12], Fb, sigma2, S[13], S[14], S[15], S[16], S[17],
    S[18], S[5], S[6], S[7])
  local dc = (mt[SSE_B] - mt[SSE_A]) / sigma2
  across[1], across[2], across[3], across[4], across[5] = S[4], S[13], d2a, d2b, dc
  -- Laplace: each basin's mass exp(-χ²/2) (2π)³ det(H/σ²)^(-1/2), σ cancels in the ratio
  local ld_a = logdet(Fa)
  return 0.5 * dc + 0.5 * (logdet(Fb) - ld_a)
end

-- Whether both candidates are off face-on and across each other's tilt.
local function is_across()
  local d2a, d2b = across[3], across[4]
  return across[1] > FACE_ON and across[2] > FACE_ON and d2a > 0 and d2b > 0 and d2a < huge
    and d2b < huge
end

-- The basins' part of the log-odds, the chord factors into the record.
local function shapes(x)
  local d2a, d2b, dc = across[3], across[4], across[5]
  local phi_a, va = lookup(d2a, dc)
  local phi_b, vb = lookup(d2b, -dc)
  x[X_K_A], x[X_K_B] = (va - 1) / d2a, (vb - 1) / d2b
  -- the basins' shapes, and the tilt prior (uniform in angle: density ∝ 1 / sin θ)
  return phi_a - phi_b + log(across[2] / across[1])
end

-- σ² and κ into the record, the pose checked first; returns σ².
local function noise_of(mt, x)
  local p = mt[FIRST]
  local t, q = p.position, p.quaternion
  if t.x + t.y + t.z + q.w + q.x + q.y + q.z ~= mt[CHECK] then error(CHANGED, 5) end
  local sigma2, kappa = mt[SIGMA2], 1
  if not sigma2 then sigma2, kappa = noise(mt[SSE_A]) end
  x[X_SIGMA2], x[X_KAPPA] = sigma2, kappa
  return sigma2
end

--- The branch analysis of a result, into its record x (`tagpose.uncertainty.read.analyse`: the
-- same numbers, with few live locals where it branches).
-- @tparam table mt the result's metatable
-- @tparam table x its record of what was made on read
-- @treturn number the pose's confidence (1 when it is the only minimum)
-- @raise when the pose was changed in place after its solve
function M.analyse(mt, x)
  -- (the chord factors and the chord, 0 unless made below: a loop, whose trace of its own ends a
  -- caller's, see the header)
  for i = 3, 10 do x[i] = 0 end
  local sigma2 = noise_of(mt, x)
  if not mt[ERR_B] then return 1 end
  local L = evidence(mt, x, sigma2)
  if not (L > DECIDED or L < -DECIDED) then
    if is_across() then
      L = L + shapes(x)
    else
      L = L + 0
    end
    if not (L == L) then L = 0 end
  end
  local confidence = probability(L)
  if x[X_K_A] ~= 0 or x[X_K_B] ~= 0 then chord(mt, x) end
  return confidence
end

-- The covariance `s H⁻¹ + k c cᵀ` from H's factors (`matrix`'s inverse and table, the same
-- operations), into the nested 6×6 out: each entry stored as soon as it is made (both places,
-- the table is symmetric), so that few values are live at once.
local function fill(out, s, k, c1, c2, c3, c4, c5, c6, d1, l21, l31, l41, l51, l61, d2, l32,
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
  local o1, o2, o3, o4, o5, o6 = out[1], out[2], out[3], out[4], out[5], out[6]
  -- H⁻¹ row by row (h11 .. h66, in (δω, δt) order), each into the contract's places
  -- (position, the last three of H's order, first)
  local v = s * (r1 + i21 * i21 * r2 + i31 * i31 * r3 + i41 * i41 * r4 + i51 * i51 * r5
    + i61 * i61 * r6) + k * (c1 * c1)
  o4[4] = v
  v = s * (i21 * r2 + i31 * i32 * r3 + i41 * i42 * r4 + i51 * i52 * r5 + i61 * i62 * r6)
    + k * (c1 * c2)
  o4[5], o5[4] = v, v
  v = s * (i31 * r3 + i41 * i43 * r4 + i51 * i53 * r5 + i61 * i63 * r6) + k * (c1 * c3)
  o4[6], o6[4] = v, v
  v = s * (i41 * r4 + i51 * i54 * r5 + i61 * i64 * r6) + k * (c1 * c4)
  o1[4], o4[1] = v, v
  v = s * (i51 * r5 + i61 * i65 * r6) + k * (c1 * c5)
  o2[4], o4[2] = v, v
  v = s * (i61 * r6) + k * (c1 * c6)
  o3[4], o4[3] = v, v
  v = s * (r2 + i32 * i32 * r3 + i42 * i42 * r4 + i52 * i52 * r5 + i62 * i62 * r6)
    + k * (c2 * c2)
  o5[5] = v
  v = s * (i32 * r3 + i42 * i43 * r4 + i52 * i53 * r5 + i62 * i63 * r6) + k * (c2 * c3)
  o5[6], o6[5] = v, v
  v = s * (i42 * r4 + i52 * i54 * r5 + i62 * i64 * r6) + k * (c2 * c4)
  o1[5], o5[1] = v, v
  v = s * (i52 * r5 + i62 * i65 * r6) + k * (c2 * c5)
  o2[5], o5[2] = v, v
  v = s * (i62 * r6) + k * (c2 * c6)
  o3[5], o5[3] = v, v
  v = s * (r3 + i43 * i43 * r4 + i53 * i53 * r5 + i63 * i63 * r6) + k * (c3 * c3)
  o6[6] = v
  v = s * (i43 * r4 + i53 * i54 * r5 + i63 * i64 * r6) + k * (c3 * c4)
  o1[6], o6[1] = v, v
  v = s * (i53 * r5 + i63 * i65 * r6) + k * (c3 * c5)
  o2[6], o6[2] = v, v
  v = s * (i63 * r6) + k * (c3 * c6)
  o3[6], o6[3] = v, v
  v = s * (r4 + i54 * i54 * r5 + i64 * i64 * r6) + k * (c4 * c4)
  o1[1] = v
  v = s * (i54 * r5 + i64 * i65 * r6) + k * (c4 * c5)
  o1[2], o2[1] = v, v
  v = s * (i64 * r6) + k * (c4 * c6)
  o1[3], o3[1] = v, v
  v = s * (r5 + i65 * i65 * r6) + k * (c5 * c5)
  o2[2] = v
  v = s * (i65 * r6) + k * (c5 * c6)
  o2[3], o3[2] = v, v
  o3[3] = s * r6 + k * (c6 * c6)
  return out
end

-- fill from factors in `matrix.factor`'s slots
local function fill_factors(out, s, k, c1, c2, c3, c4, c5, c6, F)
  return fill(out, s, k, c1, c2, c3, c4, c5, c6, F[1], F[3], F[5], F[7], F[9], F[11], F[12],
    F[14], F[16], F[18], F[20], F[21], F[23], F[25], F[27], F[28], F[30], F[32], F[33], F[35],
    F[36])
end

--- The covariance of an analysed result's pose, or of its alternative
-- (`tagpose.uncertainty.read.covariance`).
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
  if out == nil then
    -- (made before any number is loaded: each table is made by a call, across which every
    -- live number would be spilled)
    out = { { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 },
      { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 } }
  end
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
    local F = factors_b
    factor(mt, H_B, F)
    return fill_factors(out, s, k, c1, c2, c3, c4, c5, c6, F)
  end
  if not mt[ERR_B] then
    local F = factors_a
    factor(mt, H_A, F)
    return fill_factors(out, s, 0, 0, 0, 0, 0, 0, 0, F)
  end
  local k = kappa * x[X_K_A]
  local c1, c2, c3, c4, c5, c6 = 0, 0, 0, 0, 0, 0
  if k == 0 then
    k = 0
  else
    c1, c2, c3, c4, c5, c6 = x[5], x[6], x[7], x[8], x[9], x[10]
  end
  return fill(out, s, k, c1, c2, c3, c4, c5, c6, x[15], x[16], x[17], x[18], x[19], x[20],
    x[21], x[22], x[23], x[24], x[25], x[26], x[27], x[28], x[29], x[30], x[31], x[32], x[33],
    x[34], x[35])
end

return M
