local rotation = require("tagpose.core.rotation")
local geometry = require("support.geometry")

local sin, cos, pi, sqrt = math.sin, math.cos, math.pi, math.sqrt

local function quat(w, x, y, z)
  local n = sqrt(w * w + x * x + y * y + z * z)
  return { w = w / n, x = x / n, y = y / n, z = z / n }
end

local function to_q(r)
  local w, x, y, z = rotation.to_quaternion(r)
  return { w = w, x = x, y = y, z = z }
end

-- single-axis rotations written out by hand
local function rx(t) return { 1, 0, 0, 0, cos(t), -sin(t), 0, sin(t), cos(t) } end
local function ry(t) return { cos(t), 0, sin(t), 0, 1, 0, -sin(t), 0, cos(t) } end
local function rz(t) return { cos(t), -sin(t), 0, sin(t), cos(t), 0, 0, 0, 1 } end

describe("tagpose.core.rotation", function()
  describe("to_quaternion() and from_quaternion()", function()
    it("round-trip axes in every octant, at small, middle and near-half-turn angles", function()
      for sx = -1, 1, 2 do
        for sy = -1, 1, 2 do
          for sz = -1, 1, 2 do
            for _, angle in ipairs({ 1e-9, 0.3, 1.5, 3, pi - 1e-7 }) do
              local ax, ay, az = sx * 0.3, sy * 0.5, sz * 0.8
              local n = sqrt(ax * ax + ay * ay + az * az)
              local s = sin(angle / 2) / n
              local q = quat(cos(angle / 2), ax * s, ay * s, az * s)
              local r = rotation.from_quaternion(q.w, q.x, q.y, q.z)
              local back = to_q(r)
              assert.quaternion_near(q, back, 1e-14)
              assert.is_true(back.w >= 0)
            end
          end
        end
      end
    end)

    it("takes the half turns about every axis and diagonal (w = 0)", function()
      for _, axis in ipairs({ { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 }, { 1, 1, 0 }, { 0, -1, 1 },
        { 1, 1, 1 }, { -1, 2, -3 } }) do
        local r = geometry.axis_angle(axis[1], axis[2], axis[3], pi)
        local n = sqrt(axis[1] ^ 2 + axis[2] ^ 2 + axis[3] ^ 2)
        assert.quaternion_near(quat(0, axis[1] / n, axis[2] / n, axis[3] / n), to_q(r), 1e-14)
      end
    end)

    it("keeps full precision just short of a half turn (where the trace formula fails)", function()
      local angle = pi - 1e-6
      local r = geometry.axis_angle(0.2, -0.4, 0.9, angle)
      local n = sqrt(0.2 ^ 2 + 0.4 ^ 2 + 0.9 ^ 2)
      local s = sin(angle / 2) / n
      assert.quaternion_near(quat(cos(angle / 2), 0.2 * s, -0.4 * s, 0.9 * s), to_q(r), 1e-14)
    end)

    it("gives yaw, pitch and roll about one axis", function()
      for _, t in ipairs({ -2.5, -0.7, 0.1, 1.2, 3.0 }) do
        local c, s = cos(t / 2), sin(t / 2)
        local sign = c < 0 and -1 or 1
        assert.quaternion_near(quat(c, s, 0, 0), to_q(rx(t)), 1e-15)
        assert.quaternion_near(quat(c, 0, s, 0), to_q(ry(t)), 1e-15)
        assert.quaternion_near(quat(c, 0, 0, s), to_q(rz(t)), 1e-15)
        assert.is_true(sign * c >= 0)
        local r = rotation.from_quaternion(c, 0, 0, s)
        for i = 1, 9 do assert.near(rz(t)[i], r[i], 1e-15) end
      end
    end)

    it("normalises a quaternion that is not unit", function()
      local r = rotation.from_quaternion(2, 0, 0, 2)
      for i, v in ipairs(rz(pi / 2)) do assert.near(v, r[i], 1e-15) end
    end)
  end)

  describe("to_rotation_vector()", function()
    it("gives axis times angle of single-axis rotations", function()
      assert.vector_near({ 0, 0.8, 0 }, { rotation.to_rotation_vector(ry(0.8)) }, 1e-15)
      assert.vector_near({ -0.8, 0, 0 }, { rotation.to_rotation_vector(rx(-0.8)) }, 1e-15)
      assert.same({ 0, 0, 0 }, { rotation.to_rotation_vector({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }) })
    end)

    it("inverts from_rotation_vector(), including the half turn and tiny angles", function()
      for _, case in ipairs({ { 1, 2, 3, 0.5 }, { -1, 0, 1, pi }, { 0, 0, 1, 1e-12 },
        { 0.3, -0.7, 0.1, 3 } }) do
        local n = sqrt(case[1] ^ 2 + case[2] ^ 2 + case[3] ^ 2)
        local k = case[4] / n
        local r = geometry.axis_angle(case[1], case[2], case[3], case[4])
        local wx, wy, wz = rotation.to_rotation_vector(r)
        local a = sqrt(wx * wx + wy * wy + wz * wz)
        assert.near(case[4], a, 1e-14)
        local sign = (wx * case[1] + wy * case[2] + wz * case[3]) >= 0 and 1 or -1
        assert.vector_near({ sign * k * case[1], sign * k * case[2], sign * k * case[3] },
          { wx, wy, wz }, 1e-7 * case[4] + 1e-20)
        assert.rotation_near(r, rotation.from_rotation_vector(wx, wy, wz), 1e-12)
      end
    end)
  end)

  describe("from_rotation_vector()", function()
    it("agrees with the axis-angle form, large and tiny", function()
      for _, v in ipairs({ { 0.3, -0.2, 0.9 }, { 1e-5, 2e-5, -1e-5 }, { 1e-12, 0, 0 },
        { 2, 1, -1 } }) do
        local n = sqrt(v[1] ^ 2 + v[2] ^ 2 + v[3] ^ 2)
        local expected = geometry.axis_angle(v[1], v[2], v[3], n)
        assert.rotation_near(expected, rotation.from_rotation_vector(v[1], v[2], v[3]), 1e-12)
      end
    end)
  end)

  describe("angle()", function()
    it("measures small and large angles between rotations", function()
      local a = geometry.axis_angle(1, 2, 2, 0.7)
      for _, t in ipairs({ 1e-10, 1e-6, 0.5, 3 }) do
        local b = rotation.multiply(a, geometry.axis_angle(0.3, -1, 0.2, t))
        assert.near(t, rotation.angle(a, b), 1e-15 + 1e-13 * t)
      end
    end)
  end)

  describe("multiply() and transpose()", function()
    it("compose rotations and invert them", function()
      local a, b = rx(0.4), rz(-1.1)
      local ab = rotation.multiply(a, b)
      local id = rotation.multiply(ab, rotation.transpose(ab))
      for i, v in ipairs({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }) do assert.near(v, id[i], 1e-15) end
      -- out may alias an input
      local c = {}
      for i = 1, 9 do c[i] = a[i] end
      rotation.multiply(c, b, c)
      assert.rotation_near(ab, c, 1e-12)
    end)
  end)

  describe("multiply_transpose() and transpose_multiply()", function()
    it("are a·bᵀ and aᵀ·b, also in place", function()
      local a = geometry.axis_angle(0.2, 0.9, -0.4, 1.1)
      local b = geometry.axis_angle(-0.7, 0.1, 0.5, 2.3)
      local abt = rotation.multiply(a, rotation.transpose(b))
      local atb = rotation.multiply(rotation.transpose(a), b)
      local got = rotation.multiply_transpose(a, b)
      for i = 1, 9 do assert.near(abt[i], got[i], 1e-15) end
      got = rotation.transpose_multiply(a, b)
      for i = 1, 9 do assert.near(atb[i], got[i], 1e-15) end
      local c = {}
      for i = 1, 9 do c[i] = a[i] end
      rotation.transpose_multiply(c, b, c)
      for i = 1, 9 do assert.near(atb[i], c[i], 1e-15) end
    end)
  end)

  describe("orthonormalise()", function()
    it("turns a perturbed rotation into the nearby proper rotation", function()
      local r = geometry.axis_angle(0.5, -0.5, 1, 1.3)
      local p = {}
      for i = 1, 9 do p[i] = r[i] * 1.3 end
      p[1], p[4] = p[1] + 1e-4, p[4] - 2e-4 -- column 1 off by a small angle
      local o = assert(rotation.orthonormalise(p))
      local t = rotation.multiply(rotation.transpose(o), o)
      for i, v in ipairs({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }) do assert.near(v, t[i], 1e-15) end
      assert.rotation_near(r, o, 0.02)
      local det = o[1] * (o[5] * o[9] - o[6] * o[8]) - o[2] * (o[4] * o[9] - o[6] * o[7])
        + o[3] * (o[4] * o[8] - o[5] * o[7])
      assert.near(1, det, 1e-15)
    end)

    it("turns both columns by half their deviation from a right angle", function()
      -- columns at 80 degrees in the x-y plane, symmetric about the diagonal
      local h = math.rad(40)
      local x = { cos(math.rad(45) - h), sin(math.rad(45) - h), 0 }
      local y = { cos(math.rad(45) + h), sin(math.rad(45) + h), 0 }
      local o = assert(rotation.orthonormalise({ x[1], y[1], 0, x[2], y[2], 0, x[3], y[3], 0 }))
      assert.rotation_near({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, o, 1e-12)
    end)

    it("reports zero and parallel columns", function()
      assert.same({ nil, "rotation: zero column" },
        { rotation.orthonormalise({ 0, 1, 0, 0, 0, 0, 0, 0, 0 }) })
      assert.same({ nil, "rotation: columns are parallel" },
        { rotation.orthonormalise({ 1, 2, 0, 1, 2, 0, 0, 0, 0 }) })
    end)
  end)

  describe("to_nested() and from_nested()", function()
    it("convert between flat and nested layouts", function()
      local flat = { 1, 2, 3, 4, 5, 6, 7, 8, 9 }
      local nested = rotation.to_nested(flat)
      assert.same({ { 1, 2, 3 }, { 4, 5, 6 }, { 7, 8, 9 } }, nested)
      assert.same(flat, rotation.from_nested(nested))
    end)
  end)

  describe("of_pose()", function()
    it("reads a pose's rotation, else its quaternion, and nothing else", function()
      -- a quarter turn about z: x -> y
      local r = { 0, -1, 0, 1, 0, 0, 0, 0, 1 }
      local nested = rotation.to_nested(r)
      assert.rotation_near(r, rotation.of_pose({ rotation = nested }), 1e-12)
      local h = math.sqrt(0.5)
      -- a quaternion of any length is normalised
      assert.rotation_near(r, rotation.of_pose({ quaternion = { w = 2 * h, x = 0, y = 0,
        z = 2 * h } }), 1e-12)
      -- the rotation wins; a rotation with a NaN falls back to the quaternion
      local q_id = { w = 1, x = 0, y = 0, z = 0 }
      assert.rotation_near(r, rotation.of_pose({ rotation = nested, quaternion = q_id }), 1e-12)
      assert.rotation_near({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, rotation.of_pose({
        rotation = { { 0 / 0, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } }, quaternion = q_id }), 1e-12)
      for _, bad in ipairs({ {}, 5, { quaternion = { w = 0, x = 0, y = 0, z = 0 } },
        { quaternion = { w = 1, x = 0, y = 0, z = math.huge } }, { rotation = { 1, 2, 3 } } }) do
        assert.is_nil(rotation.of_pose(bad))
      end
    end)
  end)
end)
