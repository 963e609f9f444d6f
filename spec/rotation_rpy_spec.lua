-- Roll, pitch and yaw (tagpose.core.rotation.to_rpy, from_rpy) against formulas of their own:
-- the elementary rotations multiplied by a generic loop, the quaternion as the Hamilton product
-- of the three elementary ones, and the textbook angles away from gimbal lock.
local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")
local qmul = geometry.qmul
local assertions = require("support.assertions")

local sin, cos, pi, abs, asin = math.sin, math.cos, math.pi, math.abs, math.asin
local atan2 = require("tagpose.core.compat").atan2
local raised = assertions.raised

local SEED = 4051
local TOL = 1e-12

local function rx(t) return { { 1, 0, 0 }, { 0, cos(t), -sin(t) }, { 0, sin(t), cos(t) } } end
local function ry(t) return { { cos(t), 0, sin(t) }, { 0, 1, 0 }, { -sin(t), 0, cos(t) } } end
local function rz(t) return { { cos(t), -sin(t), 0 }, { sin(t), cos(t), 0 }, { 0, 0, 1 } } end

local function mul(a, b)
  local c = {}
  for i = 1, 3 do
    c[i] = {}
    for j = 1, 3 do
      local s = 0
      for k = 1, 3 do s = s + a[i][k] * b[k][j] end
      c[i][j] = s
    end
  end
  return c
end

local function largest_difference(a, b)
  local worst = 0
  for i = 1, 3 do
    for j = 1, 3 do
      local d = abs(a[i][j] - b[i][j])
      if d > worst then worst = d end
    end
  end
  return worst
end

local function assert_matrix(expected, actual, message)
  local d = largest_difference(expected, actual)
  assert.is_true(d <= TOL, ("%s: entries differ by %.3g"):format(message, d))
end

-- the same angle, modulo 2π
local function assert_angle(expected, actual, message)
  local d = abs(atan2(sin(expected - actual), cos(expected - actual)))
  assert.is_true(d <= TOL, ("%s: expected %.17g, got %.17g"):format(message, expected, actual))
end

describe("tagpose.core.rotation", function()
  describe("from_rpy()", function()
    it("is Rz(yaw)·Ry(pitch)·Rx(roll) multiplied out, for 1000 random angles", function()
      local rng = geometry.rng(SEED)
      for trial = 1, 1000 do
        local r, p, y = rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(-4, 4)
        assert_matrix(mul(rz(y), mul(ry(p), rx(r))), rotation.from_rpy(r, p, y),
          ("seed %d, trial %d"):format(SEED, trial))
      end
    end)

    it("has the quaternion q(yaw about z)·q(pitch about y)·q(roll about x)", function()
      local rng = geometry.rng(SEED + 1)
      for trial = 1, 300 do
        local r, p, y = rng.uniform(-pi, pi), rng.uniform(-pi, pi), rng.uniform(-pi, pi)
        local q = qmul({ cos(y / 2), 0, 0, sin(y / 2) }, qmul({ cos(p / 2), 0, sin(p / 2), 0 },
          { cos(r / 2), sin(r / 2), 0, 0 }))
        local w, x, qy, z = rotation.to_quaternion(rotation.from_nested(rotation.from_rpy(r, p, y)))
        assert.quaternion_near({ w = q[1], x = q[2], y = q[3], z = q[4] },
          { w = w, x = x, y = qy, z = z }, TOL, ("seed %d, trial %d"):format(SEED + 1, trial))
      end
    end)

    it("turns the axes as ROS's frames do: yaw a quarter turn takes x to y", function()
      local m = rotation.from_rpy(0, 0, pi / 2)
      assert.vector_near({ 0, 1, 0 }, { m[1][1], m[2][1], m[3][1] }, 1e-15)
      -- pitch a quarter turn takes x down (to -z), roll a quarter turn takes y up (to +z)
      m = rotation.from_rpy(0, pi / 2, 0)
      assert.vector_near({ 0, 0, -1 }, { m[1][1], m[2][1], m[3][1] }, 1e-15)
      m = rotation.from_rpy(pi / 2, 0, 0)
      assert.vector_near({ 0, 0, 1 }, { m[1][2], m[2][2], m[3][2] }, 1e-15)
    end)
  end)

  describe("to_rpy()", function()
    it("gives back the angles, away from gimbal lock (|pitch| < π/2 - 0.001)", function()
      local rng = geometry.rng(SEED + 2)
      for trial = 1, 1000 do
        local r, p, y = rng.uniform(-pi, pi), rng.uniform(-1, 1) * (pi / 2 - 1e-3),
          rng.uniform(-pi, pi)
        local message = ("seed %d, trial %d"):format(SEED + 2, trial)
        -- tolerance: the angles are only as good as the matrix over cos(pitch)
        local r2, p2, y2 = rotation.to_rpy(mul(rz(y), mul(ry(p), rx(r))))
        local k = 1 / cos(p)
        assert.is_true(abs(atan2(sin(r - r2), cos(r - r2))) <= k * TOL, message .. " roll")
        assert.is_true(abs(p - p2) <= k * TOL, message .. " pitch")
        assert.is_true(abs(atan2(sin(y - y2), cos(y - y2))) <= k * TOL, message .. " yaw")
        assert.is_true(p2 >= -pi / 2 and p2 <= pi / 2, message)
      end
    end)

    it("agrees with the textbook angles (atan2(r32, r33), asin(-r31), atan2(r21, r11))",
      function()
        local rng = geometry.rng(SEED + 3)
        for trial = 1, 500 do
          local m = geometry.nested(geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
            rng.uniform(0, pi)))
          if abs(m[3][1]) < 0.9 then
            local message = ("seed %d, trial %d"):format(SEED + 3, trial)
            local r, p, y = rotation.to_rpy(m)
            assert_angle(atan2(m[3][2], m[3][3]), r, message .. " roll")
            assert_angle(asin(-m[3][1]), p, message .. " pitch")
            assert_angle(atan2(m[2][1], m[1][1]), y, message .. " yaw")
          end
        end
      end)

    it("gives angles whose rotation is R, for 1000 random rotations, nested and flat", function()
      local rng = geometry.rng(SEED + 4)
      for trial = 1, 1000 do
        local flat = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
          rng.uniform(0, pi))
        local m = geometry.nested(flat)
        local message = ("seed %d, trial %d"):format(SEED + 4, trial)
        assert_matrix(m, rotation.from_rpy(rotation.to_rpy(m)), message)
        local a, b, c = rotation.to_rpy(m)
        local d, e, f = rotation.to_rpy(flat)
        assert.same({ a, b, c }, { d, e, f }, message)
      end
    end)

    it("handles gimbal lock: pitch ±π/2, yaw 0, roll carrying the turn, R given back", function()
      local rng = geometry.rng(SEED + 5)
      for trial = 1, 200 do
        local r, y = rng.uniform(-pi, pi), rng.uniform(-pi, pi)
        local message = ("seed %d, trial %d"):format(SEED + 5, trial)
        for _, sign in ipairs({ 1, -1 }) do
          local m = mul(rz(y), mul(ry(sign * pi / 2), rx(r)))
          local r2, p2, y2 = rotation.to_rpy(m)
          assert.equal(0, y2, message)
          assert_angle(sign * pi / 2, p2, message)
          -- at +π/2, R depends on roll - yaw; at -π/2 on roll + yaw
          assert_angle(sign > 0 and r - y or r + y, r2, message)
          assert_matrix(m, rotation.from_rpy(r2, p2, y2), message)
        end
      end
    end)

    it("gives R back near gimbal lock too (pitch within 1e-16 to 1e-3 of ±π/2)", function()
      local rng = geometry.rng(SEED + 6)
      for trial = 1, 400 do
        local r, y = rng.uniform(-pi, pi), rng.uniform(-pi, pi)
        local p = (trial % 2 == 0 and 1 or -1) * (pi / 2 - 10 ^ rng.uniform(-16, -3))
        local m = mul(rz(y), mul(ry(p), rx(r)))
        local r2, p2, y2 = rotation.to_rpy(m)
        assert_matrix(m, rotation.from_rpy(r2, p2, y2), ("seed %d, trial %d"):format(SEED + 6,
          trial))
      end
    end)
  end)

  describe("misuse", function()
    local function message(f)
      return raised(f, "rotation_rpy_spec.lua")
    end

    it("raises bad argument at the caller's line", function()
      local expected = "bad argument #1 to 'to_rpy' (rotation matrix expected: nested {{r11, "
        .. "r12, r13}, {r21, r22, r23}, {r31, r32, r33}} or flat {r11, ..., r33} of finite "
        .. "numbers)"
      assert.equal(expected, message(function() rotation.to_rpy(nil) end))
      assert.equal(expected, message(function() rotation.to_rpy({ 1, 0, 0, 0, 1, 0, 0, 0 }) end))
      assert.equal(expected, message(function()
        rotation.to_rpy({ { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 0 / 0 } })
      end))
      assert.equal("bad argument #1 to 'to_rpy' (not a rotation matrix (largest entry of R·Rᵀ "
        .. "- I 0, determinant -1))", message(function()
          rotation.to_rpy({ { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, -1 } })
        end))
      assert.equal("bad argument #2 to 'from_rpy' (finite number expected, got nil)",
        message(function() rotation.from_rpy(0) end))
      assert.equal("bad argument #3 to 'from_rpy' (finite number expected, got string 1)",
        message(function() rotation.from_rpy(0, 0, "1") end))
      assert.equal("bad argument #1 to 'from_rpy' (finite number expected, got number inf)",
        message(function() rotation.from_rpy(math.huge, 0, 0) end))
    end)
  end)
end)
