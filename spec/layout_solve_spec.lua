-- tagpose.layout.solve, from geometry: glued cubes and boards posed in front of a camera, their
-- tags' corners projected, the body's pose recovered.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local assertions = require("support.assertions")
local gauss = require("support.gauss")

local sqrt, rad, abs = math.sqrt, math.rad, math.abs

local CAMERAS = {
  pinhole = { fx = 307.2, fy = 305.7, cx = 157.1, cy = 117.9 },
  brown = { fx = 600, fy = 590, cx = 321.5, cy = 238.5,
    distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4 } },
  fisheye = { fx = 400, fy = 400, cx = 320, cy = 240, model = "fisheye",
    distortion = { k1 = 0.05, k2 = -0.01 } },
}

-- a random body pose 0.2-0.5 m ahead with the body's centre near the optical axis
local function random_pose(rng)
  local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), rng.uniform(0, math.pi))
  return r, { rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(0.2, 0.5) }
end

local function board(size, spacing)
  -- a 2×2 board in the body's z = 0 plane, tag z along body z
  local tags = {}
  local id = 10
  for i = 0, 1 do
    for j = 0, 1 do
      tags[id] = { size = size, position = { x = (i - 0.5) * spacing, y = (j - 0.5) * spacing,
        z = 0 }, quaternion = { w = 1, x = 0, y = 0, z = 0 } }
      id = id + 1
    end
  end
  return { tags = tags }
end

describe("tagpose.layout", function()
  describe("solve()", function()
    for name, camera in pairs(CAMERAS) do
      it("returns the pose of projected exact corners to round-off (" .. name .. ")", function()
        local rng = geometry.rng(7)
        local _, glued = layouts.cube(rng, 0.0229, 0.0548, 2, 3, 0.5)
        local solved = 0
        for trial = 1, 60 do
          local r, t = random_pose(rng)
          local dets = layouts.detections(glued, camera, r, t, rng, 0)
          if #dets > 0 then
            local body = assert(tagpose.layout.solve(dets, camera, glued))
            -- with one tag (or a view where a second minimum exists) the truth is a branch
            local best = body
            if body.alternative and assertions.rotation_angle(r, body.alternative.rotation)
              < assertions.rotation_angle(r, body.rotation) then
              best = body.alternative
            end
            local msg = "seed 7, trial " .. trial .. ", " .. #dets .. " tags"
            assert.vector_near(t, best.position, 1e-9, msg)
            assert.rotation_near(r, best.rotation, 1e-7, msg)
            assert.is_true(best.error < 1e-7, msg)
            if #dets > 1 then assert.is_nil(body.alternative, msg) end
            solved = solved + 1
          end
        end
        assert.is_true(solved > 40)
      end)
    end

    it("fits all the corners jointly: with two tags it beats each tag alone", function()
      local rng = geometry.rng(3)
      local camera = CAMERAS.pinhole
      local _, glued = layouts.cube(rng, 0.0229, 0.0548, 2, 3, 0.5)
      local joint, single, n = 0, 0, 0
      while n < 200 do
        local r, t = random_pose(rng)
        local dets = layouts.detections(glued, camera, r, t, rng, 0.3)
        if #dets >= 2 then
          n = n + 1
          local body = assert(tagpose.layout.solve(dets, camera, glued))
          joint = joint + (body.position.x - t[1]) ^ 2 + (body.position.y - t[2]) ^ 2
            + (body.position.z - t[3]) ^ 2
          local one = assert(tagpose.layout.solve({ dets[1] }, camera, glued))
          single = single + (one.position.x - t[1]) ^ 2 + (one.position.y - t[2]) ^ 2
            + (one.position.z - t[3]) ^ 2
        end
      end
      assert.is_true(sqrt(joint / n) < 0.5 * sqrt(single / n),
        ("joint rms %.3g m, single %.3g m"):format(sqrt(joint / n), sqrt(single / n)))
    end)

    it("skips unknown ids and malformed detections, and lists them with a reason", function()
      local rng = geometry.rng(5)
      local camera = CAMERAS.pinhole
      local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
      local r = geometry.axis_angle(1, 1, 0.3, rad(130))
      local t = { 0, 0, 0.3 }
      local dets = layouts.detections(nominal, camera, r, t, rng, 0)
      assert.is_true(#dets >= 2)
      local n = #dets
      dets[#dets + 1] = { id = 42, corners = dets[1].corners }
      dets[#dets + 1] = { id = 0, corners = { { 1, 2 }, { 3, 4 } } }
      dets[#dets + 1] = { id = dets[1].id, corners = dets[1].corners }
      dets[#dets + 1] = { id = 1, corners = { { 0 / 0, 1 }, { 2, 3 }, { 4, 5 }, { 6, 7 } } }
      local body = assert(tagpose.layout.solve(dets, camera, nominal))
      assert.equal(n, #body.tags)
      assert.vector_near(t, body.position, 1e-9)
      assert.equal(4, #body.skipped)
      assert.same({ n + 1, n + 2, n + 3, n + 4 }, { body.skipped[1].index, body.skipped[2].index,
        body.skipped[3].index, body.skipped[4].index })
      assert.matches("tag id 42 is not in the layout", body.skipped[1].reason)
      assert.matches("four corners", body.skipped[2].reason)
      assert.matches("detected twice", body.skipped[3].reason)
      assert.matches("not finite", body.skipped[4].reason)
      local none, why = tagpose.layout.solve({ dets[n + 1] }, camera, nominal)
      assert.is_nil(none)
      assert.matches("^layout: no detection gives a pose", why)
    end)

    it("gives both branches of the planar ambiguity for one tag, and for a board", function()
      local rng = geometry.rng(9)
      local camera = CAMERAS.pinhole
      local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
      local flat = board(0.03, 0.05)
      for _, case in ipairs({ { nominal, 1, 0.6 }, { flat, 4, 1.5 } }) do
        local layout, count, distance = case[1], case[2], case[3]
        local found = 0
        for _ = 1, 40 do
          -- seen from afar and nearly face-on: the two branches fit almost alike
          local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), rad(8))
          local t = { rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), distance }
          if count == 1 then
            -- tag 5 (-z face, tag z along +z) faces the camera
            r = geometry.mul(r, layouts.transpose(layouts.matrix(layout.tags[5].quaternion)))
          end
          local dets = layouts.detections(layout, camera, r, t, rng, 0)
          if #dets == count then
            local body = assert(tagpose.layout.solve(dets, camera, layout))
            local alt = body.alternative
            if alt then
              found = found + 1
              assert.is_true(assertions.rotation_angle(body.rotation, alt.rotation) > 1e-4)
              assert.is_true(body.error <= alt.error + 1e-12)
              -- (the better fit may be the less likely branch: the confidence weighs the
              -- curvature of each minimum and the tilt's prior too)
              assert.is_true(body.confidence >= 0 and body.confidence <= 1)
              assert.near(1, body.confidence + alt.confidence, 1e-12)
              -- one of the two is the truth (exact corners)
              local e1 = assertions.rotation_angle(r, body.rotation)
              local e2 = assertions.rotation_angle(r, alt.rotation)
              assert.is_true(math.min(e1, e2) < 1e-6, ("%.3g, %.3g deg"):format(e1, e2))
            end
          end
        end
        assert.is_true(found >= 20, count .. " tags: " .. found .. " views with two branches")
      end
    end)

    it("gives one pose, confidence 1, for tags on faces at an angle", function()
      local rng = geometry.rng(13)
      local camera = CAMERAS.pinhole
      local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
      local r = geometry.axis_angle(1, 1, 0.3, rad(130))
      local dets = layouts.detections(nominal, camera, r, { 0, 0, 0.6 }, rng, 0.3)
      assert.is_true(#dets >= 2)
      local body = assert(tagpose.layout.solve(dets, camera, nominal))
      assert.is_nil(body.alternative)
      assert.equal(1, body.confidence)
    end)

    it("gives a covariance that matches the scatter of poses from noisy corners", function()
      local rng = geometry.rng(21)
      local camera = CAMERAS.pinhole
      local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
      local r = geometry.axis_angle(1, 1, 0.3, rad(130))
      local t = { 0.01, -0.01, 0.3 }
      local sigma = 0.5
      local sum, n, cov = { 0, 0, 0 }, 300, nil
      local sq = { 0, 0, 0 }
      for _ = 1, n do
        local dets = layouts.detections(nominal, camera, r, t, rng, sigma)
        local body = assert(tagpose.layout.solve(dets, camera, nominal, { sigma = sigma }))
        local p = body.position
        local d = { p.x - t[1], p.y - t[2], p.z - t[3] }
        for k = 1, 3 do
          sum[k] = sum[k] + d[k]
          sq[k] = sq[k] + d[k] * d[k]
        end
        cov = body.covariance
      end
      for k = 1, 3 do
        local var = sq[k] / n - (sum[k] / n) ^ 2
        local ratio = sqrt(var / cov[k][k])
        assert.is_true(ratio > 0.8 and ratio < 1.25, ("axis %d: scatter / predicted %.3f"):format(k,
          ratio))
      end
      for i = 1, 6 do
        for j = 1, 6 do assert.near(cov[i][j], cov[j][i], 1e-12 * abs(cov[i][i] + cov[j][j])) end
      end
    end)

    -- Without options.sigma a fit of n >= 2 tags (8n - 6 residual degrees of freedom) is judged
    -- by its own residuals, its covariance widened for σ² being an estimate (Student's F): it
    -- covers as claimed at a σ well below and above the default.
    for _, sigma in ipairs({ 0.15, 1 }) do
      it("covers a view of several tags as it claims without sigma (σ " .. sigma .. " px)",
        function()
          local rng = geometry.rng(22)
          local camera = CAMERAS.pinhole
          local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
          local r = geometry.axis_angle(1, 1, 0.3, rad(130))
          local t = { 0.01, -0.01, 0.3 }
          local n, inside = 500, 0
          for _ = 1, n do
            local dets = layouts.detections(nominal, camera, r, t, rng, sigma)
            assert.is_true(#dets >= 2)
            local body = assert(tagpose.layout.solve(dets, camera, nominal))
            if gauss.mahalanobis(body.covariance, gauss.error_of(body, r, t)) < 12.59 then
              inside = inside + 1
            end
          end
          local share = inside / n
          assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / n),
            ("coverage %.3f"):format(share))
        end)
    end

    it("gives a one-tag view the tag's own uncertainty, the covariance at the body origin",
      function()
        local rng = geometry.rng(23)
        local camera = CAMERAS.pinhole
        local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
        local tag5 = layouts.transpose(layouts.matrix(nominal.tags[5].quaternion))
        local sigma, n, inside, seen = 0.4, 300, 0, 0
        for _ = 1, n do
          -- tag 5 faces the camera, tilted up to 40°, 0.15-0.6 m away
          local r = geometry.mul(geometry.axis_angle(rng.normal(), rng.normal(), 0,
            rng.uniform(0, rad(40))), tag5)
          local t = { rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(0.15, 0.6) }
          local dets = layouts.detections(nominal, camera, r, t, rng, sigma, 60)
          if #dets == 1 then
            seen = seen + 1
            local body = assert(tagpose.layout.solve(dets, camera, nominal, { sigma = sigma }))
            local tag = assert(tagpose.solve(dets[1].corners, camera, nominal.tags[5].size,
              { sigma = sigma }))
            -- the same corners, the same problem: the tag's poses, confidence and rotation
            -- covariance
            local alt = body.alternative
            assert.is_true(assertions.rotation_angle(geometry.mul(assertions.flat(tag.rotation),
              tag5), body.rotation) < 1e-9)
            assert.equal(tag.alternative == nil, alt == nil)
            assert.near(tag.confidence, body.confidence, 1e-12)
            local tc = tag.covariance
            for i = 4, 6 do
              for j = 4, 6 do
                assert.near(tc[i][j], body.covariance[i][j], 1e-9 * sqrt(tc[i][i] * tc[j][j]))
              end
            end
            -- coverage of the body pose on its true branch
            local best, e = body, gauss.error_of(body, r, t)
            if alt then
              assert.near(1, body.confidence + alt.confidence, 1e-12)
              local ea = gauss.error_of(alt, r, t)
              if ea[4] ^ 2 + ea[5] ^ 2 + ea[6] ^ 2 < e[4] ^ 2 + e[5] ^ 2 + e[6] ^ 2 then
                best, e = alt, ea
              end
            end
            assert.is_true(gauss.is_spd(best.covariance))
            if gauss.mahalanobis(best.covariance, e) < 12.59 then inside = inside + 1 end
          end
        end
        assert.is_true(seen > 200, "views with one tag " .. seen)
        local share = inside / seen
        assert.is_true(abs(share - 0.95) < 4 * sqrt(0.0475 / seen),
          ("coverage %.3f"):format(share))
      end)

    it("refuses misuse with the argument's position", function()
      local camera = CAMERAS.pinhole
      local nominal = tagpose.layout.cube(0.0229, 0.0548)
      local det = { { id = 0, corners = { { 1, 2 }, { 3, 2 }, { 3, 0 }, { 1, 0 } } } }
      local raised = assertions.raised
      local name = "layout_solve_spec.lua"
      assert.equal("bad argument #1 to 'solve' (array of detections expected, got string)",
        raised(function() tagpose.layout.solve("x", camera, nominal) end, name))
      assert.matches("^bad argument #2 to 'solve' %(camera.fx",
        raised(function() tagpose.layout.solve(det, {}, nominal) end, name))
      assert.matches("^bad argument #3 to 'solve' %(layout.tags",
        raised(function() tagpose.layout.solve(det, camera, {}) end, name))
      local bad = { tags = { [0] = { size = -1, position = { x = 0, y = 0, z = 0 },
        quaternion = { w = 1, x = 0, y = 0, z = 0 } } } }
      assert.equal("bad argument #3 to 'solve' (layout.tags[0].size: positive number expected,"
        .. " got number -1)", raised(function() tagpose.layout.solve(det, camera, bad) end, name))
      assert.equal("bad argument #4 to 'solve' (options.sigm: unknown key (did you mean 'sigma'?))",
        raised(function() tagpose.layout.solve(det, camera, nominal, { sigm = 1 }) end, name))
    end)
  end)

  describe("fit.fit()", function()
    it("returns the normal equations at the minimum: zero gradient on exact pixels", function()
      local fit = require("tagpose.layout.fit")
      local camera = CAMERAS.brown
      local rng = geometry.rng(17)
      local nominal = layouts.cube(rng, 0.0229, 0.0548, 0, 0, 0)
      local r, t = geometry.axis_angle(1, 1, 0.3, rad(130)), { 0.01, 0, 0.3 }
      local dets = layouts.detections(nominal, camera, r, t, rng, 0)
      local points, px = {}, {}
      for _, d in ipairs(dets) do
        for i, c in ipairs(layouts.corners(nominal.tags[d.id])) do
          points[#points + 1], points[#points + 2], points[#points + 3] = c[1], c[2], c[3]
          px[#px + 1], px[#px + 2] = d.corners[i][1], d.corners[i][2]
        end
      end
      local start = geometry.mul(geometry.axis_angle(0, 1, 0, rad(3)), r)
      local N = {}
      local x, y, z, cost, k, sse = fit.fit(camera, points, px, #points / 3, start, t[1] + 0.01,
        t[2], t[3] - 0.02, nil, nil, N)
      assert.vector_near(t, { x, y, z }, 1e-9)
      assert.rotation_near(r, start, 1e-7)
      assert.is_true(cost < 1e-16 and sse < 1e-16 and k >= 2)
      for i = 22, 27 do assert.is_true(abs(N[i]) < 1e-6, "gradient " .. N[i]) end
      assert.is_true(N[1] > 0 and N[16] > 0)
    end)
  end)
end)
