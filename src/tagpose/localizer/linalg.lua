--- The localizer's small dense algebra: inverses of the n×n and 3×3 matrices its fits and
-- filter form (flat, row-major, 1-based).
-- @module tagpose.localizer.linalg

local abs = math.abs

local M = {}

--- The inverse of a dense n×n (flat row-major), by Gauss-Jordan with partial pivoting.
-- @tparam {number,...} A
-- @tparam int n
-- @tparam {number,...} out n×n to fill
-- @treturn {number,...}|nil out, nil when A is singular
function M.invert(A, n, out)
  local a = {}
  for i = 1, n * n do a[i] = A[i] end
  for i = 1, n * n do out[i] = 0 end
  for i = 1, n do out[(i - 1) * n + i] = 1 end
  for col = 1, n do
    local p, best = col, abs(a[(col - 1) * n + col])
    for row = col + 1, n do
      local v = abs(a[(row - 1) * n + col])
      if v > best then p, best = row, v end
    end
    if not (best > 1e-300) then return nil end
    if p ~= col then
      for j = 1, n do
        local i1, i2 = (col - 1) * n + j, (p - 1) * n + j
        a[i1], a[i2] = a[i2], a[i1]
        out[i1], out[i2] = out[i2], out[i1]
      end
    end
    local d = 1 / a[(col - 1) * n + col]
    for j = 1, n do
      a[(col - 1) * n + j] = a[(col - 1) * n + j] * d
      out[(col - 1) * n + j] = out[(col - 1) * n + j] * d
    end
    for row = 1, n do
      if row ~= col then
        local f = a[(row - 1) * n + col]
        if f ~= 0 then
          for j = 1, n do
            a[(row - 1) * n + j] = a[(row - 1) * n + j] - f * a[(col - 1) * n + j]
            out[(row - 1) * n + j] = out[(row - 1) * n + j] - f * out[(col - 1) * n + j]
          end
        end
      end
    end
  end
  return out
end

--- The inverse of a 3×3 (flat row-major) by its cofactors, a new table.
-- @tparam {number,...} S
-- @treturn {number,...}|nil nil when S is singular
function M.inverse3(S)
  local a, b, c, d, e, f, g, h, i = S[1], S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9]
  local A, B, C = e * i - f * h, -(d * i - f * g), d * h - e * g
  local det = a * A + b * B + c * C
  if not (det > 0 or det < 0) then return nil end
  local r = 1 / det
  return { A * r, -(b * i - c * h) * r, (b * f - c * e) * r,
    B * r, (a * i - c * g) * r, -(a * f - c * d) * r,
    C * r, -(a * h - b * g) * r, (a * e - b * d) * r }
end

return M
