-- tagpose.block, from geometry: cubes placed in front of a robot's camera, their faces' tags
-- projected, the block poses recovered.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local gauss = require("support.gauss")

local sqrt, sin, cos, rad, abs = math.sqrt, math.sin, math.cos, math.rad, math.abs

local camera = { fx = 313.9, fy = 312.1, cx = 161.2, cy = 118.4, width = 320, height = 240 }
local TAG, BLOCK = 0.024, 0.055

local FACES = require("support.faces").FACES

-- the cube's 24 rotations: signed permutation matrices with determinant +1
local SYMMETRIES = {}
local PERMUTATIONS = { { 1, 2, 3 }, { 2, 3, 1 }, { 3, 1, 2 }, { 1, 3, 2 }, { 3, 2, 1 },
  { 2, 1, 3 } }
for _, p in ipairs(PERMUTATIONS) do
  for s = 0, 7 do
    local signs = { s % 2 == 0 and 1 or -1, s % 4 < 2 and 1 or -1, s < 4 and 1 or -1 }
    local g = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }
    for row = 1, 3 do g[(row - 1) * 3 + p[row]] = signs[row] end
    local det = g[1] * (g[5] * g[9] - g[6] * g[8]) - g[2] * (g[4] * g[9] - g[6] * g[7])
      + g[3] * (g[4] * g[8] - g[5] * g[7])
    if det > 0 then SYMMETRIES[#SYMMETRIES + 1] = g end
  end
end

local function apply(r, v)
  return { r[1] * v[1] + r[2] * v[2] + r[3] * v[3], r[4] * v[1] + r[5] * v[2] + r[6] * v[3],
    r[7] * v[1] + r[8] * v[2] + r[9] * v[3] }
end

-- rotation error in degrees, the least over the cube's symmetries
local function symmetric_error(truth, got)
  local best = math.huge
  for _, g in ipairs(SYMMETRIES) do
    local e = assertions.rotation_angle(geometry.mul(truth, g), got)
    if e < best then best = e end
  end
  return best
end

-- The robot's camera: looking forward (world x) and down by `pitch` from `height` above the
-- floor (world z up). Returns world → camera rotation, the camera centre, and up in the camera.
local function robot_camera(pitch, height)
  local c, s = cos(pitch), sin(pitch)
  -- rows: camera x (right = world -y), camera y (down), camera z (forward)
  local r = { 0, -1, 0, -s, 0, -c, c, 0, -s }
  return r, { 0, 0, height }, { r[3], r[6], r[9] }
end

-- A block in the world: centre (world), rotation block → world. Its pose in the camera and the
-- tags of the faces that face the camera (or of the faces named), projected.
local function view(cam_r, cam_c, centre, r_world, opts)
  opts = opts or {}
  local r = geometry.mul(cam_r, r_world)
  local t = apply(cam_r, { centre[1] - cam_c[1], centre[2] - cam_c[2], centre[3] - cam_c[3] })
  local tags = {}
  for _, f in ipairs(FACES) do
    local n = apply(r, f.n)
    local tt = { t[1] + 0.5 * BLOCK * n[1], t[2] + 0.5 * BLOCK * n[2], t[3] + 0.5 * BLOCK * n[3] }
    local d = sqrt(tt[1] ^ 2 + tt[2] ^ 2 + tt[3] ^ 2)
    local facing = (n[1] * tt[1] + n[2] * tt[2] + n[3] * tt[3]) / d
    local wanted = opts.faces and opts.faces[f.name] or (not opts.faces and facing < -0.15)
    if wanted then
      local corners = geometry.project(camera, geometry.mul(r, f.r), tt, TAG)
      if opts.rng and opts.sigma then
        for _, c in ipairs(corners) do
          c[1] = c[1] + opts.sigma * opts.rng.normal()
          c[2] = c[2] + opts.sigma * opts.rng.normal()
        end
      end
      tags[#tags + 1] = { id = opts.id or 0, corners = corners, face = f.name }
    end
  end
  return r, t, tags
end

local function yaw(a)
  return geometry.axis_angle(0, 0, 1, a)
end

-- a random scene: one block on the floor, `k` faces in view
local function random_block(rng, k, sigma)
  for _ = 1, 1000 do
    local pitch, height = rad(rng.uniform(20, 40)), rng.uniform(0.06, 0.22)
    local cam_r, cam_c, up = robot_camera(pitch, height)
    local range = rng.uniform(0.1, 0.45)
    local az = rng.uniform(-0.4, 0.4)
    local centre = { range * cos(az), range * sin(az), 0.5 * BLOCK }
    local r_world = yaw(rng.uniform(0, 2 * math.pi))
    local r, t, tags = view(cam_r, cam_c, centre, r_world, { rng = rng, sigma = sigma })
    local inside = t[3] > 0.05
    for _, tag in ipairs(tags) do
      for _, c in ipairs(tag.corners) do
        if c[1] < 0 or c[1] > camera.width or c[2] < 0 or c[2] > camera.height then
          inside = false
        end
      end
    end
    if inside and #tags == k then return r, t, tags, up end
  end
  error("no scene with " .. k .. " faces")
end

local function detections_of(tags)
  local out = {}
  for i, tag in ipairs(tags) do out[i] = { id = tag.id, corners = tag.corners } end
  return out
end

local function solve(tags, options)
  return tagpose.block.solve(detections_of(tags), camera, TAG, BLOCK, options)
end

describe("tagpose.block", function()
  describe("solve() on exact corners", function()
    for k = 1, 3 do
      it("recovers a block seen with " .. k .. " face(s) to round-off", function()
        local rng = geometry.rng(100 + k)
        for n = 1, 30 do
          local r, t, tags = random_block(rng, k)
          local blocks = assert(solve(tags))
          assert.equal(1, #blocks, "scene " .. n)
          local b = blocks[1]
          assert.vector_near(t, b.position, 1e-9, "scene " .. n)
          assert.is_true(symmetric_error(r, b.rotation) < 1e-6, "scene " .. n)
          assert.equal(k, b.faces)
          assert.is_true(b.error < 1e-6)
          local used = {}
          for _, i in ipairs(b.tags) do used[i] = true end
          for i = 1, k do assert.is_true(used[i]) end
        end
      end)
    end

    it("names each tag's face in the returned frame", function()
      local rng = geometry.rng(7)
      for _ = 1, 20 do
        local _, _, tags = random_block(rng, 3)
        local b = solve(tags)[1]
        local r = assertions.flat(b.rotation)
        for m, i in ipairs(b.tags) do
          -- the face's outward normal, in the camera, points from the centre to the tag
          local normal
          for _, f in ipairs(FACES) do
            if f.name == b.tag_faces[m] then normal = apply(r, f.n) end
          end
          local c = tags[i].corners
          local u = (c[1][1] + c[2][1] + c[3][1] + c[4][1]) / 4
          local v = (c[1][2] + c[2][2] + c[3][2] + c[4][2]) / 4
          local p = b.position
          local z = p.z + 0.5 * BLOCK * normal[3]
          local pu = camera.fx * (p.x + 0.5 * BLOCK * normal[1]) / z + camera.cx
          local pv = camera.fy * (p.y + 0.5 * BLOCK * normal[2]) / z + camera.cy
          -- the projected face centre is the tag's centre (to perspective's small offset)
          assert.is_true(sqrt((pu - u) ^ 2 + (pv - v) ^ 2) < 2, b.tag_faces[m])
        end
      end
    end)

    it("gives a block through a distorting lens", function()
      local lens = { fx = 300, fy = 300, cx = 160, cy = 120,
        distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4 } }
      local saved = camera
      camera = lens
      local cam_r, cam_c = robot_camera(rad(30), 0.15)
      local r, t, tags = view(cam_r, cam_c, { 0.25, 0.03, 0.5 * BLOCK }, yaw(0.5))
      camera = saved
      local blocks = tagpose.block.solve(detections_of(tags), lens, TAG, BLOCK)
      assert.equal(1, #blocks)
      assert.equal(#tags, blocks[1].faces)
      assert.is_true(#tags >= 2)
      assert.vector_near(t, blocks[1].position, 1e-9)
      assert.is_true(symmetric_error(r, blocks[1].rotation) < 1e-6)
    end)
  end)

  describe("solve() with noise (0.3 px)", function()
    for k = 2, 3 do
      it("recovers blocks seen with " .. k .. " faces, with no flip", function()
        local rng = geometry.rng(200 + k)
        local errors = {}
        for n = 1, 40 do
          local r, t, tags = random_block(rng, k, 0.3)
          local blocks = assert(solve(tags))
          assert.equal(1, #blocks, "scene " .. n)
          assert.equal(k, blocks[1].faces, "scene " .. n)
          local p = blocks[1].position
          errors[n] = sqrt((p.x - t[1]) ^ 2 + (p.y - t[2]) ^ 2 + (p.z - t[3]) ^ 2)
          assert.is_true(symmetric_error(r, blocks[1].rotation) < 5, "scene " .. n)
        end
        table.sort(errors)
        assert.is_true(errors[20] < 0.0015, "median centre error " .. errors[20])
        assert.is_true(errors[40] < 0.01, "largest centre error " .. errors[40])
      end)
    end

    it("is closer to the truth with two faces than any of its tags alone", function()
      local rng = geometry.rng(31)
      local joint, single = 0, 0
      for _ = 1, 40 do
        local _, t, tags = random_block(rng, 2, 0.3)
        local b = solve(tags)[1]
        joint = joint + (b.position.x - t[1]) ^ 2 + (b.position.y - t[2]) ^ 2
          + (b.position.z - t[3]) ^ 2
        for _, tag in ipairs(tags) do
          local one = solve({ tag })[1]
          single = single + 0.5 * ((one.position.x - t[1]) ^ 2 + (one.position.y - t[2]) ^ 2
            + (one.position.z - t[3]) ^ 2)
        end
      end
      assert.is_true(joint < 0.5 * single, ("joint %.3g, single %.3g"):format(joint, single))
    end)

    it("chooses a one-face block's pose with options.up, where the error alone flips", function()
      local rng = geometry.rng(41)
      local flips_error, flips_up, alternatives = 0, 0, 0
      for _ = 1, 100 do
        local r, _, tags, up = random_block(rng, 1, 0.5)
        local plain = solve(tags)[1]
        local with_up = solve(tags, { up = up })[1]
        if symmetric_error(r, plain.rotation) > 30 then flips_error = flips_error + 1 end
        if symmetric_error(r, with_up.rotation) > 30 then flips_up = flips_up + 1 end
        if plain.alternative then alternatives = alternatives + 1 end
        assert.equal("error", plain.orientation)
        assert.equal("up", with_up.orientation)
      end
      assert.is_true(flips_error >= 5, "flips by error " .. flips_error)
      assert.is_true(flips_up <= 1, "flips with up " .. flips_up)
      assert.is_true(alternatives > 50, "alternatives " .. alternatives)
    end)
  end)

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

  describe("unusable input", function()
    it("returns an empty array for no detections", function()
      local blocks = assert(tagpose.block.solve({}, camera, TAG, BLOCK))
      assert.equal(0, #blocks)
      assert.same({}, blocks.skipped)
    end)

    it("skips a detection that gives no pose, and says why", function()
      local rng = geometry.rng(5)
      local _, t, tags = random_block(rng, 2)
      local bad = { { 10, 10 }, { 20, 20 }, { 30, 30 }, { 40, 40 } }
      local nan = { { 0 / 0, 1 }, { 20, 20 }, { 30, 10 }, { 10, 10 } }
      local dets = detections_of(tags)
      table.insert(dets, 1, { id = 0, corners = bad })
      dets[#dets + 1] = { id = 0, corners = nan }
      local blocks = assert(tagpose.block.solve(dets, camera, TAG, BLOCK))
      assert.equal(1, #blocks)
      assert.vector_near(t, blocks[1].position, 1e-9)
      assert.same({ 2, 3 }, (function()
        local s = { blocks[1].tags[1], blocks[1].tags[2] }
        table.sort(s)
        return s
      end)())
      assert.equal(2, #blocks.skipped)
      assert.equal(1, blocks.skipped[1].index)
      assert.matches("collinear", blocks.skipped[1].reason)
      assert.equal(#dets, blocks.skipped[2].index)
      assert.matches("not finite", blocks.skipped[2].reason)
    end)

    it("reports a tag detected twice once, and the copy as skipped", function()
      local rng = geometry.rng(8)
      for k = 1, 3 do
        local _, t, tags = random_block(rng, k)
        local dets = detections_of(tags)
        local copy = {}
        for i, c in ipairs(tags[1].corners) do copy[i] = { c[1] + 0.2, c[2] - 0.1 } end
        dets[#dets + 1] = { id = 0, corners = copy }
        local blocks = assert(tagpose.block.solve(dets, camera, TAG, BLOCK))
        assert.equal(1, #blocks)
        assert.equal(k, blocks[1].faces)
        assert.vector_near(t, blocks[1].position, 0.002)
        assert.equal(1, #blocks.skipped)
        assert.matches("does not fit the block", blocks.skipped[1].reason)
      end
    end)

    it("skips a malformed detection (a detector's glitch), and says why", function()
      local rng = geometry.rng(10)
      local _, t, tags = random_block(rng, 2)
      local dets = detections_of(tags)
      table.insert(dets, 1, 5)
      dets[#dets + 1] = { id = 0 }
      dets[#dets + 1] = { id = 0, corners = { { 1, 2 }, { 3, 4 }, { 5, "6" }, { 7, 8 } } }
      local blocks = assert(tagpose.block.solve(dets, camera, TAG, BLOCK))
      assert.equal(1, #blocks)
      assert.vector_near(t, blocks[1].position, 1e-9)
      assert.same({
        { index = 1, reason = "block: table {id =, corners =} expected, got number" },
        { index = 4, reason = "block: corners: table of four corners expected, got nil" },
        { index = 5, reason = "block: corner 3: numbers {u, v} or {x =, y =} expected, "
          .. "got number 5 and string 6" },
      }, blocks.skipped)
      local none, err = tagpose.block.solve({ { id = 0, corners = { { 1, 2 } } } }, camera, TAG,
        BLOCK)
      assert.is_nil(none)
      assert.equal("block: no detection gives a tag pose (detection 1: block: corners: four "
        .. "corners expected, got 1)", err)
    end)

    it("returns nil and a message when no detection gives a pose", function()
      local blocks, err = tagpose.block.solve({ { id = 0, corners = { { 1, 1 }, { 2, 2 },
        { 3, 3 }, { 4, 4 } } } }, camera, TAG, BLOCK)
      assert.is_nil(blocks)
      assert.matches("^block: no detection gives a tag pose %(detection 1: .*collinear", err)
    end)

    it("never returns NaN for random quadrilaterals", function()
      local rng = geometry.rng(9)
      for _ = 1, 200 do
        local dets = {}
        for i = 1, 1 + math.floor(rng.uniform() * 5) do
          local c = {}
          for k = 1, 4 do c[k] = { rng.uniform(-50, 370), rng.uniform(-50, 290) } end
          dets[i] = { id = 0, corners = c }
        end
        local blocks = tagpose.block.solve(dets, camera, TAG, BLOCK)
        for _, b in ipairs(blocks or {}) do
          local p, q = b.position, b.quaternion
          for _, v in ipairs({ p.x, p.y, p.z, q.w, q.x, q.y, q.z, b.error }) do
            assert.is_true(v == v and abs(v) < math.huge)
          end
        end
      end
    end)
  end)

  describe("misuse", function()
    local good = { { id = 0, corners = { { 100, 100 }, { 120, 100 }, { 120, 80 }, { 100, 80 } } } }
    local function raised(f)
      return assertions.raised(f, "block_spec.lua")
    end
    local cases = {
      { function() tagpose.block.solve(nil, camera, TAG, BLOCK) end,
        "bad argument #1 to 'solve' (array of detections expected, got nil)" },
      { function() tagpose.block.solve(good, { fx = 1 }, TAG, BLOCK) end,
        "bad argument #2 to 'solve' (camera.fy: positive number expected, got nil)" },
      { function() tagpose.block.solve(good, camera, -1, BLOCK) end,
        "bad argument #3 to 'solve' (positive number expected for tag_size, got number -1)" },
      { function() tagpose.block.solve(good, camera, TAG, 0) end,
        "bad argument #4 to 'solve' (positive number expected for block_size, got number 0)" },
      { function() tagpose.block.solve(good, camera, 0.06, 0.055) end,
        "bad argument #4 to 'solve' (block_size must exceed tag_size, got 0.055 <= 0.06)" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, 3) end,
        "bad argument #5 to 'solve' (options table expected, got number)" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { up = { 0, 0, 0 } }) end,
        "bad argument #5 to 'solve' (options.up: non-zero vector expected (or 'auto'))" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { floor = 0.1 }) end,
        "bad argument #5 to 'solve' (options.floor: needs options.up (a vector))" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { floor = "auto" }) end,
        "bad argument #5 to 'solve' (options.floor: 'auto' needs options.up (a vector or "
          .. "'auto'))" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { floor = "high" }) end,
        "bad argument #5 to 'solve' (options.floor: finite number (or 'auto') expected, got "
          .. "string high)" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { faces = { [1] = "top" } }) end,
        "bad argument #5 to 'solve' (options.faces[1]: face '+x', '-x', '+y', '-y', '+z' or "
          .. "'-z' expected, got string top)" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK,
        { previous = { noise = { sse = -1, dof = 2 } } }) end,
        "bad argument #5 to 'solve' (options.previous.noise: {sse =, dof =} (finite, >= 0) "
          .. "expected)" },
      { function() tagpose.block.solve(good, camera, TAG, BLOCK, { previous = { {} } }) end,
        "bad argument #5 to 'solve' (options.previous[1]: block with a finite position "
          .. "expected)" },
    }
    for i, case in ipairs(cases) do
      it(case[2], function()
        assert.equal(case[2], raised(case[1]), "case " .. i)
      end)
    end
  end)

  describe("uncertainty", function()
    -- the truth aligned with the returned frame (the cube's symmetry nearest it): the error
    -- (t_true - t, r) in the covariance's order
    local function block_error(b, r, t)
      local best, best_e = nil, math.huge
      for _, g in ipairs(SYMMETRIES) do
        local rg = geometry.mul(r, g)
        local e = assertions.rotation_angle(rg, b.rotation)
        if e < best_e then best, best_e = rg, e end
      end
      return gauss.error_of(b, best, t)
    end

    local function renoise(tags, rng, sigma)
      local out = {}
      for i, tag in ipairs(tags) do
        local corners = {}
        for k, c in ipairs(tag.corners) do
          corners[k] = { c[1] + sigma * rng.normal(), c[2] + sigma * rng.normal() }
        end
        out[i] = { id = tag.id, corners = corners }
      end
      return out
    end

    it("covers a two-face block's pose as it claims (Monte-Carlo, 6 dof)", function()
      local rng = geometry.rng(61)
      local r, t, tags = random_block(rng, 2)
      local sigma, n, inside, sum = 0.3, 300, 0, 0
      for _ = 1, n do
        local b = tagpose.block.solve(renoise(tags, rng, sigma), camera, TAG, BLOCK,
          { sigma = sigma })[1]
        assert.equal(2, b.faces)
        assert.equal(1, b.confidence)
        assert.is_true(gauss.is_spd(b.covariance))
        local m2 = gauss.mahalanobis(b.covariance, block_error(b, r, t))
        sum = sum + m2
        if m2 < 12.59 then inside = inside + 1 end
      end
      local mean, share = sum / n, inside / n
      assert.is_true(abs(mean - 6) < 4 * sqrt(12 / n), ("mean Mahalanobis² %.2f"):format(mean))
      assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n), ("coverage %.3f"):format(share))
    end)

    -- Without options.sigma a frame with a block of two faces (10 residual degrees of freedom)
    -- is judged by its own residuals, whatever σ they show, its covariance widened for σ² being
    -- an estimate (Student's F): it covers as claimed at a σ well below and above the default.
    for _, sigma in ipairs({ 0.15, 1 }) do
      it("covers a two-face block's pose as it claims without sigma (σ " .. sigma .. " px)",
        function()
          local rng = geometry.rng(65)
          local r, t, tags = random_block(rng, 2)
          local n, inside = 500, 0
          for _ = 1, n do
            local b = tagpose.block.solve(renoise(tags, rng, sigma), camera, TAG, BLOCK)[1]
            assert.equal(2, b.faces)
            if gauss.mahalanobis(b.covariance, block_error(b, r, t)) < 12.59 then
              inside = inside + 1
            end
          end
          local share = inside / n
          assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n),
            ("coverage %.3f"):format(share))
        end)
    end

    it("covers one-face blocks' centres on their true branch, with the tag's confidence",
      function()
        local rng = geometry.rng(62)
        local sigma, n, inside = 0.3, 300, 0
        for _ = 1, n do
          local r, t, tags = random_block(rng, 1, sigma)
          local b = solve(tags, { sigma = sigma })[1]
          local tag = assert(tagpose.solve(tags[1].corners, camera, TAG, { sigma = sigma }))
          -- the tag's branch probability, and its rotation covariance (the centre moves, the
          -- rotation does not)
          assert.near(tag.confidence, b.confidence, 1e-9)
          for i = 4, 6 do
            for j = 4, 6 do
              assert.near(tag.covariance[i][j], b.covariance[i][j],
                1e-9 * abs(tag.covariance[i][i]))
            end
          end
          local a = b.alternative
          if a then assert.near(1, b.confidence + a.confidence, 1e-12) end
          local e = block_error(b, r, t)
          if a then
            local ea = block_error(a, r, t)
            if ea[4] ^ 2 + ea[5] ^ 2 + ea[6] ^ 2 < e[4] ^ 2 + e[5] ^ 2 + e[6] ^ 2 then
              b, e = a, ea
            end
          end
          assert.is_true(gauss.is_spd(b.covariance))
          if gauss.mahalanobis(b.covariance, { e[1], e[2], e[3] }) < 7.81 then
            inside = inside + 1
          end
        end
        local share = inside / n
        assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n), ("coverage %.3f"):format(share))
      end)

    it("with up, weighs both fits: the tilt is tighter, the confidences complementary",
      function()
        local rng = geometry.rng(63)
        local tighter, n = 0, 40
        for _ = 1, n do
          local _, _, tags, up = random_block(rng, 1, 0.3)
          local plain = solve(tags, { sigma = 0.3 })[1]
          local with_up = solve(tags, { sigma = 0.3, up = up })[1]
          assert.is_true(gauss.is_spd(with_up.covariance))
          local c = with_up.covariance
          local p = plain.covariance
          if c[4][4] + c[5][5] + c[6][6] < p[4][4] + p[5][5] + p[6][6] then
            tighter = tighter + 1
          end
          local a = with_up.alternative
          assert.is_true(with_up.confidence >= 0 and with_up.confidence <= 1)
          if a then assert.near(1, with_up.confidence + a.confidence, 1e-12) end
        end
        assert.equal(n, tighter)
      end)

    it("refuses a sigma that is not a positive number", function()
      local _, _, tags = random_block(geometry.rng(64), 1)
      assert.equal("bad argument #5 to 'solve' (options.sigma: positive number expected, got "
        .. "number 0)", assertions.raised(function()
          tagpose.block.solve(detections_of(tags), camera, TAG, BLOCK, { sigma = 0 })
        end,
        "block_spec.lua"))
    end)
  end)
end)
