-- Hardening: tagpose.solve, the lens inverse and tagpose.block.solve on inputs built to break
-- them. Every input gives either a finite pose (or blocks) whose reported error is its own
-- reprojection error, or nil and a "module: reason" message; nothing raises, nothing is NaN or
-- infinite, no count exceeds its documented bound, no detection is lost. Deterministic: the
-- seed of a failing case is in the message.
--
-- The suite runs a twentieth of the cases (5000 solves, 1000 lens inverses, 150 block frames);
-- `bench/fuzz.sh` runs all of them and more (TAGPOSE_FUZZ_SCALE = 1, 10, ...: the cases and
-- the counts the routes must reach scale together).

local tagpose = require("tagpose")
local camera_model = require("tagpose.core.camera")
local refine = require("tagpose.core.refine")
local solvequad = require("tagpose.core.solvequad")
local geometry = require("support.geometry")

local sqrt, huge = math.sqrt, math.huge
local nan = 0 / 0

-- how many cases, as a share of the full fuzz's (TAGPOSE_FUZZ_SCALE; the suite's default 0.05)
local SCALE = tonumber(os.getenv("TAGPOSE_FUZZ_SCALE") or "") or 0.05
local function cases(full) return math.max(1, math.floor(full * SCALE + 0.5)) end

local function finite(v)
  return type(v) == "number" and v - v == 0
end

-- RMS reprojection error of a returned pose, recomputed here from geometry
local function reprojection(pose, camera, s, corners)
  local R = pose.rotation
  local r = { R[1][1], R[1][2], R[1][3], R[2][1], R[2][2], R[2][3], R[3][1], R[3][2], R[3][3] }
  local p = pose.position
  local px = geometry.project(camera, r, { p.x, p.y, p.z }, s)
  if not px then return huge end
  local sum = 0
  for i = 1, 4 do
    local c = corners[i]
    local u, v = c[1] or c.x, c[2] or c.y
    sum = sum + (px[i][1] - u) ^ 2 + (px[i][2] - v) ^ 2
  end
  return sqrt(sum / 4)
end

-- the checks every answer must pass; returns nil or what is wrong
local function check_pose(pose, camera, s, corners, options)
  local p, q, R = pose.position, pose.quaternion, pose.rotation
  local sum = p.x + p.y + p.z + pose.error + q.w + q.x + q.y + q.z
  for i = 1, 3 do
    sum = sum + R[i][1] + R[i][2] + R[i][3]
  end
  if not finite(sum) then return "non-finite field" end
  local max_it = options and options.max_iterations or solvequad.MAX_ITERATIONS
  if pose.iterations > max_it then return "solveQuad iterations above the bound" end
  if (pose.refine_iterations or 0) > 2 * refine.MAX_ITERATIONS + 4 then
    return "refinement iterations above the bound"
  end
  local e = reprojection(pose, camera, s, corners)
  -- the error is the pose's own: to round-off relative to the pixel coordinates' size
  local scale = 0
  for i = 1, 4 do
    local c = corners[i]
    scale = math.max(scale, math.abs(c[1] or c.x), math.abs(c[2] or c.y))
  end
  if not (math.abs(e - pose.error) <= 1e-6 * (1 + pose.error) + 1e-9 * scale) then
    return ("reported error %.17g, reprojection %.17g"):format(pose.error, e)
  end
  if pose.alternative then return check_pose(pose.alternative, camera, s, corners, options) end
  return nil
end

local cameras = {
  { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 },
  { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 },
  { fx = 700, fy = 700, cx = 639.5, cy = 359.5,
    distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0 } },
  { fx = 600, fy = 600, cx = 639.5, cy = 359.5, model = "fisheye",
    distortion = { k1 = -0.013, k2 = 0.02, k3 = -0.008, k4 = 0.001 } },
  { fx = 1e-6, fy = 1e-6, cx = 0, cy = 0 },
  { fx = 1e9, fy = 2e9, cx = -5e5, cy = 1e7 },
  { fx = 1, fy = 1, cx = 0, cy = 0 },
}

describe("fuzzing", function()
  it("tagpose.solve survives " .. cases(100000) .. " hostile inputs", function()
    local seed = 20261122
    local rng = geometry.rng(seed)
    local u, n = rng.uniform, 0
    local counts = { ok = 0, failed = 0 }
    local valid = { { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } }
    local function quad_from(kind, camera)
      local c = {}
      if kind == 1 then -- random quadrilateral anywhere
        local span = 10 ^ u(-1, 4)
        local ox, oy = u(-2, 2) * span, u(-2, 2) * span
        for i = 1, 4 do c[i] = { ox + u(-1, 1) * span, oy + u(-1, 1) * span } end
      elseif kind == 2 then -- a real tag, then one coordinate made NaN or ±inf
        local r, t = geometry.random_pose(rng, camera, 0.05)
        c = geometry.project(camera, r, t, 0.05) or valid
        local bad = ({ nan, huge, -huge })[math.floor(u(1, 4))]
        c[math.floor(u(1, 5))][math.floor(u(1, 3))] = bad
      elseif kind == 3 then -- duplicate corners
        for i = 1, 4 do c[i] = { valid[i][1], valid[i][2] } end
        local a, b = math.floor(u(1, 5)), math.floor(u(1, 5))
        c[a][1], c[a][2] = c[b][1], c[b][2]
      elseif kind == 4 then -- collinear corners (three or four)
        local x0, y0, dx, dy = u(-1e3, 1e3), u(-1e3, 1e3), u(-50, 50), u(-50, 50)
        for i = 1, 4 do c[i] = { x0 + i * dx, y0 + i * dy } end
        if u() < 0.5 then c[math.floor(u(1, 5))] = { x0 + u(-100, 100), y0 + u(-100, 100) } end
      elseif kind == 5 then -- bow-tie or clockwise (mirrored) orderings of a real tag
        local r, t = geometry.random_pose(rng, camera, 0.05)
        local p = geometry.project(camera, r, t, 0.05) or valid
        local order = ({ { 1, 2, 4, 3 }, { 1, 4, 3, 2 }, { 2, 1, 3, 4 }, { 1, 3, 2, 4 } })
          [math.floor(u(1, 5))]
        for i = 1, 4 do c[i] = p[order[i]] end
      elseif kind == 6 then -- sub-pixel tags
        local w = 10 ^ u(-6, 0)
        local x0, y0 = u(0, 640), u(0, 480)
        c = { { x0, y0 + w }, { x0 + w, y0 + w }, { x0 + w, y0 }, { x0, y0 } }
      elseif kind == 7 then -- coordinates of 1e12
        local big = 1e12 * (u() < 0.5 and 1 or -1)
        for i = 1, 4 do c[i] = { big + valid[i][1] * 1e10, big + valid[i][2] * 1e10 } end
      elseif kind == 8 then -- a real tag at a random pose, noisy (the ordinary case)
        local r, t = geometry.random_pose(rng, camera, 0.05, { width = 10 ^ u(0.5, 3) })
        c = geometry.project(camera, r, t, 0.05) or valid
        local sigma = 10 ^ u(-3, 1)
        for i = 1, 4 do
          c[i] = { c[i][1] + sigma * rng.normal(), c[i][2] + sigma * rng.normal() }
        end
      else -- wildly distorted or edge-of-image tags, and {x =, y =} corners
        for i = 1, 4 do c[i] = { x = u(-1e4, 1e4), y = u(-1e4, 1e4) } end
      end
      return c
    end
    for case = 1, cases(100000) do
      local camera = cameras[math.floor(u(1, #cameras + 1))]
      local kind = math.floor(u(1, 10))
      local corners = quad_from(kind, camera)
      local s = 10 ^ u(-9, 9)
      local options
      local pick = u()
      if pick < 0.2 then
        options = { method = "seed" }
      elseif pick < 0.3 then
        options = { tolerance = 10 ^ u(-20, 0), max_iterations = math.floor(u(1, 200)) }
      elseif pick < 0.4 then
        local w, x, y, z = rng.normal(), rng.normal(), rng.normal(), rng.normal()
        options = { prior = { quaternion = { w = w, x = x, y = y, z = z } } }
      elseif pick < 0.45 then
        options = { into = {} }
      end
      local label = ("seed %d case %d (kind %d)"):format(seed, case, kind)
      local ok, pose, err = pcall(tagpose.solve, corners, camera, s, options)
      assert.is_true(ok, label .. ": raised " .. tostring(pose))
      if pose then
        counts.ok = counts.ok + 1
        local problem = check_pose(pose, camera, s, corners, options)
        assert.is_nil(problem, label .. ": " .. tostring(problem))
        -- a pose makes a good prior for the same corners and options (checked on a sample)
        local with_prior = { prior = pose }
        for k, v in pairs(options or {}) do
          if k ~= "into" and k ~= "prior" then with_prior[k] = v end
        end
        if case % 8 == 0 then
          local again = tagpose.solve(corners, camera, s, with_prior)
          assert.is_table(again, label .. ": the pose as a prior")
        end
      else
        counts.failed = counts.failed + 1
        assert.is_string(err, label)
        assert.truthy(err:match("^%a+: "), label .. ": message " .. err)
      end
      n = n + 1
    end
    assert.equal(cases(100000), n)
    -- both routes were exercised
    assert.is_true(counts.ok > cases(20000) and counts.failed > cases(20000),
      ("%d poses, %d refusals"):format(counts.ok, counts.failed))
  end)

  it("the lens inverse answers exactly or refuses, over random models and points", function()
    local seed = 4711
    local rng = geometry.rng(seed)
    local u = rng.uniform
    local accepted = 0
    for case = 1, cases(20000) do
      local camera
      if u() < 0.7 then
        camera = { fx = 700, fy = 700, cx = 0, cy = 0, distortion = { k1 = u(-1, 1),
          k2 = u(-0.5, 0.5), p1 = u(-0.02, 0.02), p2 = u(-0.02, 0.02), k3 = u(-0.5, 0.5) } }
        if u() < 0.3 then
          camera.distortion.k4, camera.distortion.k5 = u(0, 1), u(-0.2, 0.2)
        end
      else
        camera = { fx = 700, fy = 700, cx = 0, cy = 0, model = "fisheye", distortion = {
          k1 = u(-0.2, 0.2), k2 = u(-0.1, 0.1), k3 = u(-0.05, 0.05), k4 = u(-0.01, 0.01) } }
      end
      local xd, yd = u(-3, 3), u(-3, 3)
      if u() < 0.02 then xd = ({ nan, huge, 1e300 })[math.floor(u(1, 4))] end
      local label = ("seed %d case %d"):format(seed, case)
      local ok, x, y = pcall(camera_model.undistort, camera, xd, yd)
      assert.is_true(ok, label .. ": raised " .. tostring(x))
      if x then
        assert.is_true(finite(x) and finite(y), label)
        local bx, by = geometry.distort(camera, x, y)
        local d = sqrt((bx - xd) ^ 2 + (by - yd) ^ 2)
        assert.is_true(d <= 1e-12 * (1 + math.abs(xd) + math.abs(yd)),
          ("%s: residual %.3g"):format(label, d))
        -- and it is the camera's inverse, reached from the centre without a fold: along the
        -- ray to it the distorted point moves steadily away from the centre
        accepted = accepted + 1
        local last = 0
        for k = 1, 64 do
          local s = k / 64
          local px, py = geometry.distort(camera, s * x, s * y)
          local r = px * xd + py * yd
          if not (r > last) then
            error(("%s: the map folds at %.3f of the way to (%.6g, %.6g)"):format(label, s, x, y))
          end
          last = r
        end
      else
        assert.truthy(tostring(y):match("^camera: "), label .. ": " .. tostring(y))
      end
    end
    assert.is_true(accepted > cases(5000), accepted .. " inversions accepted")
  end)
  it("tagpose.block.solve survives " .. cases(3000) .. " hostile frames", function()
    local faces = require("support.faces")
    local seed = 5511
    local rng = geometry.rng(seed)
    local u = rng.uniform
    local TAG, BLOCK = 0.024, 0.055
    local cams = {
      { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 },
      { fx = 700, fy = 700, cx = 639.5, cy = 359.5, width = 1280, height = 720,
        distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0 } },
    }
    -- the tags of 1 to 4 random cubes in front of the camera, noisy
    local function scene(camera, sigma)
      local dets = {}
      for _ = 1, math.floor(u(1, 5)) do
        local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), u(0, math.pi))
        local d = 10 ^ u(-1, 0.3)
        local t = { d * u(-0.5, 0.5), d * u(-0.4, 0.4), d }
        for _, f in ipairs(faces.FACES) do
          local n = { r[1] * f.n[1] + r[2] * f.n[2] + r[3] * f.n[3],
            r[4] * f.n[1] + r[5] * f.n[2] + r[6] * f.n[3],
            r[7] * f.n[1] + r[8] * f.n[2] + r[9] * f.n[3] }
          local tt = { t[1] + 0.5 * BLOCK * n[1], t[2] + 0.5 * BLOCK * n[2],
            t[3] + 0.5 * BLOCK * n[3] }
          if n[1] * tt[1] + n[2] * tt[2] + n[3] * tt[3] < 0 then
            local c = geometry.project(camera, geometry.mul(r, f.r), tt, TAG)
            if c then
              for _, p in ipairs(c) do
                p[1], p[2] = p[1] + sigma * rng.normal(), p[2] + sigma * rng.normal()
              end
              dets[#dets + 1] = { id = 0, corners = c }
            end
          end
        end
      end
      return dets
    end
    local function quad()
      local span, ox, oy = 10 ^ u(-1, 3), u(-500, 1500), u(-500, 1000)
      local c = {}
      for i = 1, 4 do c[i] = { ox + u(-1, 1) * span, oy + u(-1, 1) * span } end
      return c
    end
    -- what a detector glitch can look like
    local glitches = {
      function(d) d.corners[math.floor(u(1, 5))][math.floor(u(1, 3))] = ({ nan, huge, -huge })
        [math.floor(u(1, 4))] end,
      function(d) d.corners[4] = nil end,
      function(d) d.corners = "corners" end,
      function(d) d.id = nil end,
      function(d) d.corners[2] = { d.corners[1][1], d.corners[1][2] } end,
      function(d) d.corners = { d.corners[1], d.corners[4], d.corners[3], d.corners[2] } end,
      function(d) for i = 1, 4 do d.corners[i] = { 1e12 + i, 1e12 - i } end end,
      function(d) d.corners = quad() end,
    }
    -- Whether some quarter turn of each tag on its named face reprojects with the reported
    -- RMS error (the face names the normal; the tag's quarter turn on it is not named, as the
    -- returned frame is one of the cube's 24, not the data set's own); and the least such RMS.
    local function reprojects(block, camera, dets)
      local R = block.rotation
      local r = { R[1][1], R[1][2], R[1][3], R[2][1], R[2][2], R[2][3], R[3][1], R[3][2],
        R[3][3] }
      local p = block.position
      local sse = {}
      for m, i in ipairs(block.tags) do
        local f = faces.BY_NAME[block.tag_faces[m]]
        if not f then return false, huge end
        local nn = { r[1] * f.n[1] + r[2] * f.n[2] + r[3] * f.n[3],
          r[4] * f.n[1] + r[5] * f.n[2] + r[6] * f.n[3],
          r[7] * f.n[1] + r[8] * f.n[2] + r[9] * f.n[3] }
        local px = geometry.project(camera, geometry.mul(r, f.r), { p.x + 0.5 * BLOCK * nn[1],
          p.y + 0.5 * BLOCK * nn[2], p.z + 0.5 * BLOCK * nn[3] }, TAG)
        if not px then return false, huge end
        sse[m] = {}
        for shift = 0, 3 do
          local e = 0
          for k = 1, 4 do
            local c, q = dets[i].corners[k], px[(k + shift - 1) % 4 + 1]
            e = e + (q[1] - c[1]) ^ 2 + (q[2] - c[2]) ^ 2
          end
          sse[m][shift + 1] = e
        end
      end
      local n, target, least = #sse, block.error, huge
      local function walk(m, total)
        if m > n then
          local e = sqrt(total / (4 * n))
          if e < least then least = e end
          return math.abs(e - target) <= 1e-6 * (1 + target)
        end
        local found = false
        for shift = 1, 4 do found = walk(m + 1, total + sse[m][shift]) or found end
        return found
      end
      return walk(1, 0), least
    end
    local previous
    local counts = { blocks = 0, refused = 0, skipped = 0 }
    for case = 1, cases(3000) do
      local camera = cams[case % 5 == 0 and 2 or 1]
      local kind = math.floor(u(1, 5))
      local dets
      if kind == 1 then -- a clean or noisy scene
        dets = scene(camera, 10 ^ u(-3, 0.5))
      elseif kind == 2 then -- a scene with glitches
        dets = scene(camera, 0.3)
        for _ = 1, math.floor(u(1, 3)) do
          local d = dets[math.floor(u(1, #dets + 1))]
          if d and type(d.corners) == "table" and #d.corners == 4 then
            glitches[math.floor(u(1, #glitches + 1))](d)
          end
        end
      elseif kind == 3 then -- random quadrilaterals
        dets = {}
        for i = 1, math.floor(u(0, 7)) do
          dets[i] = { id = math.floor(u(0, 3)), corners = quad() }
        end
      else -- a scene and the same tags twice, or nothing at all
        dets = scene(camera, 0.3)
        if u() < 0.5 then dets[#dets + 1] = dets[1] else dets = {} end
      end
      local options = {}
      local pick = u()
      if pick < 0.2 then
        options.up = { x = rng.normal(), y = rng.normal() - 2, z = rng.normal() }
      elseif pick < 0.35 then
        options.up = "auto"
      elseif pick < 0.45 then
        options.up, options.floor = { 0, -0.8, -0.6 }, u(0.01, 2)
      elseif pick < 0.6 then
        options.previous = previous
      elseif pick < 0.7 then
        options.max_iterations = math.floor(u(1, 30))
      elseif pick < 0.75 then
        options.faces = { [0] = "+x", [1] = "-z", [2] = "+y" }
      end
      local label = ("seed %d case %d (kind %d)"):format(seed, case, kind)
      local ok, blocks, err = pcall(tagpose.block.solve, dets, camera, TAG, BLOCK, options)
      assert.is_true(ok, label .. ": raised " .. tostring(blocks))
      if blocks then
        local used = {}
        for _, b in ipairs(blocks) do
          counts.blocks = counts.blocks + 1
          local p, q = b.position, b.quaternion
          local sum = p.x + p.y + p.z + q.w + q.x + q.y + q.z + b.error
          for i = 1, 3 do for j = 1, 3 do sum = sum + b.rotation[i][j] end end
          assert.is_true(finite(sum), label .. ": non-finite block")
          assert.near(1, q.w ^ 2 + q.x ^ 2 + q.y ^ 2 + q.z ^ 2, 1e-9, label)
          assert.equal(#b.tags, b.faces, label)
          for _, i in ipairs(b.tags) do
            assert.is_nil(used[i], label .. ": detection " .. i .. " used twice")
            used[i] = true
          end
          local matches, least = reprojects(b, camera, dets)
          assert.is_true(matches, ("%s: reported error %.17g, least reprojection %.17g"):format(
            label, b.error, least))
        end
        for _, s in ipairs(blocks.skipped or {}) do
          counts.skipped = counts.skipped + 1
          assert.is_nil(used[s.index], label .. ": detection " .. s.index .. " used and skipped")
          assert.is_string(s.reason, label)
          used[s.index] = true
        end
        for i = 1, #dets do assert.is_true(used[i], label .. ": detection " .. i .. " lost") end
        previous = blocks
      else
        counts.refused = counts.refused + 1
        assert.is_string(err, label)
        assert.truthy(err:match("^%a+: "), label .. ": message " .. err)
      end
    end
    -- every route was exercised
    assert.is_true(counts.blocks > cases(3000) and counts.skipped > cases(1000)
      and counts.refused > cases(100),
      ("%d blocks, %d skipped detections, %d refusals"):format(counts.blocks, counts.skipped,
        counts.refused))
  end)
end)
