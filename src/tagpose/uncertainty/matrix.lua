--- The 6×6 algebra of the uncertainty: the LDLᵀ factors of a pose's normal equations (their
-- log-determinant, a quadratic form of their inverse), the inverse itself, and a covariance
-- table filled in the contract's order. H is packed as the normal equations' first 21 numbers
-- (the upper triangle row by row, over (δω, δt), `tagpose.core.lsq`'s layout); nothing is
-- allocated but a new covariance table when asked for.
-- @module tagpose.uncertainty.matrix

local compat = require("tagpose.core.compat")

local log = math.log

local M = {}

-- pivots of H below SINGULAR times their diagonal are raised to it
local SINGULAR, TINY = 1e-12, 1e-200

-- The factors with their intermediates in table slots (for LuaJIT, see `fill`).
local function factor_table(N, F)
  local T = F
  T[1] = N[1]
  if not (T[1] > SINGULAR * N[1]) then T[1] = SINGULAR * N[1] + TINY end
  T[2] = N[2]
  T[3] = T[2] / T[1]
  T[4] = N[3]
  T[5] = T[4] / T[1]
  T[6] = N[4]
  T[7] = T[6] / T[1]
  T[8] = N[5]
  T[9] = T[8] / T[1]
  T[10] = N[6]
  T[11] = T[10] / T[1]
  T[12] = N[7] - T[3] * T[2]
  if not (T[12] > SINGULAR * N[7]) then T[12] = SINGULAR * N[7] + TINY end
  T[13] = N[8] - T[5] * T[2]
  T[14] = T[13] / T[12]
  T[15] = N[9] - T[7] * T[2]
  T[16] = T[15] / T[12]
  T[17] = N[10] - T[9] * T[2]
  T[18] = T[17] / T[12]
  T[19] = N[11] - T[11] * T[2]
  T[20] = T[19] / T[12]
  T[21] = N[12] - T[5] * T[4] - T[14] * T[13]
  if not (T[21] > SINGULAR * N[12]) then T[21] = SINGULAR * N[12] + TINY end
  T[22] = N[13] - T[7] * T[4] - T[16] * T[13]
  T[23] = T[22] / T[21]
  T[24] = N[14] - T[9] * T[4] - T[18] * T[13]
  T[25] = T[24] / T[21]
  T[26] = N[15] - T[11] * T[4] - T[20] * T[13]
  T[27] = T[26] / T[21]
  T[28] = N[16] - T[7] * T[6] - T[16] * T[15] - T[23] * T[22]
  if not (T[28] > SINGULAR * N[16]) then T[28] = SINGULAR * N[16] + TINY end
  T[29] = N[17] - T[9] * T[6] - T[18] * T[15] - T[25] * T[22]
  T[30] = T[29] / T[28]
  T[31] = N[18] - T[11] * T[6] - T[20] * T[15] - T[27] * T[22]
  T[32] = T[31] / T[28]
  T[33] = N[19] - T[9] * T[8] - T[18] * T[17] - T[25] * T[24] - T[30] * T[29]
  if not (T[33] > SINGULAR * N[19]) then T[33] = SINGULAR * N[19] + TINY end
  T[34] = N[20] - T[11] * T[8] - T[20] * T[17] - T[27] * T[24] - T[32] * T[29]
  T[35] = T[34] / T[33]
  T[36] = N[21] - T[11] * T[10] - T[20] * T[19] - T[27] * T[26] - T[32] * T[31] - T[35] * T[34]
  if not (T[36] > SINGULAR * N[21]) then T[36] = SINGULAR * N[21] + TINY end
  return log(T[1] * T[12] * T[21]) + log(T[28] * T[33] * T[36])
end

-- The factors with locals (the fastest on PUC Lua), the same slots filled at the end.
local function factor_unrolled(N, F)
  local a11, a12, a13, a14, a15, a16 = N[1], N[2], N[3], N[4], N[5], N[6]
  local d1 = a11
  if not (d1 > SINGULAR * a11) then d1 = SINGULAR * a11 + TINY end
  local e21, e31, e41, e51, e61 = a12, a13, a14, a15, a16
  local l21, l31, l41, l51, l61 = e21 / d1, e31 / d1, e41 / d1, e51 / d1, e61 / d1
  local a22 = N[7]
  local d2 = a22 - l21 * e21
  if not (d2 > SINGULAR * a22) then d2 = SINGULAR * a22 + TINY end
  local e32, e42, e52, e62 = N[8] - l31 * e21, N[9] - l41 * e21, N[10] - l51 * e21,
    N[11] - l61 * e21
  local l32, l42, l52, l62 = e32 / d2, e42 / d2, e52 / d2, e62 / d2
  local a33 = N[12]
  local d3 = a33 - l31 * e31 - l32 * e32
  if not (d3 > SINGULAR * a33) then d3 = SINGULAR * a33 + TINY end
  local e43 = N[13] - l41 * e31 - l42 * e32
  local e53 = N[14] - l51 * e31 - l52 * e32
  local e63 = N[15] - l61 * e31 - l62 * e32
  local l43, l53, l63 = e43 / d3, e53 / d3, e63 / d3
  local a44 = N[16]
  local d4 = a44 - l41 * e41 - l42 * e42 - l43 * e43
  if not (d4 > SINGULAR * a44) then d4 = SINGULAR * a44 + TINY end
  local e54 = N[17] - l51 * e41 - l52 * e42 - l53 * e43
  local e64 = N[18] - l61 * e41 - l62 * e42 - l63 * e43
  local l54, l64 = e54 / d4, e64 / d4
  local a55 = N[19]
  local d5 = a55 - l51 * e51 - l52 * e52 - l53 * e53 - l54 * e54
  if not (d5 > SINGULAR * a55) then d5 = SINGULAR * a55 + TINY end
  local e65 = N[20] - l61 * e51 - l62 * e52 - l63 * e53 - l64 * e54
  local l65 = e65 / d5
  local a66 = N[21]
  local d6 = a66 - l61 * e61 - l62 * e62 - l63 * e63 - l64 * e64 - l65 * e65
  if not (d6 > SINGULAR * a66) then d6 = SINGULAR * a66 + TINY end
  F[1], F[3], F[5], F[7], F[9], F[11] = d1, l21, l31, l41, l51, l61
  F[12], F[14], F[16], F[18], F[20] = d2, l32, l42, l52, l62
  F[21], F[23], F[25], F[27], F[28], F[30], F[32] = d3, l43, l53, l63, d4, l54, l64
  F[33], F[35], F[36] = d5, l65, d6
  return log(d1 * d2 * d3) + log(d4 * d5 * d6)
end

--- The LDLᵀ factors of the packed 6×6 symmetric H (upper triangle row by row, as the normal
-- equations' first 21 numbers) into F: the pivots in `F[1], F[12], F[21], F[28], F[33], F[36]`,
-- the multipliers `l_ij` and the products `e_ij = l_ij d_j` in between. A pivot below
-- `SINGULAR` times its diagonal entry is raised to it (a direction the view does not measure
-- gets a huge but finite variance).
-- @tparam {number,...} N the normal equations (H in their first 21 numbers)
-- @tparam {number,...} F scratch of 36 numbers to fill
-- @treturn number ln det H
-- @function factor
M.factor = compat.jit and factor_table or factor_unrolled

--- The quadratic form `qᵀ H⁻¹ q` of a factored H (`factor`), by forward substitution.
-- @tparam {number,...} F the factors
-- @tparam number q1 the vector q, in (δω, δt) order
-- @tparam number q2
-- @tparam number q3
-- @tparam number q4
-- @tparam number q5
-- @tparam number q6
-- @treturn number
function M.variance(F, q1, q2, q3, q4, q5, q6)
  local y1 = q1
  local y2 = q2 - F[3] * y1
  local y3 = q3 - F[5] * y1 - F[14] * y2
  local y4 = q4 - F[7] * y1 - F[16] * y2 - F[23] * y3
  local y5 = q5 - F[9] * y1 - F[18] * y2 - F[25] * y3 - F[30] * y4
  local y6 = q6 - F[11] * y1 - F[20] * y2 - F[27] * y3 - F[32] * y4 - F[35] * y5
  return y1 * y1 / F[1] + y2 * y2 / F[12] + y3 * y3 / F[21] + y4 * y4 / F[28]
    + y5 * y5 / F[33] + y6 * y6 / F[36]
end

--- The inverse of a factored H, packed like H, into out.
-- @tparam {number,...} F the factors (`factor`; its slots 37 to 57 are used as scratch)
-- @tparam {number,...} out 21 numbers to fill
-- @treturn {number,...} out
function M.inverse(F, out)
  local T = F
  T[37] = -T[3]
  T[38] = -(T[5] + T[14] * T[37])
  T[39] = -(T[7] + T[16] * T[37] + T[23] * T[38])
  T[40] = -(T[9] + T[18] * T[37] + T[25] * T[38] + T[30] * T[39])
  T[41] = -(T[11] + T[20] * T[37] + T[27] * T[38] + T[32] * T[39] + T[35] * T[40])
  T[42] = -T[14]
  T[43] = -(T[16] + T[23] * T[42])
  T[44] = -(T[18] + T[25] * T[42] + T[30] * T[43])
  T[45] = -(T[20] + T[27] * T[42] + T[32] * T[43] + T[35] * T[44])
  T[46] = -T[23]
  T[47] = -(T[25] + T[30] * T[46])
  T[48] = -(T[27] + T[32] * T[46] + T[35] * T[47])
  T[49] = -T[30]
  T[50] = -(T[32] + T[35] * T[49])
  T[51] = -T[35]
  T[52] = 1 / T[1]
  T[53] = 1 / T[12]
  T[54] = 1 / T[21]
  T[55] = 1 / T[28]
  T[56] = 1 / T[33]
  T[57] = 1 / T[36]
  out[1] = T[52] + T[37] * T[37] * T[53] + T[38] * T[38] * T[54] + T[39] * T[39] * T[55]
    + T[40] * T[40] * T[56] + T[41] * T[41] * T[57]
  out[2] = T[37] * T[53] + T[38] * T[42] * T[54] + T[39] * T[43] * T[55] + T[40] * T[44] * T[56]
    + T[41] * T[45] * T[57]
  out[3] = T[38] * T[54] + T[39] * T[46] * T[55] + T[40] * T[47] * T[56] + T[41] * T[48] * T[57]
  out[4] = T[39] * T[55] + T[40] * T[49] * T[56] + T[41] * T[50] * T[57]
  out[5] = T[40] * T[56] + T[41] * T[51] * T[57]
  out[6] = T[41] * T[57]
  out[7] = T[53] + T[42] * T[42] * T[54] + T[43] * T[43] * T[55] + T[44] * T[44] * T[56]
    + T[45] * T[45] * T[57]
  out[8] = T[42] * T[54] + T[43] * T[46] * T[55] + T[44] * T[47] * T[56] + T[45] * T[48] * T[57]
  out[9] = T[43] * T[55] + T[44] * T[49] * T[56] + T[45] * T[50] * T[57]
  out[10] = T[44] * T[56] + T[45] * T[51] * T[57]
  out[11] = T[45] * T[57]
  out[12] = T[54] + T[46] * T[46] * T[55] + T[47] * T[47] * T[56] + T[48] * T[48] * T[57]
  out[13] = T[46] * T[55] + T[47] * T[49] * T[56] + T[48] * T[50] * T[57]
  out[14] = T[47] * T[56] + T[48] * T[51] * T[57]
  out[15] = T[48] * T[57]
  out[16] = T[55] + T[49] * T[49] * T[56] + T[50] * T[50] * T[57]
  out[17] = T[49] * T[56] + T[50] * T[51] * T[57]
  out[18] = T[50] * T[57]
  out[19] = T[56] + T[51] * T[51] * T[57]
  out[20] = T[51] * T[57]
  out[21] = T[57]
  return out
end

-- out = s S + k d dᵀ in the contract's order (position first, then rotation), S packed in
-- (δω, δt) order, d = (d1..d6) in that order too; out a nested 6×6 filled in place, or nil for
-- a new one (made in one constructor); returns it.
local function fill_unrolled(out, S, s, k, d1, d2, d3, d4, d5, d6)
  local h11, h12, h13, h14, h15, h16 = S[1], S[2], S[3], S[4], S[5], S[6]
  local h22, h23, h24, h25, h26 = S[7], S[8], S[9], S[10], S[11]
  local h33, h34, h35, h36 = S[12], S[13], S[14], S[15]
  local h44, h45, h46 = S[16], S[17], S[18]
  local h55, h56 = S[19], S[20]
  local h66 = S[21]
  local c11 = s * h44 + k * (d4 * d4)
  local c12 = s * h45 + k * (d4 * d5)
  local c13 = s * h46 + k * (d4 * d6)
  local c14 = s * h14 + k * (d1 * d4)
  local c15 = s * h24 + k * (d2 * d4)
  local c16 = s * h34 + k * (d3 * d4)
  local c22 = s * h55 + k * (d5 * d5)
  local c23 = s * h56 + k * (d5 * d6)
  local c24 = s * h15 + k * (d1 * d5)
  local c25 = s * h25 + k * (d2 * d5)
  local c26 = s * h35 + k * (d3 * d5)
  local c33 = s * h66 + k * (d6 * d6)
  local c34 = s * h16 + k * (d1 * d6)
  local c35 = s * h26 + k * (d2 * d6)
  local c36 = s * h36 + k * (d3 * d6)
  local c44 = s * h11 + k * (d1 * d1)
  local c45 = s * h12 + k * (d1 * d2)
  local c46 = s * h13 + k * (d1 * d3)
  local c55 = s * h22 + k * (d2 * d2)
  local c56 = s * h23 + k * (d2 * d3)
  local c66 = s * h33 + k * (d3 * d3)
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


local function fill_table(out, S, s, k, d1, d2, d3, d4, d5, d6)
  if out == nil then
    out = { { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 },
      { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 }, { 0, 0, 0, 0, 0, 0 } }
  end
  local o1, o2, o3, o4, o5, o6 = out[1], out[2], out[3], out[4], out[5], out[6]
  local v
  o1[1] = s * S[16] + k * (d4 * d4)
  v = s * S[17] + k * (d4 * d5)
  o1[2], o2[1] = v, v
  v = s * S[18] + k * (d4 * d6)
  o1[3], o3[1] = v, v
  v = s * S[4] + k * (d1 * d4)
  o1[4], o4[1] = v, v
  v = s * S[9] + k * (d2 * d4)
  o1[5], o5[1] = v, v
  v = s * S[13] + k * (d3 * d4)
  o1[6], o6[1] = v, v
  o2[2] = s * S[19] + k * (d5 * d5)
  v = s * S[20] + k * (d5 * d6)
  o2[3], o3[2] = v, v
  v = s * S[5] + k * (d1 * d5)
  o2[4], o4[2] = v, v
  v = s * S[10] + k * (d2 * d5)
  o2[5], o5[2] = v, v
  v = s * S[14] + k * (d3 * d5)
  o2[6], o6[2] = v, v
  o3[3] = s * S[21] + k * (d6 * d6)
  v = s * S[6] + k * (d1 * d6)
  o3[4], o4[3] = v, v
  v = s * S[11] + k * (d2 * d6)
  o3[5], o5[3] = v, v
  v = s * S[15] + k * (d3 * d6)
  o3[6], o6[3] = v, v
  o4[4] = s * S[1] + k * (d1 * d1)
  v = s * S[2] + k * (d1 * d2)
  o4[5], o5[4] = v, v
  v = s * S[3] + k * (d1 * d3)
  o4[6], o6[4] = v, v
  o5[5] = s * S[7] + k * (d2 * d2)
  v = s * S[8] + k * (d2 * d3)
  o5[6], o6[5] = v, v
  o6[6] = s * S[12] + k * (d3 * d3)
  return out
end

--- A covariance table from a packed H⁻¹: `s S + k d dᵀ`, in the contract's order (position
-- first, then rotation), S and d in (δω, δt) order; into the nested 6×6 `out`, or a new one.
-- (Two forms of one function: with locals, the fastest on PUC Lua; with table slots on LuaJIT,
-- whose traces abort on the locals' spills.)
-- @function fill
-- @tparam[opt] table out nested 6×6 to fill
-- @tparam {number,...} S packed H⁻¹
-- @tparam number s σ²
-- @tparam number k the factor of d dᵀ
-- @tparam number d1 d, six numbers
-- @treturn table out
M.fill = compat.jit and fill_table or fill_unrolled

return M
