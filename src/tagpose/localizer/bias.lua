--- The bias the mounts' and the map's errors put in the fused estimate: the frames'
-- sensitivities of (x, y, heading) to each error (a camera's mount, a tag's place), averaged
-- as the frames weigh in the estimate, forgetting the older ones; its covariance `S̄ S̄ᵀ` per
-- error. A bias every frame of a camera shares stays whole; one that turns with the view
-- averages out.
-- @module tagpose.localizer.bias

local M = {}

--- The sums after a frame of camera `cam` with sensitivities `sens` (`tagpose.localizer.fit`'s
-- covariance) and weight w, into `s.bias`: every sum forgets by `a`, the frame's added; new
-- tables (a snapshot keeps its own).
-- @tparam table s the localizer's state
-- @tparam int cameras how many cameras
-- @tparam {number,...} ids the map's tag ids, sorted (the order of the sums)
-- @tparam int cam the frame's camera
-- @tparam table sens its sensitivities
-- @tparam number w its weight
-- @tparam number a the weight of the past
function M.update(s, cameras, ids, cam, sens, w, a)
  local old = s.bias or { w = 0, cams = {}, tags = {} }
  local new = { w = a * old.w + w, cams = {}, tags = {} }
  for c = 1, cameras do
    local e, add = old.cams[c], c == cam and sens.mount
    if e or add then
      local v = {}
      for k = 1, 18 do v[k] = a * (e and e[k] or 0) + (add and w * add[k] or 0) end
      new.cams[c] = v
    end
  end
  for i = 1, #ids do
    local id = ids[i]
    local e, add = old.tags[id], sens.tags[id]
    if e or add then
      local v = {}
      for k = 1, 9 do v[k] = a * (e and e[k] or 0) + (add and w * add[k] or 0) end
      new.tags[id] = v
    end
  end
  s.bias = new
end

--- The position's covariance from the mounts' and the map's errors: each error's mean
-- sensitivity S̄ = Σ w S / Σ w, summed as S̄ S̄ᵀ (their covariance over σ per axis is I).
-- @tparam ?table b the sums (`s.bias`)
-- @tparam int cameras
-- @tparam {number,...} ids
-- @treturn number c11, c12, c22 (m²), then c13, c23 (m·rad), c33 (rad²) of the heading
function M.covariance(b, cameras, ids)
  if not b or not (b.w > 0) then return 0, 0, 0, 0, 0, 0 end
  local iw = 1 / b.w
  local b11, b12, b22, b13, b23, b33 = 0, 0, 0, 0, 0, 0
  local function add(S, cols)
    for c = 1, cols do
      local x, y, h = S[c] * iw, S[cols + c] * iw, S[2 * cols + c] * iw
      b11, b12, b22 = b11 + x * x, b12 + x * y, b22 + y * y
      b13, b23, b33 = b13 + x * h, b23 + y * h, b33 + h * h
    end
  end
  for c = 1, cameras do
    if b.cams[c] then add(b.cams[c], 6) end
  end
  for i = 1, #ids do
    local S = b.tags[ids[i]]
    if S then add(S, 3) end
  end
  return b11, b12, b22, b13, b23, b33
end

return M
