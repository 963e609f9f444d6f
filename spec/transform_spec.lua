-- tagpose.transform against formulas of its own: poses as 4×4 homogeneous matrices, multiplied
-- and inverted (Gauss-Jordan) by the generic loops below, and the camera's place in the tag's
-- frame known from the geometry that made the corners.
local transform = require("tagpose.transform")
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local layouts = require("support.layouts")
local run = require("support.run")
local compat = require("tagpose.core.compat")

local sqrt, abs, pi = math.sqrt, math.abs, math.pi
local raised = assertions.raised

local SEED = 20240415
local TOL = 1e-12

-- 4×4 homogeneous matrices, m[i][j]

local function homogeneous(r, t)
  return { { r[1], r[2], r[3], t[1] }, { r[4], r[5], r[6], t[2] }, { r[7], r[8], r[9], t[3] },
    { 0, 0, 0, 1 } }
end

local function mul4(a, b)
  local c = {}
  for i = 1, 4 do
    c[i] = {}
    for j = 1, 4 do
      local s = 0
      for k = 1, 4 do s = s + a[i][k] * b[k][j] end
      c[i][j] = s
    end
  end
  return c
end

-- the inverse by Gauss-Jordan elimination with partial pivoting (nothing of rotations in it)
local function inv4(m)
  local a = {}
  for i = 1, 4 do
    a[i] = {}
    for j = 1, 4 do a[i][j] = m[i][j] end
    for j = 1, 4 do a[i][4 + j] = i == j and 1 or 0 end
  end
  for col = 1, 4 do
    local p = col
    for i = col + 1, 4 do
      if abs(a[i][col]) > abs(a[p][col]) then p = i end
    end
    a[col], a[p] = a[p], a[col]
    local d = a[col][col]
    for j = 1, 8 do a[col][j] = a[col][j] / d end
    for i = 1, 4 do
      if i ~= col then
        local f = a[i][col]
        for j = 1, 8 do a[i][j] = a[i][j] - f * a[col][j] end
      end
    end
  end
  local out = {}
  for i = 1, 4 do out[i] = { a[i][5], a[i][6], a[i][7], a[i][8] } end
  return out
end

-- rotation matrix of a unit quaternion, written out (Hamilton, scalar first)
local function q_matrix(q)
  local w, x, y, z = q.w, q.x, q.y, q.z
  return { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
end

-- A random pose: a rotation about a random axis by U(0, π), a position within ±3 per axis.
local function random_pose(rng)
  local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), rng.uniform(0, pi))
  local t = { rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3) }
  return r, t
end

local function as_pose(r, t)
  return { position = { x = t[1], y = t[2], z = t[3] }, rotation = geometry.nested(r) }
end

-- The pose p is the homogeneous matrix m to TOL, and its quaternion is its rotation, unit,
-- w >= 0.
local function assert_pose(m, p, message)
  local worst = 0
  for i = 1, 3 do
    for j = 1, 3 do worst = math.max(worst, abs(m[i][j] - p.rotation[i][j])) end
  end
  local pos = { p.position.x, p.position.y, p.position.z }
  for i = 1, 3 do worst = math.max(worst, abs(m[i][4] - pos[i])) end
  assert.is_true(worst <= TOL, message .. ": off by " .. worst)
  local q = p.quaternion
  assert.is_true(q.w >= 0, message .. ": w < 0")
  assert.is_true(abs(sqrt(q.w ^ 2 + q.x ^ 2 + q.y ^ 2 + q.z ^ 2) - 1) <= 1e-15, message)
  local rq = q_matrix(q)
  for i = 1, 3 do
    for j = 1, 3 do
      assert.is_true(abs(rq[3 * (i - 1) + j] - m[i][j]) <= TOL, message .. ": quaternion")
    end
  end
end

describe("tagpose.transform", function()
  describe("inverse()", function()
    it("is the 4×4 inverse of the pose, for 500 random poses (Park-Miller)", function()
      local rng = geometry.rng(SEED)
      for trial = 1, 500 do
        local r, t = random_pose(rng)
        assert_pose(inv4(homogeneous(r, t)), transform.inverse(as_pose(r, t)),
          ("seed %d, trial %d"):format(SEED, trial))
      end
    end)

    it("reads the rotation from the quaternion alone, from a flat matrix, or from both", function()
      local rng = geometry.rng(SEED + 1)
      for trial = 1, 50 do
        local r, t = random_pose(rng)
        local q = layouts.quaternion(r)
        local w, x, y, z = q.w, q.x, q.y, q.z
        local expected = inv4(homogeneous(r, t))
        local message = ("seed %d, trial %d"):format(SEED + 1, trial)
        local position = { x = t[1], y = t[2], z = t[3] }
        -- a quaternion of any length, either sign
        local k = trial % 2 == 0 and 3 or -0.5
        assert_pose(expected, transform.inverse({ position = position,
          quaternion = { w = k * w, x = k * x, y = k * y, z = k * z } }), message)
        assert_pose(expected, transform.inverse({ position = { t[1], t[2], t[3] }, rotation = r }),
          message)
        local both = as_pose(r, t)
        both.quaternion = q
        assert_pose(expected, transform.inverse(both), message)
      end
    end)

    it("gives back the pose when applied twice", function()
      local rng = geometry.rng(SEED + 2)
      for trial = 1, 100 do
        local r, t = random_pose(rng)
        assert_pose(homogeneous(r, t), transform.inverse(transform.inverse(as_pose(r, t))),
          ("seed %d, trial %d"):format(SEED + 2, trial))
      end
    end)

    it("puts the camera where it was in the tag's frame (project a known pose, solve)", function()
      local rng = geometry.rng(SEED + 3)
      local camera = { fx = 600, fy = 600, cx = 319.5, cy = 239.5 }
      local s = 0.16
      for trial = 1, 40 do
        -- the camera at c in the tag's frame (in front of it: z < 0), looking at the tag's
        -- centre, rolled at random
        local c = { rng.uniform(-1, 1), rng.uniform(-1, 1), -rng.uniform(1, 3) }
        local n = sqrt(c[1] ^ 2 + c[2] ^ 2 + c[3] ^ 2)
        local zc = { -c[1] / n, -c[2] / n, -c[3] / n } -- the optical axis, tag frame
        local up = { rng.normal(), rng.normal(), rng.normal() }
        local d = up[1] * zc[1] + up[2] * zc[2] + up[3] * zc[3]
        local xc = { up[1] - d * zc[1], up[2] - d * zc[2], up[3] - d * zc[3] }
        local m = sqrt(xc[1] ^ 2 + xc[2] ^ 2 + xc[3] ^ 2)
        xc = { xc[1] / m, xc[2] / m, xc[3] / m }
        local yc = { zc[2] * xc[3] - zc[3] * xc[2], zc[3] * xc[1] - zc[1] * xc[3],
          zc[1] * xc[2] - zc[2] * xc[1] }
        -- the tag → camera rotation has rows xc, yc, zc; t = -R c
        local r = { xc[1], xc[2], xc[3], yc[1], yc[2], yc[3], zc[1], zc[2], zc[3] }
        local t = {}
        for i = 1, 3 do
          t[i] = -(r[3 * i - 2] * c[1] + r[3 * i - 1] * c[2] + r[3 * i] * c[3])
        end
        local corners = {}
        for k, p in ipairs(geometry.tag_corners(s)) do
          local x = r[1] * p[1] + r[2] * p[2] + r[3] * p[3] + t[1]
          local y = r[4] * p[1] + r[5] * p[2] + r[6] * p[3] + t[2]
          local z = r[7] * p[1] + r[8] * p[2] + r[9] * p[3] + t[3]
          corners[k] = { camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy }
        end
        local pose = assert(tagpose.solve(corners, camera, s))
        local message = ("seed %d, trial %d"):format(SEED + 3, trial)
        local p = pose.error < 1e-6 and pose or pose.alternative
        local back = transform.inverse(p)
        assert.vector_near({ x = c[1], y = c[2], z = c[3] }, back.position, 1e-9, message)
        -- the camera's optical axis, in the tag's frame, is the third column of the inverse
        assert.vector_near(zc, { back.rotation[1][3], back.rotation[2][3], back.rotation[3][3] },
          1e-9, message)
      end
    end)
  end)

  describe("compose()", function()
    it("is the 4×4 product, a after b, for 500 random pairs", function()
      local rng = geometry.rng(SEED + 4)
      for trial = 1, 500 do
        local ra, ta = random_pose(rng)
        local rb, tb = random_pose(rng)
        local a, b = as_pose(ra, ta), as_pose(rb, tb)
        b.rotation = nil
        b.quaternion = layouts.quaternion(rb)
        assert_pose(mul4(homogeneous(ra, ta), homogeneous(rb, tb)), transform.compose(a, b),
          ("seed %d, trial %d"):format(SEED + 4, trial))
      end
    end)

    it("gives the identity with the inverse, on either side, and associates", function()
      local rng = geometry.rng(SEED + 5)
      local identity = homogeneous({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, { 0, 0, 0 })
      for trial = 1, 200 do
        local message = ("seed %d, trial %d"):format(SEED + 5, trial)
        local ra, ta = random_pose(rng)
        local rb, tb = random_pose(rng)
        local rc, tc = random_pose(rng)
        local a, b, c = as_pose(ra, ta), as_pose(rb, tb), as_pose(rc, tc)
        assert_pose(identity, transform.compose(transform.inverse(a), a), message)
        assert_pose(identity, transform.compose(a, transform.inverse(a)), message)
        local left = transform.compose(transform.compose(a, b), c)
        local right = transform.compose(a, transform.compose(b, c))
        local m = homogeneous(geometry.mul(ra, geometry.mul(rb, rc)), { 0, 0, 0 })
        m[1][4], m[2][4], m[3][4] = right.position.x, right.position.y, right.position.z
        assert_pose(m, left, message)
        assert_pose(mul4(mul4(homogeneous(ra, ta), homogeneous(rb, tb)), homogeneous(rc, tc)),
          right, message)
      end
    end)
  end)

  describe("apply()", function()
    it("is R·p + t, for points named or positional, and agrees with compose", function()
      local rng = geometry.rng(SEED + 6)
      for trial = 1, 300 do
        local message = ("seed %d, trial %d"):format(SEED + 6, trial)
        local ra, ta = random_pose(rng)
        local rb, tb = random_pose(rng)
        local p = { rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2) }
        local m = homogeneous(ra, ta)
        local expected = {}
        for i = 1, 3 do
          expected[i] = m[i][1] * p[1] + m[i][2] * p[2] + m[i][3] * p[3] + m[i][4]
        end
        local a, b = as_pose(ra, ta), as_pose(rb, tb)
        assert.vector_near(expected, transform.apply(a, { x = p[1], y = p[2], z = p[3] }), TOL,
          message)
        assert.vector_near(expected, transform.apply(a, p), TOL, message)
        -- apply(a ∘ b, p) = apply(a, apply(b, p))
        assert.vector_near(transform.apply(a, transform.apply(b, p)),
          transform.apply(transform.compose(a, b), p), TOL, message)
      end
    end)
  end)

  describe("misuse", function()
    local good = { position = { x = 1, y = 2, z = 3 }, quaternion = { w = 1, x = 0, y = 0, z = 0 } }
    local function message(f)
      return raised(f, "transform_spec.lua")
    end

    it("raises bad argument at the caller's line, naming what is wrong", function()
      assert.equal("bad argument #1 to 'inverse' (pose table expected, got nil)",
        message(function() transform.inverse(nil) end))
      assert.equal("bad argument #1 to 'inverse' (pose.position: {x =, y =, z =} of finite "
        .. "numbers expected, got nil)",
        message(function() transform.inverse({ quaternion = good.quaternion }) end))
      assert.equal("bad argument #2 to 'compose' (pose.position: {x =, y =, z =} of finite "
        .. "numbers expected, got table)", message(function()
          transform.compose(good, { position = { x = 0 / 0, y = 0, z = 0 },
            quaternion = good.quaternion })
        end))
      assert.equal("bad argument #1 to 'apply' (pose.rotation or pose.quaternion expected)",
        message(function() transform.apply({ position = good.position }, { 1, 2, 3 }) end))
      assert.equal("bad argument #2 to 'apply' (point {x =, y =, z =} or {x, y, z} of finite "
        .. "numbers expected, got table)",
        message(function() transform.apply(good, { x = 1, y = 2 }) end))
      assert.equal("bad argument #2 to 'apply' (point {x =, y =, z =} or {x, y, z} of finite "
        .. "numbers expected, got string xyz)",
        message(function() transform.apply(good, "xyz") end))
      assert.equal("bad argument #1 to 'inverse' (pose.quaternion: {w =, x =, y =, z =} of "
        .. "finite numbers, not zero, expected)", message(function()
          transform.inverse({ position = good.position, quaternion = { w = 0, x = 0, y = 0,
            z = 0 } })
        end))
    end)

    it("refuses a matrix that is not a rotation, and a rotation its quaternion contradicts",
      function()
        local scaled = { { 2, 0, 0 }, { 0, 2, 0 }, { 0, 0, 2 } }
        local mirror = { { -1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } }
        assert.equal("bad argument #1 to 'inverse' (pose.rotation: not a rotation matrix "
          .. "(largest entry of R·Rᵀ - I 3, determinant 8))", message(function()
            transform.inverse({ position = good.position, rotation = scaled })
          end))
        assert.equal("bad argument #2 to 'compose' (pose.rotation: not a rotation matrix "
          .. "(largest entry of R·Rᵀ - I 0, determinant -1))", message(function()
            transform.compose(good, { position = good.position, rotation = mirror })
          end))
        assert.equal("bad argument #1 to 'inverse' (pose.rotation: nested {{r11, r12, r13}, "
          .. "{r21, r22, r23}, {r31, r32, r33}} or flat {r11, ..., r33} of finite numbers "
          .. "expected)", message(function()
            transform.inverse({ position = good.position, rotation = { { 1, 0, 0 }, { 0, 1 },
              { 0, 0, 1 } } })
          end))
        -- a quarter turn about z against the identity quaternion
        assert.equal("bad argument #1 to 'apply' (pose.rotation and pose.quaternion disagree "
          .. "by 1.57 rad)", message(function()
            transform.apply({ position = good.position, quaternion = good.quaternion,
              rotation = { { 0, -1, 0 }, { 1, 0, 0 }, { 0, 0, 1 } } }, { 0, 0, 0 })
          end))
      end)

    it("takes a rotation orthonormal to TOLERANCE and a quaternion that agrees to it", function()
      local e = 0.5 * transform.TOLERANCE
      local p = transform.inverse({ position = good.position, quaternion = good.quaternion,
        rotation = { { 1 + 0.5 * e, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } } })
      assert.vector_near({ -1, -2, -3 }, p.position, 1e-6)
    end)
  end)
  describe("docs/conventions.md", function()
    it("prints what its pose algebra example says it prints", function()
      local text = run.read("docs/conventions.md")
      local section = text:match("\n## Pose algebra\n(.-)\n## ") or
        text:match("\n## Pose algebra\n(.*)$")
      local code = section:match("```lua\n(.-)```")
      local shown = section:match("prints[^\n]*\n\n```\n(.-)```")
      assert.is_string(code)
      assert.is_string(shown)
      local lines = {}
      local env = setmetatable({ print = function(s) lines[#lines + 1] = s end },
        { __index = _G })
      assert(compat.load_text(code, "=docs/conventions.md", env))()
      assert.equal(shown, table.concat(lines, "\n") .. "\n")
    end)
  end)
end)
