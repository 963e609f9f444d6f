local tagpose = require("tagpose")
local geometry = require("support.geometry")
local dataset = require("support.dataset")
local assertions = require("support.assertions")

local sqrt, rad = math.sqrt, math.rad

local METHODS = { "seed", "refined" }

-- rotation error tolerance (degrees) and position tolerance (fraction of the distance)
local ROT_TOL, POS_TOL = 1e-6, 1e-9

local function distance(t)
  return sqrt(t[1] ^ 2 + t[2] ^ 2 + t[3] ^ 2)
end

-- True when check_pose below would pass, in plain Lua (the dev-set loops check thousands of
-- poses: luassert's calls cost more than the solves; a failing pose is then asserted in full).
local function pose_ok(pose, r, t)
  if type(pose) ~= "table" then return false end
  local q, p, R = pose.quaternion, pose.position, pose.rotation
  local w, x, y, z = q.w, q.x, q.y, q.z
  local from_q = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
  local d = sqrt((p.x - t[1]) ^ 2 + (p.y - t[2]) ^ 2 + (p.z - t[3]) ^ 2)
  return assertions.rotation_angle(r, R) <= ROT_TOL
    and assertions.rotation_angle(r, from_q) <= ROT_TOL
    and d <= POS_TOL * distance(t)
    and math.abs(1 - (w * w + x * x + y * y + z * z)) <= 1e-12 and w >= 0
    and pose.error >= 0 and pose.error < 1e-6
end

local function check_pose(pose, r, t, label)
  if pose_ok(pose, r, t) then return end
  assert.is_table(pose, label)
  assert.rotation_near(r, pose.rotation, ROT_TOL, label)
  assert.vector_near(t, pose.position, POS_TOL * distance(t), label)
  -- the quaternion is the rotation's, unit, w >= 0
  local q = pose.quaternion
  assert.near(1, q.w ^ 2 + q.x ^ 2 + q.y ^ 2 + q.z ^ 2, 1e-12, label)
  assert.is_true(q.w >= 0, label)
  local w, x, y, z = q.w, q.x, q.y, q.z
  local from_q = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
  assert.rotation_near(r, from_q, ROT_TOL, label)
  assert.is_true(pose.error >= 0 and pose.error < 1e-6, label)
  error(label .. ": the pose fails pose_ok, though each check above passed")
end

local cameras = {
  { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 },
  { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 },
  { fx = 1210.3, fy = 1195.7, cx = 655.2, cy = 351.9, width = 1280, height = 720 },
  { fx = 420, fy = 460, cx = 300.1, cy = 250.7, width = 640, height = 480 },
}

describe("tagpose.solve()", function()
  for _, method in ipairs(METHODS) do
    describe("method " .. method, function()
      it("recovers 600 random exact poses to round-off", function()
        local seed = 4242
        local rng = geometry.rng(seed)
        local n = 0
        while n < 600 do
          local camera = cameras[n % #cameras + 1]
          local s = rng.log_uniform(1e-3, 1e3)
          -- widths from ~10 px to filling the image
          local width = rng.log_uniform(10, camera.height)
          local r, t = geometry.random_pose(rng, camera, s, { width = width })
          local px = geometry.project(camera, r, t, s)
          if px then
            n = n + 1
            local label = ("seed %d, case %d (s = %g, width %.1f px)"):format(seed, n, s, width)
            check_pose(tagpose.solve(px, camera, s, { method = method }), r, t, label)
          end
        end
      end)

      it("solves a fronto-parallel tag at the image centre (R = I)", function()
        local camera = cameras[1]
        local s, d = 0.024, 0.3
        local id = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }
        local pose = tagpose.solve(geometry.project(camera, id, { 0, 0, d }, s), camera, s,
          { method = method })
        check_pose(pose, id, { 0, 0, d })
        assert.same({ w = 1, x = 0, y = 0, z = 0 }, pose.quaternion)
      end)

      it("solves tags at the corners of the image", function()
        local camera = cameras[1]
        local rng = geometry.rng(7)
        for _, uv in ipairs({ { 8, 8 }, { 632, 8 }, { 632, 472 }, { 8, 472 } }) do
          local r, t = geometry.random_pose(rng, camera, 0.024,
            { u = uv[1], v = uv[2], width = 12 })
          check_pose(tagpose.solve(geometry.project(camera, r, t, 0.024), camera, 0.024,
            { method = method }), r, t)
        end
      end)

      it("solves quarter and half turns in the image plane", function()
        local camera = cameras[1]
        for _, roll in ipairs({ 90, 180, 270, -90 }) do
          for _, tilt in ipairs({ 0, 30 }) do
            local r, t = geometry.random_pose(geometry.rng(roll + 1000), camera, 0.05,
              { roll = rad(roll), tilt = rad(tilt), azimuth = 0.3, u = 300, v = 200, width = 80 })
            check_pose(tagpose.solve(geometry.project(camera, r, t, 0.05), camera, 0.05,
              { method = method }), r, t, ("roll %d tilt %d"):format(roll, tilt))
          end
        end
      end)

      it("takes corners as {x =, y =} tables", function()
        local camera = cameras[2]
        local r, t = geometry.random_pose(geometry.rng(99), camera, 0.024, { width = 60 })
        local px = geometry.project(camera, r, t, 0.024)
        local xy = {}
        for i = 1, 4 do xy[i] = { x = px[i][1], y = px[i][2] } end
        check_pose(tagpose.solve(xy, camera, 0.024, { method = method }), r, t)
      end)

      it("reports the RMS reprojection error of all four corners", function()
        local camera = cameras[1]
        local r, t = geometry.random_pose(geometry.rng(5), camera, 0.05,
          { width = 100, tilt = 0.4 })
        local px = geometry.project(camera, r, t, 0.05)
        -- move corner 4 (which the seed method does not use) by (3, 4) px: a 5 px miss
        px[4][1], px[4][2] = px[4][1] + 3, px[4][2] + 4
        local pose = tagpose.solve(px, camera, 0.05, { method = method })
        local est = {}
        for i = 1, 3 do est[i] = pose.rotation[i] end
        local flat = { est[1][1], est[1][2], est[1][3], est[2][1], est[2][2], est[2][3],
          est[3][1], est[3][2], est[3][3] }
        local p = pose.position
        local back = geometry.project(camera, flat, { p.x, p.y, p.z }, 0.05)
        local sum = 0
        for i = 1, 4 do
          sum = sum + (back[i][1] - px[i][1]) ^ 2 + (back[i][2] - px[i][2]) ^ 2
        end
        assert.near(sqrt(sum / 4), pose.error, 1e-9)
        assert.is_true(pose.error > 0.1)
      end)
    end)
  end

  describe("options.into", function()
    it("fills the caller's table and its sub-tables in place, with the same values", function()
      local camera = cameras[1]
      local rng = geometry.rng(77)
      local into = {}
      local tables
      for n = 1, 30 do
        local r, t = geometry.random_pose(rng, camera, 0.05, { width = rng.uniform(15, 150) })
        local px = geometry.project(camera, r, t, 0.05)
        for i = 1, 4 do
          px[i][1], px[i][2] = px[i][1] + 0.5 * rng.normal(), px[i][2] + 0.5 * rng.normal()
        end
        local fresh = assert(tagpose.solve(px, camera, 0.05))
        local filled = assert(tagpose.solve(px, camera, 0.05, { into = into }))
        assert.equal(into, filled)
        assert.same(fresh, filled, "case " .. n)
        local now = { into.position, into.rotation, into.rotation[1], into.quaternion, into.track }
        if tables then
          for i = 1, #now do assert.equal(tables[i], now[i]) end
        end
        tables = now
      end
    end)
  end)

  describe("on the exact dev set (spec/fixtures/exact)", function()
    local camera, corners, truth = dataset.load("spec/fixtures/exact")
    for _, method in ipairs(METHODS) do
      it("solves every row to round-off with method " .. method, function()
        for i, row in ipairs(corners) do
          local tr = truth[i]
          local w, x, y, z = tr.qw, tr.qx, tr.qy, tr.qz
          local r = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
          local pose = tagpose.solve(dataset.corners(row), camera, camera.tag_size,
            { method = method })
          check_pose(pose, r, { tr.x, tr.y, tr.z }, "frame " .. row.frame)
        end
      end)
    end
  end)
end)
