-- What the tracker's association costs on crowded frames of one id: N detections of id 0
-- (squares of a side w px), fed to `tracker:assign` (the association alone, no solve) for
-- three frames, each tag moved a little and the list shuffled between frames. Prints, per
-- arrangement and N, the CPU milliseconds per frame of the second and third frames (the first
-- only starts the tracks) and how many detections of them continued their own tag's track.
--
--   lua5.4 bench/crowd_association.lua [N ...]   (default 250 1000)
--
-- Arrangements: `grid` (w = 16, 1.2 sides apart: each within its neighbours' gates), `spread`
-- (w 10..20 at random over 4000 x 3000 px) and `pile` (w 20..40 within 5 px of one point:
-- every detection within every other's gate; which tag is which is then a matter of the
-- corners' noise, so the count of kept tracks is not a check there). Run from the repository
-- root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local tagpose = require("tagpose")

local sizes = {}
for i = 1, #arg do sizes[i] = assert(tonumber(arg[i]), "N expected") end
if #sizes == 0 then sizes = { 250, 1000 } end

local camera = { fx = 2000, fy = 2000, cx = 2000, cy = 1500, width = 4000, height = 3000 }
local cos, sin, floor = math.cos, math.sin, math.floor

-- Park-Miller: the same places on every VM
local seed = 1
local function uniform(a, b)
  seed = (16807 * seed) % 2147483647
  return a + (b - a) * seed / 2147483647
end

-- the tags of an arrangement: centre, side, roll
local function tags(kind, n)
  local list = {}
  for i = 1, n do
    local u, v, w
    if kind == "grid" then
      w = 16
      u, v = 100 + 1.2 * w * ((i - 1) % 150), 100 + 1.2 * w * floor((i - 1) / 150)
    elseif kind == "spread" then
      w, u, v = uniform(10, 20), uniform(50, 3950), uniform(50, 2950)
    else
      w, u, v = uniform(20, 40), 2000 + uniform(-5, 5), 1500 + uniform(-5, 5)
    end
    list[i] = { u = u, v = v, w = w, roll = uniform(0, 6.28) }
  end
  return list
end

-- frame k's detections, in a shuffled order, each tag moved by k px; the tag of each entry
local function frame(list, k)
  local order, dets = {}, {}
  for i = 1, #list do order[i] = i end
  for i = #order, 2, -1 do
    local j = floor(uniform(1, i + 0.999999))
    order[i], order[j] = order[j], order[i]
  end
  for e = 1, #order do
    local t = list[order[e]]
    local h, c, s = t.w / 2, cos(t.roll), sin(t.roll)
    local u, v = t.u + k, t.v + 0.5 * k
    local corners = {}
    for q, p in ipairs({ { -h, h }, { h, h }, { h, -h }, { -h, -h } }) do
      corners[q] = { u + c * p[1] - s * p[2], v + s * p[1] + c * p[2] }
    end
    dets[e] = { id = 0, corners = corners }
  end
  return dets, order
end

local vm = rawget(_G, "jit") and rawget(_G, "jit").version or _VERSION
print(vm .. ": CPU ms per frame of tracker:assign, N detections of one id (frames 2 and 3)")
for _, kind in ipairs({ "grid", "spread", "pile" }) do
  for _, n in ipairs(sizes) do
    seed = 1
    local list = tags(kind, n)
    local tr = tagpose.tracker.new(camera, 0.024, { max_tracks = 2 * n })
    local track_of = {}
    local dets, order = frame(list, 0)
    local seen = tr:assign(dets, 0)
    for e = 1, n do track_of[order[e]] = seen[e].track end
    local ms, kept = {}, 0
    for k = 1, 2 do
      dets, order = frame(list, k)
      collectgarbage()
      local t0 = os.clock()
      seen = tr:assign(dets, k / 30)
      ms[k] = (os.clock() - t0) * 1000
      for e = 1, n do
        if seen[e].track == track_of[order[e]] then kept = kept + 1 end
      end
    end
    print(("%-6s N %5d: %8.1f ms, %8.1f ms; %d of %d kept their track"):format(kind, n, ms[1],
      ms[2], kept, 2 * n))
  end
end
