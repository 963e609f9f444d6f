local tagpose = require("tagpose")
local cube = require("tagpose.rigid.cube")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local layouts = require("support.layouts")
local FACES = require("support.faces").FACES

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

describe("tagpose.rigid.cube", function()
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

  describe("face names", function()
    it("name each face by its outward normal, and a tag's face by its frame", function()
      assert.same({ "+x", "-x", "+y", "-y", "+z", "-z" }, cube.FACE_NAMES)
      for _, name in ipairs(cube.FACE_NAMES) do
        local n = cube.NORMALS[name]
        local axis = ({ x = 1, y = 2, z = 3 })[name:sub(2)]
        local sign = name:sub(1, 1) == "+" and 1 or -1
        for i = 1, 3 do assert.equal(i == axis and sign or 0, n[i]) end
        assert.equal(name, cube.face_name(n[1], n[2], n[3]))
      end
      -- a tag's z axis points into the block: its face's outward normal is -G·e_z
      local count = {}
      for _, g in ipairs(cube.ROTATIONS) do
        local name = cube.face_of(g)
        local n = cube.NORMALS[name]
        assert.same({ -n[1], -n[2], -n[3] }, { g[3], g[6], g[9] })
        count[name] = (count[name] or 0) + 1
      end
      -- four turns on each face
      for _, name in ipairs(cube.FACE_NAMES) do assert.equal(4, count[name]) end
    end)
  end)

  describe("of_nested()", function()
    it("finds a nested rotation of the cube, and nothing else", function()
      for k, g in ipairs(cube.ROTATIONS) do
        assert.equal(k, cube.of_nested({ { g[1], g[2], g[3] }, { g[4], g[5], g[6] },
          { g[7], g[8], g[9] } }))
      end
      local off = geometry.axis_angle(1, 2, 3, 1e-3)
      local nested = { { off[1], off[2], off[3] }, { off[4], off[5], off[6] },
        { off[7], off[8], off[9] } }
      assert.is_nil(cube.of_nested(nested))
      assert.equal(1, cube.of_nested(nested, 2e-3))
      assert.is_nil(cube.of_nested({ { 2, 0, 0 }, { 0, 2, 0 }, { 0, 0, 2 } }, 0.1))
      assert.is_nil(cube.of_nested({ { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 0 / 0 } }))
      assert.is_nil(cube.of_nested({ { 1, 0, 0 }, { 0, 1, 0 } }))
      assert.is_nil(cube.of_nested("+x"))
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

describe("tagpose.layout.cube()", function()
  local function raised(f) return assertions.raised(f, "cube_spec.lua") end

  it("puts the lab's tags on the faces: centred, z into the block, upright on the sides",
    function()
      local layout = tagpose.layout.cube(0.024, 0.055)
      -- ids 0 to 5 on +x, -x, +y, -y, +z, -z
      for i, f in ipairs(FACES) do
        local e = layout.tags[i - 1]
        assert.equal(0.024, e.size)
        assert.rotation_near(f.r, layouts.matrix(e.quaternion), 1e-12)
        assert.vector_near({ 0.0275 * f.n[1], 0.0275 * f.n[2], 0.0275 * f.n[3] }, e.position, 0)
      end
    end)

  it("takes faces by name or turned, and sizes by id", function()
    local turned = geometry.mul(FACES[5].r, geometry.axis_angle(0, 0, 1, math.pi / 2))
    local nested = { { turned[1], turned[2], turned[3] }, { turned[4], turned[5], turned[6] },
      { turned[7], turned[8], turned[9] } }
    local layout = tagpose.layout.cube({ [7] = 0.03, default = 0.02 }, 0.05,
      { [7] = "-y", [8] = nested })
    assert.equal(0.03, layout.tags[7].size)
    assert.equal(0.02, layout.tags[8].size)
    assert.rotation_near(FACES[4].r, layouts.matrix(layout.tags[7].quaternion), 1e-12)
    assert.rotation_near(turned, layouts.matrix(layout.tags[8].quaternion), 1e-12)
    assert.vector_near({ 0, 0, 0.025 }, layout.tags[8].position, 0)
    assert.is_nil(layout.tags[0])
  end)

  it("refuses bad sizes and faces", function()
    for _, case in ipairs({
      { function() tagpose.layout.cube(-1, 0.05) end,
        "bad argument #1 to 'cube' (positive number expected for tag_size, got number -1)" },
      { function() tagpose.layout.cube(0.06, 0.05) end,
        "bad argument #2 to 'cube' (number above tag_size expected for block_size, got "
          .. "number 0.05)" },
      { function() tagpose.layout.cube(0.02, 0.05, { [1] = "top" }) end,
        "bad argument #3 to 'cube' (faces[1]: face '+x', '-x', '+y', '-y', '+z' or '-z', or a "
          .. "3x3 rotation of the cube, expected)" },
      { function() tagpose.layout.cube({ [1] = 0.02 }, 0.05, { [2] = "+x" }) end,
        "bad argument #1 to 'cube' (tag_size has no size for tag id 2 and no default)" },
    }) do
      assert.equal(case[2], raised(case[1]))
    end
  end)
end)
