-- examples/controller.lua as a module: the step a robot controller makes with tagpose.
local tagpose = require("tagpose")
local geometry = require("support.geometry")

local controller = dofile("examples/controller.lua")

local camera = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 }
local SIZE = 0.024

-- a tag list as robot Lua APIs hand it out: tags[i].id, tags[i].corners[j].x / .y
local function seen(id, r, t, extra)
  local px = assert(geometry.project(camera, r, t, SIZE))
  local corners = {}
  for j = 1, 4 do corners[j] = { x = px[j][1], y = px[j][2] } end
  local tag = { id = id, corners = corners, center = { x = 0, y = 0 } }
  for k, v in pairs(extra or {}) do tag[k] = v end
  return tag
end

local function at(u, v, width, k)
  return geometry.random_pose(nil, camera, SIZE, { width = width, tilt = 0.3 + 0.01 * k,
    azimuth = 0.5, roll = 0.1, u = u, v = v })
end

describe("examples/controller.lua", function()
  it("solves every tag of the list, in order, as tagpose.solve does", function()
    local ctl = controller.new(camera, SIZE)
    local r1, t1 = at(80, 120, 40, 0)
    local r2, t2 = at(240, 100, 30, 0)
    local poses = ctl:step({ seen(4, r1, t1), seen(9, r2, t2) })
    assert.equal(2, #poses)
    assert.same({ 4, 9 }, { poses[1].id, poses[2].id })
    assert.vector_near(t1, poses[1].pose.position, 1e-9)
    assert.vector_near(t2, poses[2].pose.position, 1e-9)
    assert.same(tagpose.solve(seen(9, r2, t2).corners, camera, SIZE).position,
      poses[2].pose.position)
    assert.is_false(poses[1].tracked)
  end)

  it("keeps each tag's track from step to step, and forgets it after a gap", function()
    local ctl = controller.new(camera, SIZE)
    local function step(k, ids)
      local list = {}
      for _, id in ipairs(ids) do
        local r, t = at(60 + 100 * id + k, 120, 40, k)
        list[#list + 1] = seen(id, r, t)
      end
      return ctl:step(list)
    end
    step(1, { 1, 2 })
    local second = step(2, { 1, 2 })
    assert.is_true(second[1].tracked)
    assert.is_true(second[2].tracked)
    -- the prior is the previous step's pose: the same result as solve with it
    local r, t = at(60 + 100 + 3, 120, 40, 3)
    local direct = tagpose.solve(seen(1, r, t).corners, camera, SIZE,
      { prior = ctl.tracks[1][1].pose })
    local third = step(3, { 1 })
    assert.same(direct.position, third[1].pose.position)
    assert.same(direct.track, third[1].pose.track)
    -- tag 2 was not seen in step 3: no prior in step 4, and its track is gone
    assert.is_nil(ctl.tracks[2])
    local fourth = step(4, { 1, 2 })
    assert.is_true(fourth[1].tracked)
    assert.is_false(fourth[2].tracked)
    ctl:reset()
    assert.same({}, ctl.tracks)
    assert.is_false(step(5, { 1 })[1].tracked)
  end)

  it("tells tags that share an id apart by where they are in the image", function()
    local ctl = controller.new(camera, SIZE)
    local ra, ta = at(70, 120, 40, 0)
    local rb, tb = at(250, 120, 40, 0)
    ctl:step({ seen(0, ra, ta), seen(0, rb, tb) })
    assert.equal(2, #ctl.tracks[0])
    -- listed the other way round next step: each continues its own track
    local poses = ctl:step({ seen(0, rb, tb), seen(0, ra, ta) })
    assert.is_true(poses[1].tracked and poses[2].tracked)
    assert.equal(2, #ctl.tracks[0])
    assert.vector_near(tb, ctl.tracks[0][2].pose.position, 1e-9)
  end)

  it("turns a bad detection into a reason instead of raising", function()
    local ctl = controller.new(camera, SIZE)
    local r, t = at(160, 120, 40, 0)
    local poses = ctl:step({
      { id = 1 },
      { id = 2, corners = { { x = 1, y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 } } },
      { id = 3, corners = { { x = 1, y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 },
        { x = 4, y = 4 } } },
      seen(4, r, t),
    })
    assert.equal(4, #poses)
    assert.equal("controller: tag 1 has no four corners {x =, y =}", poses[1].reason)
    assert.equal("controller: tag 2 has no four corners {x =, y =}", poses[2].reason)
    assert.equal("square: corners are collinear", poses[3].reason)
    assert.is_table(poses[4].pose)
    assert.same({}, ctl:step(nil))
  end)

  it("refuses a camera or tag size it cannot use", function()
    assert.has_error(function() controller.new({ fx = 300 }, SIZE) end,
      "bad argument #1 to 'new' (camera.fy: positive number expected, got nil)")
    assert.has_error(function() controller.new(camera, 0) end,
      "bad argument #2 to 'new' (positive number expected, got 0)")
  end)
end)
