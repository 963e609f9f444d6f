--- The map check: where each map tag was seen against where the map puts it.
-- @module tagpose.localizer.mapcheck

local fit = require("tagpose.localizer.fit")
local rotation = require("tagpose.core.rotation")

local sqrt = math.sqrt
local multiply = rotation.multiply

local M = {}

local rfc = {} -- scratch: the camera → field rotation

-- The normal equations of a tag's place (its centre moved by δp in the field, the robot's pose
-- held): `A += Σ e eᵀ`, `b += Σ e r` over its 8 residuals (`e` the residual's gradient in the
-- field frame); the least-squares move is `δp = −A⁻¹ b`.
-- @tparam table o an observation
-- @tparam {number,...} r robot → field rotation
-- @tparam number tx
-- @tparam number ty
-- @tparam number tz
-- @tparam number sigma σ, px
-- @tparam {number,...} A 3×3 (flat) to add to
-- @tparam {number,...} b 3 numbers to add to
-- @treturn boolean false when the tag is behind the camera (nothing added)
local function tag_normal(o, r, tx, ty, tz, sigma, A, b)
  local mnt = o.mount
  multiply(r, mnt.r, rfc)
  local f1, f2, f3, f4, f5, f6, f7, f8, f9 = rfc[1], rfc[2], rfc[3], rfc[4], rfc[5], rfc[6],
    rfc[7], rfc[8], rfc[9]
  local m = mnt.t
  local cx = r[1] * m[1] + r[2] * m[2] + r[3] * m[3] + tx
  local cy = r[4] * m[1] + r[5] * m[2] + r[6] * m[3] + ty
  local cz = r[7] * m[1] + r[8] * m[2] + r[9] * m[3] + tz
  local P, obs = o.tag.points, o.xy
  local fx, fy = o.fx / sigma, o.fy / sigma
  for pass = 1, 2 do
    for k = 1, 4 do
      local q = 3 * k
      local d1, d2, d3 = P[q - 2] - cx, P[q - 1] - cy, P[q] - cz
      local X = f1 * d1 + f4 * d2 + f7 * d3
      local Y = f2 * d1 + f5 * d2 + f8 * d3
      local Z = f3 * d1 + f6 * d2 + f9 * d3
      if not (Z > 1e-9) then return false end
      if pass == 2 then
        local iz = 1 / Z
        local xn, yn = X * iz, Y * iz
        local ru, rv = fx * (xn - obs[2 * k - 1]), fy * (yn - obs[2 * k])
        local a1, a3 = fx * iz, -fx * xn * iz
        local b2, b3 = fy * iz, -fy * yn * iz
        for side = 1, 2 do
          local e1, e2, e3, res = f1 * a1 + f3 * a3, f4 * a1 + f6 * a3, f7 * a1 + f9 * a3, ru
          if side == 2 then
            e1, e2, e3, res = f2 * b2 + f3 * b3, f5 * b2 + f6 * b3, f8 * b2 + f9 * b3, rv
          end
          A[1], A[2], A[3] = A[1] + e1 * e1, A[2] + e1 * e2, A[3] + e1 * e3
          A[4], A[5], A[6] = A[4] + e2 * e1, A[5] + e2 * e2, A[6] + e2 * e3
          A[7], A[8], A[9] = A[7] + e3 * e1, A[8] + e3 * e2, A[9] + e3 * e3
          b[1], b[2], b[3] = b[1] + e1 * res, b[2] + e2 * res, b[3] + e3 * res
        end
      end
    end
  end
  return true
end


-- The map check: each tag seen in a frame that placed the robot, the move of its centre that
-- explains its corners in that frame with the robot at the estimate (`tag_normal`), with
-- its information; kept by tag, frame time and camera (a frame replayed after late data
-- replaces its own entry).
function M.add(checks, time, camera, obs, r, t, sigma)
  local ch = checks
  for _, ob in ipairs(obs) do
    local A, b = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }, { 0, 0, 0 }
    if tag_normal(ob, r, t[1], t[2], t[3], sigma, A, b) then
      local Ai = fit.invert(A, 3, {})
      if Ai then
        local e = ch[ob.id] or {}
        ch[ob.id] = e
        e[("%.9g %s"):format(time, tostring(camera))] = { time = time,
          -(Ai[1] * b[1] + Ai[2] * b[2] + Ai[3] * b[3]),
          -(Ai[4] * b[1] + Ai[5] * b[2] + Ai[6] * b[3]),
          -(Ai[7] * b[1] + Ai[8] * b[2] + Ai[9] * b[3]), A }
      end
    end
  end
end

--- Where each map tag was seen against where the map puts it (with `options.map_check`): for
-- each tag seen in a frame that placed the robot, the move of its centre that explains its
-- corners with the robot where the localizer put it; over the frames, the median of each
-- coordinate, then the frames within 5σ of it (by each frame's own information, a phantom
-- detection's far outside) averaged by their information. Field frame, largest first.
-- @treturn {table,...} `{id =, dx =, dy =, dz =, distance =, frames =}` each
function M.list(checks)
  local out = {}
  for id, entries in pairs(checks) do
    local list = {}
    for _, e in pairs(entries) do list[#list + 1] = e end
    table.sort(list, function(a, b) return a.time < b.time end)
    local med = {}
    for k = 1, 3 do
      local v = {}
      for i, e in ipairs(list) do v[i] = e[k] end
      table.sort(v)
      local m = #v
      med[k] = m % 2 == 1 and v[(m + 1) / 2] or 0.5 * (v[m / 2] + v[m / 2 + 1])
    end
    local A, b, used = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }, { 0, 0, 0 }, 0
    for _, e in ipairs(list) do
      local W = e[4]
      local d1, d2, d3 = e[1] - med[1], e[2] - med[2], e[3] - med[3]
      local m2 = d1 * (W[1] * d1 + W[2] * d2 + W[3] * d3) + d2 * (W[4] * d1 + W[5] * d2
        + W[6] * d3) + d3 * (W[7] * d1 + W[8] * d2 + W[9] * d3)
      if m2 < 25 then
        for k = 1, 9 do A[k] = A[k] + W[k] end
        for k = 1, 3 do
          b[k] = b[k] + W[3 * k - 2] * e[1] + W[3 * k - 1] * e[2] + W[3 * k] * e[3]
        end
        used = used + 1
      end
    end
    local Ai = used > 0 and fit.invert(A, 3, {})
    if Ai then
      local dx = Ai[1] * b[1] + Ai[2] * b[2] + Ai[3] * b[3]
      local dy = Ai[4] * b[1] + Ai[5] * b[2] + Ai[6] * b[3]
      local dz = Ai[7] * b[1] + Ai[8] * b[2] + Ai[9] * b[3]
      out[#out + 1] = { id = id, dx = dx, dy = dy, dz = dz,
        distance = sqrt(dx * dx + dy * dy + dz * dz), frames = used }
    end
  end
  table.sort(out, function(a, b)
    if a.distance ~= b.distance then return a.distance > b.distance end
    return a.id < b.id
  end)
  return out
end


return M
