-- tagpose.block on scenes of several blocks: up and the floor (given or "auto"), grouping
-- touching and stacked cubes, the canonical frame, tracking with options.previous. From
-- geometry (the scenes: spec/support/blocks.lua).
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local blocks_support = require("support.blocks")

local sqrt, rad, abs = math.sqrt, math.rad, math.abs

local camera, TAG, BLOCK = blocks_support.camera, blocks_support.TAG, blocks_support.BLOCK
local apply, symmetric_error = blocks_support.apply, blocks_support.symmetric_error
local robot_camera, view, yaw = blocks_support.robot_camera, blocks_support.view,
  blocks_support.yaw
local random_block, solve = blocks_support.random_block, blocks_support.solve

describe("tagpose.block", function()
  describe("options.up = 'auto'", function()
    it("takes up from the frame's blocks seen with two faces, for those seen with one", function()
      local rng = geometry.rng(47)
      local flips_error, flips_auto = 0, 0
      for n = 1, 100 do
        local pitch, height = rad(rng.uniform(20, 40)), rng.uniform(0.06, 0.22)
        local cam_r, cam_c = robot_camera(pitch, height)
        -- a block seen with two faces, and a block further away, tipped, seen with one
        local _, _, tags1 = view(cam_r, cam_c, { 0.15, 0.05, 0.5 * BLOCK }, yaw(rad(45)),
          { rng = rng, sigma = 0.3, faces = { ["-x"] = true, ["+y"] = true } })
        local tipped = geometry.mul(yaw(rng.uniform(0, 6.3)),
          geometry.axis_angle(1, 0, 0, math.pi / 2))
        local r2, t2, tags2 = view(cam_r, cam_c, { rng.uniform(0.3, 0.5),
          rng.uniform(-0.1, 0.1), 0.5 * BLOCK }, tipped, { rng = rng, sigma = 0.5 })
        local all = { tags1[1], tags1[2], tags2[1] }
        local function flipped(blocks)
          for _, b in ipairs(blocks) do
            local p = b.position
            if sqrt((p.x - t2[1]) ^ 2 + (p.y - t2[2]) ^ 2 + (p.z - t2[3]) ^ 2) < 0.05 then
              return symmetric_error(r2, b.rotation) > 30
            end
          end
          return true
        end
        local plain, auto = solve(all), solve(all, { up = "auto" })
        assert.equal(2, #auto, "scene " .. n)
        if flipped(plain) then flips_error = flips_error + 1 end
        if flipped(auto) then flips_auto = flips_auto + 1 end
      end
      assert.is_true(flips_error >= 5, "flips by error " .. flips_error)
      assert.is_true(flips_auto <= 1,
        "flips with up auto " .. flips_auto .. ", by error " .. flips_error)
    end)

    it("is no up at all without a block seen with two faces", function()
      local rng = geometry.rng(48)
      for _ = 1, 20 do
        local _, _, tags = random_block(rng, 1, 0.5)
        local a, b = solve(tags)[1], solve(tags, { up = "auto" })[1]
        assert.same(a.position, b.position)
        assert.equal("error", b.orientation)
      end
    end)
  end)

  describe("options.floor", function()
    it("holds a resting block's centre at its level, which fixes a lone tag's depth", function()
      local rng = geometry.rng(43)
      local with_up, with_floor = {}, {}
      for n = 1, 60 do
        local pitch, height = rad(rng.uniform(20, 40)), rng.uniform(0.06, 0.22)
        local cam_r, cam_c, up = robot_camera(pitch, height)
        local stacked = rng.uniform() < 0.3
        local centre = { rng.uniform(0.15, 0.4), rng.uniform(-0.05, 0.05),
          (stacked and 1.5 or 0.5) * BLOCK }
        local r, t, tags = view(cam_r, cam_c, centre, yaw(rng.uniform(0, 6.3)),
          { rng = rng, sigma = 0.3 })
        local one = { tags[1] }
        local a = solve(one, { up = up })[1]
        local b = solve(one, { up = up, floor = height })[1]
        with_up[n] = sqrt((a.position.x - t[1]) ^ 2 + (a.position.y - t[2]) ^ 2
          + (a.position.z - t[3]) ^ 2)
        with_floor[n] = sqrt((b.position.x - t[1]) ^ 2 + (b.position.y - t[2]) ^ 2
          + (b.position.z - t[3]) ^ 2)
        assert.is_true(symmetric_error(r, b.rotation) < 10)
        -- its height above the floor is its level's
        local h = b.position.x * up[1] + b.position.y * up[2] + b.position.z * up[3] + height
        assert.near((stacked and 1.5 or 0.5) * BLOCK, h, 0.004)
      end
      table.sort(with_up)
      table.sort(with_floor)
      assert.is_true(with_floor[30] < 0.85 * with_up[30],
        ("median centre errors: %.3g with up, %.3g with the floor"):format(with_up[30],
          with_floor[30]))
    end)
  end)

  describe("options.floor = 'auto'", function()
    -- scenes of a robot's camera: two blocks on the floor seen with two faces each and a block
    -- seen with one (on the floor, or stacked on a hidden block); nothing tells the solver the
    -- camera's height
    local function scene(rng)
      local pitch, height = rad(rng.uniform(20, 40)), rng.uniform(0.06, 0.22)
      local cam_r, cam_c, up = robot_camera(pitch, height)
      local all, truth = {}, {}
      local places = { { 0.14, 0.07, 0.5 }, { 0.2, -0.08, 0.5 } }
      for k, c in ipairs(places) do
        local r, t, tags = view(cam_r, cam_c, { c[1], c[2], c[3] * BLOCK },
          yaw(rad(45 + rng.uniform(-8, 8))), { rng = rng, sigma = 0.3,
            faces = { ["-x"] = true, ["+y"] = true } })
        for _, tag in ipairs(tags) do all[#all + 1] = tag end
        truth[k] = { r = r, t = t }
      end
      local level = rng.uniform() < 0.3 and 1.5 or 0.5
      local r, t, tags = view(cam_r, cam_c, { rng.uniform(0.3, 0.45), rng.uniform(-0.1, 0.1),
        level * BLOCK }, yaw(rng.uniform(0, 6.3)), { rng = rng, sigma = 0.3 })
      all[#all + 1] = tags[1]
      truth[3] = { r = r, t = t, level = level }
      return all, truth, up, height
    end
    local function nearest(blocks, t)
      local best, bb = math.huge, nil
      for _, b in ipairs(blocks) do
        local p = b.position
        local d = sqrt((p.x - t[1]) ^ 2 + (p.y - t[2]) ^ 2 + (p.z - t[3]) ^ 2)
        if d < best then best, bb = d, b end
      end
      return best, bb
    end

    it("takes the floor from the blocks seen with two faces: a lone tag's depth improves",
      function()
        local rng = geometry.rng(61)
        local lone_up, lone_floor, pair_up, pair_floor = {}, {}, {}, {}
        for n = 1, 60 do
          local all, truth, _, height = scene(rng)
          local a = solve(all, { up = "auto" })
          local b = solve(all, { up = "auto", floor = "auto" })
          assert.equal(3, #b, "scene " .. n)
          lone_up[n] = nearest(a, truth[3].t)
          local d, lone = nearest(b, truth[3].t)
          lone_floor[n] = d
          assert.is_true(symmetric_error(truth[3].r, lone.rotation) < 30, "scene " .. n)
          pair_up[n] = nearest(a, truth[1].t)
          pair_floor[n] = nearest(b, truth[1].t)
          -- the lone block sits at its level above the floor the others show
          local up = b.up
          local p = lone.position
          assert.is_table(up, "scene " .. n)
          assert.near(truth[3].level * BLOCK, p.x * up.x + p.y * up.y + p.z * up.z + b.floor,
            0.003, "scene " .. n)
          assert.near(height, b.floor, 0.003, "scene " .. n)
        end
        table.sort(lone_up)
        table.sort(lone_floor)
        table.sort(pair_up)
        table.sort(pair_floor)
        assert.is_true(lone_floor[30] < 0.8 * lone_up[30],
          ("lone block, median centre error: %.3g with up auto, %.3g with the floor too")
            :format(lone_up[30], lone_floor[30]))
        -- each block seen with two faces gets the floor the other shows
        assert.is_true(pair_floor[30] < pair_up[30],
          ("two-face block, median centre error: %.3g with up auto, %.3g with the floor too")
            :format(pair_up[30], pair_floor[30]))
      end)

    it("is no floor at all without a block seen with two faces", function()
      local rng = geometry.rng(62)
      for _ = 1, 20 do
        local _, _, tags = random_block(rng, 1, 0.5)
        local a = solve(tags, { up = "auto" })
        local b = solve(tags, { up = "auto", floor = "auto" })
        assert.same(a[1].position, b[1].position)
        assert.is_nil(b.floor)
      end
    end)
  end)

  describe("grouping", function()
    it("keeps two touching cubes two blocks", function()
      local rng = geometry.rng(51)
      local cam_r, cam_c = robot_camera(rad(30), 0.12)
      for n = 1, 20 do
        local a = rng.uniform(0, 2 * math.pi)
        local ry = yaw(a)
        local c1 = { rng.uniform(0.15, 0.3), rng.uniform(-0.05, 0.05), 0.5 * BLOCK }
        -- the second touches the first along one of its side directions
        local sides = { { 1, 0, 0 }, { 0, 1, 0 }, { -1, 0, 0 }, { 0, -1, 0 } }
        local side = apply(ry, sides[n % 4 + 1])
        local c2 = { c1[1] + BLOCK * side[1], c1[2] + BLOCK * side[2], c1[3] }
        local r1, t1, tags1 = view(cam_r, cam_c, c1, ry, { rng = rng, sigma = 0.3 })
        local r2, t2, tags2 = view(cam_r, cam_c, c2, ry, { rng = rng, sigma = 0.3 })
        -- the touching faces hide each other
        local function visible(tags, t_other)
          local out = {}
          for _, tag in ipairs(tags) do
            local c = tag.corners
            local u = (c[1][1] + c[3][1]) / 2
            local v = (c[1][2] + c[3][2]) / 2
            local ou = camera.fx * t_other[1] / t_other[3] + camera.cx
            local ov = camera.fy * t_other[2] / t_other[3] + camera.cy
            if sqrt((u - ou) ^ 2 + (v - ov) ^ 2) > 3 then out[#out + 1] = tag end
          end
          return out
        end
        tags1, tags2 = visible(tags1, t2), visible(tags2, t1)
        local all = {}
        for _, tag in ipairs(tags1) do all[#all + 1] = tag end
        for _, tag in ipairs(tags2) do all[#all + 1] = tag end
        local blocks = assert(solve(all))
        assert.equal(2, #blocks, "scene " .. n)
        for _, truth in ipairs({ { r1, t1, #tags1 }, { r2, t2, #tags2 } }) do
          local found = false
          for _, b in ipairs(blocks) do
            local p = b.position
            local d = sqrt((p.x - truth[2][1]) ^ 2 + (p.y - truth[2][2]) ^ 2
              + (p.z - truth[2][3]) ^ 2)
            if d < 0.01 then
              found = true
              assert.equal(truth[3], b.faces, "scene " .. n)
              assert.is_true(symmetric_error(truth[1], b.rotation) < 5, "scene " .. n)
            end
          end
          assert.is_true(found, "scene " .. n)
        end
      end
    end)

    it("keeps a stack of two cubes two blocks", function()
      local cam_r, cam_c = robot_camera(rad(25), 0.2)
      local _, t1, tags1 = view(cam_r, cam_c, { 0.2, 0.01, 0.5 * BLOCK }, yaw(0.3))
      local _, t2, tags2 = view(cam_r, cam_c, { 0.2, 0.01, 1.5 * BLOCK }, yaw(0.35))
      -- the lower block's top face is covered
      local all = {}
      for _, tag in ipairs(tags1) do
        if tag.face ~= "+z" then all[#all + 1] = tag end
      end
      for _, tag in ipairs(tags2) do all[#all + 1] = tag end
      local blocks = assert(solve(all))
      assert.equal(2, #blocks)
      local lower = blocks[1].position.y > blocks[2].position.y and 1 or 2
      assert.vector_near(t1, blocks[lower].position, 1e-9)
      assert.vector_near(t2, blocks[3 - lower].position, 1e-9)
    end)

    it("groups a tag whose own pose flipped with its block", function()
      -- with noise, find scenes where a tag's best single pose is the flipped one
      local rng = geometry.rng(61)
      local seen = 0
      for n = 1, 120 do
        local r, t, tags = random_block(rng, 2, 0.5)
        for _, tag in ipairs(tags) do
          local own = solve({ tag })[1]
          if symmetric_error(r, own.rotation) > 30 then seen = seen + 1 end
        end
        local blocks = solve(tags)
        assert.equal(1, #blocks, "scene " .. n)
        assert.equal(2, blocks[1].faces, "scene " .. n)
        assert.is_true(symmetric_error(r, blocks[1].rotation) < 10, "scene " .. n)
        assert.vector_near(t, blocks[1].position, 0.015, "scene " .. n)
      end
      assert.is_true(seen >= 3, "flipped tags seen " .. seen)
    end)
  end)

  describe("canonical orientation", function()
    it("puts block z along up and x away from the camera", function()
      local rng = geometry.rng(71)
      for _ = 1, 30 do
        local r, _, tags, up = random_block(rng, 2)
        for _, options in ipairs({ {}, { up = up } }) do
          local b = solve(tags, options)[1]
          local rt = assertions.flat(b.rotation)
          local u = options.up or { 0, -1, 0 }
          local z = { rt[3], rt[6], rt[9] }
          local x = { rt[1], rt[4], rt[7] }
          -- z is the face axis nearest up: here up itself (the block rests on its bottom face)
          local cz = (z[1] * u[1] + z[2] * u[2] + z[3] * u[3])
            / sqrt(u[1] ^ 2 + u[2] ^ 2 + u[3] ^ 2)
          assert.is_true(cz > 0.7)
          if options.up then assert.near(1, cz, 1e-9) end
          local p = b.position
          local ahead = (x[1] * p.x + x[2] * p.y + x[3] * p.z)
          local other = abs(rt[2] * p.x + rt[5] * p.y + rt[8] * p.z)
          assert.is_true(ahead >= other)
          assert.is_true(symmetric_error(r, b.rotation) < 1e-6)
          -- and the raw frame is the same block
          assert.is_true(symmetric_error(r, b.raw_rotation) < 1e-6)
        end
      end
    end)

    it("is absolute when options.faces tells the faces apart", function()
      local cam_r, cam_c = robot_camera(rad(30), 0.15)
      local tipped = geometry.mul(yaw(0.7), geometry.axis_angle(1, 0, 0, math.pi / 2))
      local r, t, tags = view(cam_r, cam_c, { 0.22, -0.02, 0.5 * BLOCK }, tipped)
      local faces, ids = {}, { ["+x"] = 1, ["-x"] = 2, ["+y"] = 3, ["-y"] = 4, ["+z"] = 5,
        ["-z"] = 6 }
      for name, id in pairs(ids) do faces[id] = name end
      for _, tag in ipairs(tags) do tag.id = ids[tag.face] end
      local b = solve(tags, { faces = faces })[1]
      assert.rotation_near(r, b.rotation, 1e-6)
      assert.vector_near(t, b.position, 1e-9)
      for m, i in ipairs(b.tags) do assert.equal(tags[i].face, b.tag_faces[m]) end
      -- a tag whose id is on no face is skipped, and said so
      tags[#tags + 1] = { id = 99, corners = tags[1].corners }
      local blocks = solve(tags, { faces = faces })
      assert.equal(1, #blocks)
      assert.equal(#tags, blocks.skipped[1].index)
      assert.matches("id 99", blocks.skipped[1].reason)
    end)
  end)

  describe("tracking with options.previous", function()
    it("keeps each block's id and frame as the scene moves", function()
      local rng = geometry.rng(81)
      local cam_r, cam_c = robot_camera(rad(30), 0.12)
      local previous
      local ids
      for k = 0, 30 do
        -- two blocks turning slowly, one yawing through 45 degrees (where the canonical x
        -- would jump between two faces)
        local all = {}
        local r1 = yaw(rad(30 + 1.0 * k))
        local r2 = yaw(rad(-60 + 0.5 * k))
        local _, t1, tags1 = view(cam_r, cam_c, { 0.2 + 0.002 * k, 0.06, 0.5 * BLOCK }, r1,
          { rng = rng, sigma = 0.2 })
        local _, _, tags2 = view(cam_r, cam_c, { 0.25, -0.08, 0.5 * BLOCK }, r2,
          { rng = rng, sigma = 0.2 })
        for _, tag in ipairs(tags1) do all[#all + 1] = tag end
        for _, tag in ipairs(tags2) do all[#all + 1] = tag end
        local blocks = assert(solve(all, { previous = previous }))
        assert.equal(2, #blocks)
        local now = {}
        for _, b in ipairs(blocks) do
          local near1 = sqrt((b.position.x - t1[1]) ^ 2 + (b.position.y - t1[2]) ^ 2
            + (b.position.z - t1[3]) ^ 2) < 0.01
          now[near1 and 1 or 2] = b
        end
        assert.is_table(now[1])
        assert.is_table(now[2])
        if ids then
          assert.equal(ids[1], now[1].id)
          assert.equal(ids[2], now[2].id)
          -- the frame turned by the block's own motion only (a degree or less), not by 90
          for j = 1, 2 do
            local before
            for _, b in ipairs(previous) do
              if b.id == ids[j] then before = b end
            end
            assert.rotation_near(before.rotation, now[j].rotation, 3, "frame " .. k)
          end
        else
          ids = { now[1].id, now[2].id }
          assert.are_not.equal(ids[1], ids[2])
        end
        previous = blocks
      end
    end)

    it("carries the evidence on the corner noise from frame to frame", function()
      local rng = geometry.rng(83)
      local _, _, tags = random_block(rng, 2, 0.3)
      local first = solve(tags)
      assert.equal(4, first.noise.dof)
      local s1 = first.noise.sse
      assert.is_true(s1 > 0)
      local second = solve(tags, { previous = first })
      assert.near(4 + 0.8 * 4, second.noise.dof, 1e-12)
      assert.near(s1 + 0.8 * s1, second.noise.sse, 1e-12)
    end)

    it("gives a new block a new id", function()
      local cam_r, cam_c = robot_camera(rad(30), 0.12)
      local _, _, tags1 = view(cam_r, cam_c, { 0.2, 0.05, 0.5 * BLOCK }, yaw(0.2))
      local _, _, tags2 = view(cam_r, cam_c, { 0.3, -0.1, 0.5 * BLOCK }, yaw(0.9))
      local first = solve(tags1)
      assert.equal(1, first[1].id)
      local all = {}
      for _, tag in ipairs(tags1) do all[#all + 1] = tag end
      for _, tag in ipairs(tags2) do all[#all + 1] = tag end
      local second = solve(all, { previous = first })
      assert.equal(2, #second)
      assert.equal(1, second[1].id)
      assert.equal(2, second[2].id)
      -- an id is not reused after its block left the view
      local third = solve(tags2, { previous = { second[1], next_id = second.next_id } })
      assert.equal(3, third[1].id)
    end)

    it("keeps a one-face block's decided orientation where the error alone would flip", function()
      local rng = geometry.rng(91)
      local flips_alone, flips_tracked = 0, 0
      for _ = 1, 80 do
        local r, _, tags, up = random_block(rng, 1, 0.5)
        -- the previous frame decided the orientation (with up); this frame has no up
        local previous = solve(tags, { up = up })
        local noisy = {}
        for i, c in ipairs(tags[1].corners) do
          noisy[i] = { c[1] + 0.5 * rng.normal(), c[2] + 0.5 * rng.normal() }
        end
        local det = { { id = 0, corners = noisy } }
        local alone = tagpose.block.solve(det, camera, TAG, BLOCK)[1]
        local tracked = tagpose.block.solve(det, camera, TAG, BLOCK, { previous = previous })[1]
        if symmetric_error(r, alone.rotation) > 30 then flips_alone = flips_alone + 1 end
        if symmetric_error(r, tracked.rotation) > 30 then flips_tracked = flips_tracked + 1 end
      end
      assert.is_true(flips_alone >= 5, "flips alone " .. flips_alone)
      assert.is_true(flips_tracked <= 1, "flips tracked " .. flips_tracked)
    end)
  end)
end)
