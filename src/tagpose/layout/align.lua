--- The rigid motion that best maps one set of points onto another, in the least-squares sense.
--
-- `rigid` is Horn's closed form ("Closed-form solution of absolute orientation using unit
-- quaternions", 1987): the rotation is the eigenvector of the largest eigenvalue of a symmetric
-- 4×4 matrix built from the points' cross-covariance, found here by cyclic Jacobi rotations.
-- `planes` weighs each point's distance along a direction of its own (a tag's normal) above
-- its distance across it, by Gauss-Newton from `rigid`'s motion.
--
-- Points are flat `{x1, y1, z1, x2, ...}`; the rotation comes out flat, row-major.
-- @module tagpose.layout.align

local rotation = require("tagpose.core.rotation")
local lsq = require("tagpose.core.lsq")

local sqrt, abs = math.sqrt, math.abs

local M = {}

--- Bound on the Jacobi sweeps (each sweep zeroes the six off-diagonal entries in turn; a
-- symmetric 4×4 matrix is diagonal to round-off after a handful).
M.SWEEPS = 50

-- The eigenvector of the largest eigenvalue of the symmetric 4×4 matrix a (flat, destroyed).
local function top_eigenvector(a)
  local v = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 }
  for _ = 1, M.SWEEPS do
    local off = 0
    for p = 1, 3 do
      for q = p + 1, 4 do off = off + (a[(p - 1) * 4 + q] * a[(p - 1) * 4 + q]) end
    end
    if off < 1e-30 then break end
    for p = 1, 3 do
      for q = p + 1, 4 do
        local apq = a[(p - 1) * 4 + q]
        if abs(apq) > 1e-300 then
          local app, aqq = a[(p - 1) * 4 + p], a[(q - 1) * 4 + q]
          local theta = (aqq - app) / (2 * apq)
          local t = (theta >= 0 and 1 or -1) / (abs(theta) + sqrt(theta * theta + 1))
          local c = 1 / sqrt(t * t + 1)
          local s = t * c
          for k = 1, 4 do
            local akp, akq = a[(k - 1) * 4 + p], a[(k - 1) * 4 + q]
            a[(k - 1) * 4 + p], a[(k - 1) * 4 + q] = c * akp - s * akq, s * akp + c * akq
          end
          for k = 1, 4 do
            local apk, aqk = a[(p - 1) * 4 + k], a[(q - 1) * 4 + k]
            a[(p - 1) * 4 + k], a[(q - 1) * 4 + k] = c * apk - s * aqk, s * apk + c * aqk
          end
          for k = 1, 4 do
            local vkp, vkq = v[(k - 1) * 4 + p], v[(k - 1) * 4 + q]
            v[(k - 1) * 4 + p], v[(k - 1) * 4 + q] = c * vkp - s * vkq, s * vkp + c * vkq
          end
        end
      end
    end
  end
  local best = 1
  for k = 2, 4 do
    if a[(k - 1) * 4 + k] > a[(best - 1) * 4 + best] then best = k end
  end
  return v[best], v[4 + best], v[8 + best], v[12 + best]
end

--- The rotation `R` and translation `t` minimising `Σ |R·a_k + t - b_k|²`.
-- @tparam {number,...} a the points to move, flat
-- @tparam {number,...} b where they should go, flat (as many)
-- @treturn {number,...} R, flat 3×3
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @treturn number the RMS distance `|R·a_k + t - b_k|` left
function M.rigid(a, b)
  local n = #a / 3
  local ax, ay, az, bx, by, bz = 0, 0, 0, 0, 0, 0
  for k = 1, n do
    local o = 3 * k - 3
    ax, ay, az = ax + a[o + 1], ay + a[o + 2], az + a[o + 3]
    bx, by, bz = bx + b[o + 1], by + b[o + 2], bz + b[o + 3]
  end
  ax, ay, az, bx, by, bz = ax / n, ay / n, az / n, bx / n, by / n, bz / n
  local sxx, sxy, sxz, syx, syy, syz, szx, szy, szz = 0, 0, 0, 0, 0, 0, 0, 0, 0
  for k = 1, n do
    local o = 3 * k - 3
    local p1, p2, p3 = a[o + 1] - ax, a[o + 2] - ay, a[o + 3] - az
    local q1, q2, q3 = b[o + 1] - bx, b[o + 2] - by, b[o + 3] - bz
    sxx, sxy, sxz = sxx + p1 * q1, sxy + p1 * q2, sxz + p1 * q3
    syx, syy, syz = syx + p2 * q1, syy + p2 * q2, syz + p2 * q3
    szx, szy, szz = szx + p3 * q1, szy + p3 * q2, szz + p3 * q3
  end
  local N = {
    sxx + syy + szz, syz - szy, szx - sxz, sxy - syx,
    syz - szy, sxx - syy - szz, sxy + syx, szx + sxz,
    szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy,
    sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz,
  }
  local w, x, y, z = top_eigenvector(N)
  local r = rotation.from_quaternion(w, x, y, z)
  local tx = bx - (r[1] * ax + r[2] * ay + r[3] * az)
  local ty = by - (r[4] * ax + r[5] * ay + r[6] * az)
  local tz = bz - (r[7] * ax + r[8] * ay + r[9] * az)
  local sum = 0
  for k = 1, n do
    local o = 3 * k - 3
    local p1, p2, p3 = a[o + 1], a[o + 2], a[o + 3]
    local d1 = r[1] * p1 + r[2] * p2 + r[3] * p3 + tx - b[o + 1]
    local d2 = r[4] * p1 + r[5] * p2 + r[6] * p3 + ty - b[o + 2]
    local d3 = r[7] * p1 + r[8] * p2 + r[9] * p3 + tz - b[o + 3]
    sum = sum + d1 * d1 + d2 * d2 + d3 * d3
  end
  return r, tx, ty, tz, sqrt(sum / n)
end

-- the weighted squared distance Σ dᵀ W d, W = eps·I + (1 - eps)·n nᵀ, of the moved points, and
-- (with N) the normal equations over (δω, δt) of the left update R ← C(δω)·R, t ← t + δt
local function weighted(a, b, normals, eps, r, tx, ty, tz, N)
  if N then
    for k = 1, 27 do N[k] = 0 end
  end
  local sum = 0
  for k = 1, #a / 3 do
    local o = 3 * k - 3
    local p1, p2, p3 = a[o + 1], a[o + 2], a[o + 3]
    local y1 = r[1] * p1 + r[2] * p2 + r[3] * p3
    local y2 = r[4] * p1 + r[5] * p2 + r[6] * p3
    local y3 = r[7] * p1 + r[8] * p2 + r[9] * p3
    local d1, d2, d3 = y1 + tx - b[o + 1], y2 + ty - b[o + 2], y3 + tz - b[o + 3]
    local n1, n2, n3 = normals[o + 1], normals[o + 2], normals[o + 3]
    local dn = n1 * d1 + n2 * d2 + n3 * d3
    sum = sum + eps * (d1 * d1 + d2 * d2 + d3 * d3) + (1 - eps) * dn * dn
    if N then
      -- residual rows: sqrt(eps)·e_j for j = 1..3 and sqrt(1 - eps)·n, each over (δω, δt)
      -- with ∂d/∂δω = -[y]× (row e: (y × e)), ∂d/∂δt = I
      for row = 1, 4 do
        local e1, e2, e3, w
        if row == 4 then
          e1, e2, e3, w = n1, n2, n3, sqrt(1 - eps)
        else
          e1, e2, e3, w = row == 1 and 1 or 0, row == 2 and 1 or 0, row == 3 and 1 or 0, sqrt(eps)
        end
        e1, e2, e3 = w * e1, w * e2, w * e3
        local res = e1 * d1 + e2 * d2 + e3 * d3
        local j = { y2 * e3 - y3 * e2, y3 * e1 - y1 * e3, y1 * e2 - y2 * e1, e1, e2, e3 }
        local i = 0
        for p = 1, 6 do
          for q = p, 6 do
            i = i + 1
            N[i] = N[i] + j[p] * j[q]
          end
          N[21 + p] = N[21 + p] + j[p] * res
        end
      end
    end
  end
  return sum
end

--- The rotation `R` and translation `t` minimising `Σ d_kᵀ W_k d_k`, `d_k = R·a_k + t - b_k`,
-- `W_k = eps·I + (1 - eps)·n_k n_kᵀ`: the distances along the unit directions `n_k` weigh
-- `1/eps` times those across them. (For tags: their planes are matched first, their places in
-- the planes second.)
-- @tparam {number,...} a the points to move, flat
-- @tparam {number,...} b where they should go, flat (as many)
-- @tparam {number,...} normals a unit direction per point, flat
-- @tparam number eps the weight across the directions (0 < eps <= 1)
-- @treturn {number,...} R, flat 3×3
-- @treturn number tx
-- @treturn number ty
-- @treturn number tz
-- @treturn number the RMS distance `|R·a_k + t - b_k|` left
function M.planes(a, b, normals, eps)
  local r, tx, ty, tz = M.rigid(a, b)
  local N = {}
  for _ = 1, 20 do
    weighted(a, b, normals, eps, r, tx, ty, tz, N)
    local d1, d2, d3, d4, d5, d6 = lsq.spd6(N[1], N[2], N[3], N[4], N[5], N[6], N[7], N[8],
      N[9], N[10], N[11], N[12], N[13], N[14], N[15], N[16], N[17], N[18], N[19], N[20], N[21],
      -N[22], -N[23], -N[24], -N[25], -N[26], -N[27])
    if not d1 then break end
    local c11, c12, c13, c21, c22, c23, c31, c32, c33 = lsq.cayley(d1, d2, d3)
    r = rotation.multiply({ c11, c12, c13, c21, c22, c23, c31, c32, c33 }, r)
    tx, ty, tz = tx + d4, ty + d5, tz + d6
    if d1 * d1 + d2 * d2 + d3 * d3 < 1e-24 and d4 * d4 + d5 * d5 + d6 * d6 < 1e-24 then break end
  end
  local sum, n = 0, #a / 3
  for k = 1, n do
    local o = 3 * k - 3
    local p1, p2, p3 = a[o + 1], a[o + 2], a[o + 3]
    local e1 = r[1] * p1 + r[2] * p2 + r[3] * p3 + tx - b[o + 1]
    local e2 = r[4] * p1 + r[5] * p2 + r[6] * p3 + ty - b[o + 2]
    local e3 = r[7] * p1 + r[8] * p2 + r[9] * p3 + tz - b[o + 3]
    sum = sum + e1 * e1 + e2 * e2 + e3 * e3
  end
  return r, tx, ty, tz, sqrt(sum / n)
end

return M
