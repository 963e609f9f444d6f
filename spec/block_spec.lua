-- tagpose.block, from geometry: cubes placed in front of a robot's camera, their faces' tags
-- projected, the block poses recovered (the scenes: spec/support/blocks.lua).
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local gauss = require("support.gauss")
local blocks_support = require("support.blocks")

local sqrt, rad, abs = math.sqrt, math.rad, math.abs

local camera, TAG, BLOCK = blocks_support.camera, blocks_support.TAG, blocks_support.BLOCK
local FACES, SYMMETRIES = blocks_support.FACES, blocks_support.SYMMETRIES
local apply, symmetric_error = blocks_support.apply, blocks_support.symmetric_error
local robot_camera, view, yaw = blocks_support.robot_camera, blocks_support.view,
  blocks_support.yaw
local random_block, detections_of = blocks_support.random_block, blocks_support.detections_of
local solve = blocks_support.solve

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
      local cam_r, cam_c = robot_camera(rad(30), 0.15)
      local r, t, tags = view(cam_r, cam_c, { 0.25, 0.03, 0.5 * BLOCK }, yaw(0.5),
        { camera = lens })
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
