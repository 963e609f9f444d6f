local cube = require("tagpose.layout.cube")
local geometry = require("support.geometry")
local assertions = require("support.assertions")

local rad, abs = math.rad, math.abs

local function det(g)
  return g[1] * (g[5] * g[9] - g[6] * g[8]) - g[2] * (g[4] * g[9] - g[6] * g[7])
    + g[3] * (g[4] * g[8] - g[5] * g[7])
end

local function key(g)
  return table.concat(g, ",")
end

local function random_rotation(rng)
  return geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), rng.uniform(0, math.pi))
end

describe("tagpose.layout.cube", function()
  describe("ROTATIONS", function()
    it("are the 24 distinct proper signed permutations, identity first", function()
      assert.equal(24, #cube.ROTATIONS)
      assert.same({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, cube.ROTATIONS[1])
      local seen = {}
      for _, g in ipairs(cube.ROTATIONS) do
        assert.equal(1, det(g))
        local nonzero = 0
        for i = 1, 9 do
          assert.is_true(g[i] == 0 or abs(g[i]) == 1)
          if g[i] ~= 0 then nonzero = nonzero + 1 end
        end
        assert.equal(3, nonzero)
        assert.is_nil(seen[key(g)])
        seen[key(g)] = true
      end
    end)

    it("have their inverses listed in INVERSE", function()
      for k, g in ipairs(cube.ROTATIONS) do
        assert.same({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, geometry.mul(g, cube.ROTATIONS[cube.INVERSE[k]]))
      end
    end)

    it("are closed under composition", function()
      local index = {}
      for i, g in ipairs(cube.ROTATIONS) do index[key(g)] = i end
      for _, a in ipairs(cube.ROTATIONS) do
        for _, b in ipairs(cube.ROTATIONS) do
          assert.is_number(index[key(geometry.mul(a, b))])
        end
      end
    end)
  end)

  describe("FACES", function()
    it("carry a tag whose z points into the block, upright on the side faces", function()
      local names = 0
      for name, f in pairs(cube.FACES) do
        names = names + 1
        local r, n = f.rotation, f.normal
        assert.equal(1, det(r))
        assert.same({ -n[1], -n[2], -n[3] }, { r[3], r[6], r[9] })
        if n[3] == 0 then assert.same({ 0, 0, -1 }, { r[2], r[5], r[8] }) end
        assert.equal(1, cube.nearest(geometry.mul(r, { r[1], r[4], r[7], r[2], r[5], r[8],
          r[3], r[6], r[9] })))
        assert.equal(name, cube.face_of(r))
      end
      assert.equal(6, names)
      assert.same({ 1, 0, 0, 0, -1, 0, 0, 0, -1 }, cube.FACES["+z"].rotation)
    end)
  end)

  describe("nearest()", function()
    it("rounds a rotation near one of the 24 to it, with the angle between", function()
      local rng = geometry.rng(3)
      for k, g in ipairs(cube.ROTATIONS) do
        local angle = rad(rng.uniform(0, 40))
        local r = geometry.mul(g, geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
          angle))
        local i, a = cube.nearest(r)
        assert.equal(k, i)
        assert.near(angle, a, 1e-9)
      end
    end)
  end)

  describe("nearest() on any matrix", function()
    it("maximises trace(Gᵀ·r) over the 24, as a search of all of them does", function()
      local rng = geometry.rng(6)
      for _ = 1, 500 do
        local r = {}
        for i = 1, 9 do r[i] = rng.normal() end
        local score = -math.huge
        for _, g in ipairs(cube.ROTATIONS) do
          local s = 0
          for i = 1, 9 do s = s + g[i] * r[i] end
          if s > score then score = s end
        end
        local k = cube.nearest(r)
        local s = 0
        for i = 1, 9 do s = s + cube.ROTATIONS[k][i] * r[i] end
        assert.near(score, s, 1e-12)
      end
    end)
  end)

  describe("closest()", function()
    it("gives the symmetric equivalent nearest a reference", function()
      local rng = geometry.rng(4)
      for _ = 1, 50 do
        local r = random_rotation(rng)
        local g = cube.ROTATIONS[1 + math.floor(rng.uniform() * 24)]
        local ref = geometry.mul(geometry.mul(r, g), geometry.axis_angle(1, 2, 3, rad(10)))
        local out = cube.closest(r, ref, {})
        assert.rotation_near(geometry.mul(r, g), out, 1e-9)
      end
    end)
  end)

  describe("canonical()", function()
    it("is the same frame from any of the 24 equivalents", function()
      local rng = geometry.rng(5)
      for _ = 1, 50 do
        local r = random_rotation(rng)
        local up = { rng.normal(), rng.normal(), rng.normal() }
        local ahead = { rng.normal(), rng.normal(), rng.normal() }
        local c = cube.canonical(r, up[1], up[2], up[3], ahead[1], ahead[2], ahead[3], {})
        for _, g in ipairs(cube.ROTATIONS) do
          local e = cube.canonical(geometry.mul(r, g), up[1], up[2], up[3], ahead[1], ahead[2],
            ahead[3], {})
          assert.rotation_near(c, e, 1e-9)
        end
        -- a rotation, an equivalent of r, z the face axis nearest up, x nearest ahead
        assert.near(1, det(c), 1e-12)
        local _, angle = cube.nearest(geometry.mul({ r[1], r[4], r[7], r[2], r[5], r[8], r[3],
          r[6], r[9] }, c))
        assert.is_true(angle < 1e-6)
        local zu = c[3] * up[1] + c[6] * up[2] + c[9] * up[3]
        for k = 1, 3 do
          assert.is_true(zu >= abs(c[k] * up[1] + c[3 + k] * up[2] + c[6 + k] * up[3]) - 1e-12)
        end
        local xa = c[1] * ahead[1] + c[4] * ahead[2] + c[7] * ahead[3]
        assert.is_true(xa >= abs(c[2] * ahead[1] + c[5] * ahead[2] + c[8] * ahead[3]) - 1e-12)
      end
      assert.is_table(assertions)
    end)
  end)
end)
