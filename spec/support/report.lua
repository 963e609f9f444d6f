-- The report's camera equations as a matrix (its equation 9): the oracle against which
-- spec/square_spec.lua checks tagpose.square's closed forms (the library itself never builds
-- the matrix).
local R = {}

-- the signs (α, π) of A and P in corners 1..4
local ALPHA = { 1, 1, -1, -1 }
local PI = { 1, -1, -1, 1 }

--- The report's eight camera equations (its equation 9), in normalised coordinates: row
-- `2i - 1` is corner i's u-equation divided by fx, row `2i` its v-equation divided by fy;
-- columns are the coefficients of `x, y, z, a, b, c, p, q, r`.
-- @tparam {number,...} m flat corners (normalised)
-- @tparam[opt] {number,...} out flat 8×9 matrix to fill, row-major
-- @treturn {number,...} out
function R.camera_equations(m, out)
  out = out or {}
  for i = 1, 4 do
    local xi, yi, al, pi = m[2 * i - 1], m[2 * i], ALPHA[i], PI[i]
    local u, v = (2 * i - 2) * 9, (2 * i - 1) * 9
    out[u + 1], out[u + 2], out[u + 3] = -1, 0, xi
    out[u + 4], out[u + 5], out[u + 6] = -al, 0, al * xi
    out[u + 7], out[u + 8], out[u + 9] = -pi, 0, pi * xi
    out[v + 1], out[v + 2], out[v + 3] = 0, -1, yi
    out[v + 4], out[v + 5], out[v + 6] = 0, -al, al * yi
    out[v + 7], out[v + 8], out[v + 9] = 0, -pi, pi * yi
  end
  return out
end

return R
