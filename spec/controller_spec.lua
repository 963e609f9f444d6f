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

  -- changed with the tracker: the prior is the track's last pose with the step's time, the
  -- gap is in seconds (tagpose.tracker's max_gap), and tracks are the tracker's
  it("keeps each tag's track from step to step, and forgets it after a gap", function()
    local ctl = controller.new(camera, SIZE, { max_gap = 0.05 })
    local function step(k, ids)
      local list = {}
      for _, id in ipairs(ids) do
        local r, t = at(60 + 100 * id + k, 120, 40, k)
        list[#list + 1] = seen(id, r, t)
      end
      return ctl:step(list, k / 30)
    end
    local first = step(1, { 1, 2 })
    local second = step(2, { 1, 2 })
    assert.is_true(second[1].tracked)
    assert.is_true(second[2].tracked)
    assert.same({ first[1].track, first[2].track }, { second[1].track, second[2].track })
    -- the tracker runs the filter solve runs with options.prior: the same poses and
    -- confidences as a chain of solves, each frame's prior the frame before's result
    local direct
    for k = 1, 3 do
      local r, t = at(60 + 100 + k, 120, 40, k)
      direct = tagpose.solve(seen(1, r, t).corners, camera, SIZE,
        { prior = direct, time = k / 30 })
    end
    local third = step(3, { 1 })
    assert.same(direct.position, third[1].pose.position)
    assert.same(direct.quaternion, third[1].pose.quaternion)
    assert.equal(direct.confidence, third[1].pose.confidence)
    -- tag 2 was not seen in step 3, nor 4: more than max_gap; its track is gone, a new
    -- one starts with a new id
    step(4, { 1 })
    local fifth = step(5, { 1, 2 })
    assert.is_true(fifth[1].tracked)
    assert.is_false(fifth[2].tracked)
    assert.is_true(fifth[2].track > second[2].track)
    ctl:reset()
    local after = step(6, { 1 })
    assert.is_false(after[1].tracked)
    -- ids are never reused, reset included
    assert.is_true(after[1].track > fifth[2].track)
  end)

  it("tells tags that share an id apart by where they are in the image", function()
    local ctl = controller.new(camera, SIZE)
    local ra, ta = at(70, 120, 40, 0)
    local rb, tb = at(250, 120, 40, 0)
    local first = ctl:step({ seen(0, ra, ta), seen(0, rb, tb) })
    assert.are_not.equal(first[1].track, first[2].track)
    -- listed the other way round next step: each continues its own track
    local poses = ctl:step({ seen(0, rb, tb), seen(0, ra, ta) })
    assert.is_true(poses[1].tracked and poses[2].tracked)
    assert.equal(first[2].track, poses[1].track)
    assert.equal(first[1].track, poses[2].track)
    assert.vector_near(tb, poses[1].pose.position, 1e-9)
  end)

  -- changed: the reasons are the tracker's; malformed entries of every kind never raise
  it("turns a bad detection into a reason instead of raising", function()
    local ctl = controller.new(camera, SIZE)
    local r, t = at(160, 120, 40, 0)
    local poses = ctl:step({
      { id = 1 },
      { id = 2, corners = { { x = 1, y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 } } },
      { id = 3, corners = { { x = 1, y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 },
        { x = 4, y = 4 } } },
      seen(4, r, t),
      false,
      42,
      { corners = seen(5, r, t).corners },
      { id = 0 / 0, corners = seen(5, r, t).corners },
      { id = 6, corners = { { x = "a", y = 1 }, { x = 2, y = 2 }, { x = 3, y = 3 },
        { x = 4, y = 4 } } },
    })
    assert.equal(9, #poses)
    assert.equal("tracker: entry 1: corners: table of four corners expected, got nil",
      poses[1].reason)
    assert.equal("tracker: entry 2: corners: four corners expected, got 3", poses[2].reason)
    assert.equal("square: corners are collinear", poses[3].reason)
    assert.is_table(poses[4].pose)
    assert.equal("tracker: entry 5 is not a detection {id =, corners =} (got boolean)",
      poses[5].reason)
    assert.equal("tracker: entry 6 is not a detection {id =, corners =} (got number)",
      poses[6].reason)
    assert.equal("tracker: entry 7 has no usable id (got nil)", poses[7].reason)
    assert.equal("tracker: entry 8 has no usable id (got NaN)", poses[8].reason)
    assert.matches("^tracker: entry 9: corners: corner 1", poses[9].reason)
    for i = 1, 9 do assert.equal(i, poses[i].index) end
    assert.equal(0, #ctl:step(nil))
  end)

  it("never restarts block ids: a step without blocks keeps the count", function()
    local ctl = controller.new(camera, SIZE)
    local r, t = at(160, 120, 60, 0)
    local r2, t2 = at(40, 60, 60, 0)
    local ids = {}
    for k = 1, 4 do
      local list = k == 3 and { { id = 1, corners = { { x = 1, y = 1 }, { x = 2, y = 2 },
        { x = 3, y = 3 }, { x = 4, y = 4 } } } } or { seen(1, r, t) }
      -- the tag moves far between steps, so each block is a new one
      if k == 4 then list = { seen(1, r2, t2) } end
      local _, blocks = ctl:step(list)
      assert.is_table(blocks)
      ids[k] = blocks[1] and blocks[1].id or false
    end
    assert.is_false(ids[3])
    assert.is_true(ids[1] == ids[2])
    assert.is_true(ids[4] > ids[2], "block ids " .. tostring(ids[2]) .. ", " .. tostring(ids[4]))
  end)

  it("groups only the tags on blocks into blocks", function()
    local ra, ta = at(70, 120, 40, 0)
    local rb, tb = at(250, 120, 40, 0)
    local wall = controller.new(camera, SIZE, { block_ids = { 7 } })
    local poses, blocks = wall:step({ seen(30, ra, ta), seen(31, rb, tb) })
    assert.is_table(poses[1].pose)
    assert.is_table(poses[2].pose)
    assert.equal(0, #blocks)
    local some = controller.new(camera, SIZE, { block_ids = { 31 } })
    local _, some_blocks = some:step({ seen(30, ra, ta), seen(31, rb, tb) })
    assert.equal(1, #some_blocks)
    assert.same({ 2 }, some_blocks[1].tags)
  end)

  it("refuses a camera or tag size it cannot use", function()
    assert.has_error(function() controller.new({ fx = 300 }, SIZE) end,
      "bad argument #1 to 'new' (camera.fy: positive number expected, got nil)")
    assert.has_error(function() controller.new(camera, 0) end,
      "bad argument #2 to 'new' (positive number expected, got 0)")
  end)
end)
