--- Blocks: what the frame's blocks seen with two or more faces show of the scene — which way
-- is up (`options.up = "auto"`) and where the floor is (`options.floor = "auto"`) — for the
-- blocks seen with one face, which cannot tell.
--
-- Both assume that every block in view rests on a face, on the floor or on other blocks, and
-- that the camera is rolled and pitched by less than 45 degrees.
-- @module tagpose.block.scene

local cube = require("tagpose.rigid.cube")
local fit = require("tagpose.block.fit")

local sqrt, abs, huge = math.sqrt, math.abs, math.huge

local M = {}

require("tagpose.core.compat").interpret_module()

--- Default `floor_tolerance` with `floor = "auto"`, × block_size: about how well one block
-- seen with two faces shows the floor (its centre to ~0.7 mm, mostly along the line of sight,
-- for the lab's blocks and camera).
M.AUTO_FLOOR_TOLERANCE = 0.01

--- Up from the blocks found with two or more faces: the face axis nearest `guess` of each
-- (each block resting on a face has one along gravity), summed with weights by faces.
-- @tparam {table,...} found the blocks found, each with its hypothesis `h`
-- @tparam {number,...} guess a direction near up (the camera's −y)
-- @treturn {number,...}|nil the unit up, nil when no block shows it
function M.up(found, guess)
  local ux, uy, uz, any = 0, 0, 0, false
  for i = 1, #found do
    local h = found[i].h
    local n = #h.members
    if n > 1 then
      local r = h.r
      local k, d = cube.nearest_axis(r, guess[1], guess[2], guess[3])
      local w = d < 0 and -n or n
      ux, uy, uz, any = ux + w * r[k], uy + w * r[3 + k], uz + w * r[6 + k], true
    end
  end
  if not any then return nil end
  local norm = sqrt(ux * ux + uy * uy + uz * uz)
  if not (norm > 0) then return nil end
  return { ux / norm, uy / norm, uz / norm }
end

--- The camera's height above the floor from the blocks found with two or more faces (but the
-- `except`-th), each taken to rest at the level (0 on the floor, 1 on one block, ...) nearest
-- its height above the lowest of them, weighted by faces.
-- @tparam {table,...} found the blocks found
-- @tparam {number,...} up the unit up
-- @tparam number B the block size
-- @tparam[opt] int except a block to leave out
-- @treturn number|nil the floor, nil when no block shows it
function M.floor(found, up, B, except)
  local low = huge
  for i = 1, #found do
    local h = found[i].h
    if #h.members > 1 and i ~= except then
      local height = up[1] * h.x + up[2] * h.y + up[3] * h.z
      if height < low then low = height end
    end
  end
  if low == huge then return nil end
  local sum, weight = 0, 0
  for i = 1, #found do
    local h = found[i].h
    local n = #h.members
    if n > 1 and i ~= except then
      local height = up[1] * h.x + up[2] * h.y + up[3] * h.z
      local k = math.floor((height - low) / B + 0.5)
      if abs(height - low - k * B) <= fit.FLOOR_GATE * B then
        sum, weight = sum + n * (0.5 * B + k * B - height), weight + n
      end
    end
  end
  return sum / weight
end

--- The "auto" options, once every block seen with two or more faces is found: up from them,
-- the floor from them (each of those blocks fitted again on the floor the others show), for
-- the blocks seen with one face that remain. Sets the frame's `up`, `prior_w`, `floor_w` and
-- `floor`.
-- @tparam table fr the frame record
-- @tparam {table,...} found the blocks found so far
function M.infer(fr, found)
  local settings = fr.settings
  local sigma = sqrt(fr.sigma2)
  if settings.auto_up then
    fr.up = M.up(found, fr.default_up)
    fr.prior_w = fr.up and sigma / settings.up_tolerance or 0
  end
  if settings.auto_floor and fr.up then
    fr.floor_w = sigma / (settings.floor_tolerance or M.AUTO_FLOOR_TOLERANCE * fr.block_size)
    -- each block with two or more faces rests on the floor the others show
    for i = 1, #found do
      fr.floor = M.floor(found, fr.up, fr.block_size, i)
      if fr.floor then fit.refit_on_floor(fr, found[i].h) end
    end
    -- and those with one face on the floor all of them show
    fr.floor = M.floor(found, fr.up, fr.block_size)
  end
end

return M
