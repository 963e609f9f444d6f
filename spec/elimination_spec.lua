local elimination = require("support.elimination")
local lsq = require("tagpose.core.lsq")
local linsolve = require("tagpose.layout.linsolve")

-- residual max |a x - b| of the original system
local function residual(n, a, x, b, nrhs)
  nrhs = nrhs or 1
  local worst = 0
  for i = 1, n do
    for k = 1, nrhs do
      local s = -b[(i - 1) * nrhs + k]
      for j = 1, n do
        s = s + a[(i - 1) * n + j] * x[(j - 1) * nrhs + k]
      end
      worst = math.max(worst, math.abs(s))
    end
  end
  return worst
end

local function copy(t)
  local c = {}
  for i = 1, #t do c[i] = t[i] end
  return c
end

describe("support.elimination, tagpose.lsq.spd6() and tagpose.linsolve", function()
  describe("solve()", function()
    it("solves a system whose first pivot is zero (needs a row swap)", function()
      local a = { 0, 2, 1,
                  1, 1, 1,
                  2, 1, 0 }
      local b = { 5, 4, 4 } -- x = (1, 2, 1)
      local x = assert(elimination.solve(3, copy(a), copy(b)))
      assert.near(1, x[1], 1e-14)
      assert.near(2, x[2], 1e-14)
      assert.near(1, x[3], 1e-14)
    end)

    it("stays accurate where elimination without pivoting loses every digit", function()
      -- a tiny first pivot: without the swap, 1 - 1/eps swamps the second row
      local eps = 1e-17
      local a = { eps, 1,
                  1,   1 }
      local b = { 1, 2 } -- x ~ (1, 1)
      local x = assert(elimination.solve(2, copy(a), copy(b)))
      assert.near(1, x[1], 1e-15)
      assert.near(1, x[2], 1e-15)
    end)

    it("solves several right-hand sides at once", function()
      local a = { 4, -2, 1, 3, 6, -4, 2, 1, 8 }
      local b = { 1, 0, 0, 0, 1, 0, 0, 0, 1 } -- the inverse
      local x = assert(elimination.solve(3, copy(a), copy(b), 3))
      assert.is_true(residual(3, a, x, b, 3) < 1e-14)
    end)

    it("solves random 8x8 systems to round-off", function()
      local s = 12345
      local function rand()
        s = (16807 * s) % 2147483647
        return s / 2147483647 - 0.5
      end
      for _ = 1, 50 do
        local a, b = {}, {}
        for i = 1, 64 do a[i] = rand() end
        for i = 1, 8 do b[i] = rand() end
        local x = assert(elimination.solve(8, copy(a), copy(b)))
        assert.is_true(residual(8, a, x, b) < 1e-12)
      end
    end)

    it("reports a singular matrix instead of dividing by zero", function()
      local a = { 1, 2, 3,
                  2, 4, 6,
                  1, 0, 1 }
      local x, err = elimination.solve(3, a, { 1, 2, 3 })
      assert.is_nil(x)
      assert.equal("elimination: matrix is singular", err)
    end)

    it("reports a matrix singular to working precision", function()
      local a = { 1, 1,
                  1, 1 + 1e-15 }
      local x, err = elimination.solve(2, a, { 1, 2 })
      assert.is_nil(x)
      assert.equal("elimination: matrix is singular", err)
    end)

    it("reports the zero matrix and non-finite entries", function()
      assert.same({ nil, "elimination: matrix is singular" },
        { elimination.solve(2, { 0, 0, 0, 0 }, { 1, 1 }) })
      assert.same({ nil, "elimination: matrix is not finite" },
        { elimination.solve(2, { 1, 0, 0, 0 / 0 }, { 1, 1 }) })
      assert.same({ nil, "elimination: matrix is not finite" },
        { elimination.solve(2, { 1, 0, 0, math.huge }, { 1, 1 }) })
    end)
  end)

  describe("spd6()", function()
    local function random_spd(rand)
      -- A = M Mᵀ + 0.1 I for a random M: symmetric positive definite
      local m, a = {}, {}
      for i = 1, 36 do m[i] = rand() end
      for i = 1, 6 do
        for j = 1, 6 do
          local v = i == j and 0.1 or 0
          for k = 1, 6 do v = v + m[(i - 1) * 6 + k] * m[(j - 1) * 6 + k] end
          a[(i - 1) * 6 + j] = v
        end
      end
      return a
    end
    local function upper(a)
      local u = {}
      for i = 1, 6 do
        for j = i, 6 do u[#u + 1] = a[(i - 1) * 6 + j] end
      end
      return u
    end

    it("solves random symmetric positive definite systems to round-off", function()
      local s = 777
      local function rand()
        s = (16807 * s) % 2147483647
        return s / 2147483647 - 0.5
      end
      for _ = 1, 50 do
        local a = random_spd(rand)
        local b = {}
        for i = 1, 6 do b[i] = rand() end
        local u = upper(a)
        local x = { lsq.spd6(u[1], u[2], u[3], u[4], u[5], u[6], u[7], u[8], u[9], u[10],
          u[11], u[12], u[13], u[14], u[15], u[16], u[17], u[18], u[19], u[20], u[21],
          b[1], b[2], b[3], b[4], b[5], b[6]) }
        assert.equal(6, #x)
        assert.is_true(residual(6, a, x, b) < 1e-10)
      end
    end)

    it("does not care about the units of the unknowns", function()
      -- the same system with unknown 4 in units a million times smaller
      local a = { 4, 1, 0, 2e6, 0, 0,  1, 3, 0, 0, 0, 0,  0, 0, 2, 0, 0, 0,
                  2e6, 0, 0, 5e12, 0, 0,  0, 0, 0, 0, 1, 0,  0, 0, 0, 0, 0, 1 }
      local u = upper(a)
      local x = { lsq.spd6(u[1], u[2], u[3], u[4], u[5], u[6], u[7], u[8], u[9], u[10],
        u[11], u[12], u[13], u[14], u[15], u[16], u[17], u[18], u[19], u[20], u[21],
        1, 2, 3, 4e6, 5, 6) }
      assert.equal(6, #x)
      assert.is_true(residual(6, a, x, { 1, 2, 3, 4e6, 5, 6 }) < 1e-6)
    end)

    it("reports a matrix that is not positive definite", function()
      assert.is_nil(lsq.spd6(1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0,
        1, 1, 1, 1, 1, 1))
      assert.is_nil(lsq.spd6(1, 2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 1,
        1, 1, 1, 1, 1, 1))
      assert.is_nil(lsq.spd6(0 / 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 1,
        1, 1, 1, 1, 1, 1))
    end)
  end)

  describe("cholesky()", function()
    it("solves a symmetric positive definite system", function()
      local a = { 4, 2, 0.4,
                  2, 5, 1,
                  0.4, 1, 3 }
      local b = { 1, 2, 3 }
      local x = assert(linsolve.cholesky(3, copy(a), copy(b)))
      assert.is_true(residual(3, a, x, b) < 1e-14)
    end)

    it("reports a matrix that is not positive definite", function()
      local x, err = linsolve.cholesky(2, { 1, 2, 2, 1 }, { 1, 1 })
      assert.is_nil(x)
      assert.equal("linsolve: matrix is not positive definite", err)
      assert.same({ nil, "linsolve: matrix is not positive definite" },
        { linsolve.cholesky(2, { 1, 1, 1, 1 }, { 1, 1 }) })
    end)
  end)
end)
