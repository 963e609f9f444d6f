--- The map check: where each map tag was seen against where the map puts it.
-- @module tagpose.localizer.mapcheck

local fit = require("tagpose.localizer.fit")
local linalg = require("tagpose.localizer.linalg")

local sqrt = math.sqrt
local tag_normal = fit.tag_normal

local M = {}

-- The map check: each tag seen in a frame that placed the robot, the move of its centre that
-- explains its corners in that frame with the robot at the estimate (`fit.tag_normal`), with
-- its information; kept by tag, frame time and camera (a frame replayed after late data
-- replaces its own entry).
function M.add(checks, time, camera, obs, r, t, sigma)
  local ch = checks
  for _, ob in ipairs(obs) do
    local A, b = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }, { 0, 0, 0 }
    if tag_normal(ob, r, t[1], t[2], t[3], sigma, A, b) then
      local Ai = linalg.invert(A, 3, {})
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
    local Ai = used > 0 and linalg.invert(A, 3, {})
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
