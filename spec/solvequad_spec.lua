local solvequad = require("tagpose.core.solvequad")
local square = require("tagpose.core.square")

local abs, sqrt = math.abs, math.sqrt

local function G(q, X, Y)
  return q[1] * X * X + q[2] * Y * Y + q[3] * X * Y + q[4] * X + q[5] * Y + q[6],
    q[7] * X * X + q[8] * Y * Y + q[9] * X * Y + q[10] * X + q[11] * Y + q[12]
end

-- the report's update, written out from its Algorithm solveQuad (misprint corrected)
local function report(q, X, Y, tol, n)
  for k = 0, n do
    local g1, g2 = G(q, X, Y)
    if abs(g1) <= tol and abs(g2) <= tol then return X, Y, k end
    local g1x, g1y = 2 * q[1] * X + q[3] * Y + q[4], 2 * q[2] * Y + q[3] * X + q[5]
    local g2x, g2y = 2 * q[7] * X + q[9] * Y + q[10], 2 * q[8] * Y + q[9] * X + q[11]
    local n1, n2 = sqrt(g1x * g1x + g1y * g1y), sqrt(g2x * g2x + g2y * g2y)
    local dx1, dy1, dx2, dy2 = g1x / n1, g1y / n1, g2x / n2, g2y / n2
    local d1, d2 = g1x * dx1 + g1y * dy1, g2x * dx2 + g2y * dy2
    X = X + (0 - g1) / d1 * dx1 + (0 - g2) / d2 * dx2
    Y = Y + (0 - g1) / d1 * dy1 + (0 - g2) / d2 * dy2
  end
  return nil
end

-- corners of row 56 of the noise_0.5 dev set: a nearly frontal tag on which the report's
-- update cycles for ever between the two roots of the flip pair
local camera = { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }
local cycling = { 281.08270152357755, 195.65450302409999, 285.11424763321133, 291.73892410212289,
  380.30871457613046, 288.15949463465211, 380.11629431401508, 192.58802388230248 }

local function quadratics_of(px)
  local m = {}
  for i = 1, 4 do
    m[2 * i - 1] = (px[2 * i - 1] - camera.cx) / camera.fx
    m[2 * i] = (px[2 * i] - camera.cy) / camera.fy
  end
  return square.quadratics(m), square.proximate(assert(square.shape(m)))
end

describe("tagpose.core.solvequad", function()
  -- circle X² + Y² = 1 and the line-pair quadratic X² - Y² = 0.5: roots (±√0.75, ±√0.25)
  local circle = { 1, 1, 0, 0, 0, -1, 1, -1, 0, 0, 0, -0.5 }

  -- circle X² + Y² = 1 and the line Y = X / 2, which crosses it at right angles:
  -- roots ±(2, 1) / √5
  local line = { 1, 1, 0, 0, 0, -1, 0, 0, 0, -0.5, 1, 0 }
  local r5 = 1 / sqrt(5)

  describe("solve()", function()
    it("converges to the root the start point leads to", function()
      local X, Y, k = solvequad.solve(line, 0.9, 0.2)
      assert.near(2 * r5, X, 1e-10)
      assert.near(r5, Y, 1e-10)
      assert.is_true(k > 0 and k < 10)
      X, Y = solvequad.solve(line, -0.8, -0.6)
      assert.near(-2 * r5, X, 1e-10)
      assert.near(-r5, Y, 1e-10)
    end)

    it("is the report's iteration exactly while that converges", function()
      for _, start in ipairs({ { 0.9, 0.4 }, { 0.3, -0.9 }, { -0.5, 0.7 }, { -2, 0.1 } }) do
        local X, Y, k = solvequad.solve(line, start[1], start[2], 1e-12)
        local rx, ry, rk = report(line, start[1], start[2], 1e-12, 100)
        assert.is_true(rk < solvequad.REPORT_STEPS)
        assert.equal(rx, X)
        assert.equal(ry, Y)
        assert.equal(rk, k)
      end
    end)

    it("takes no iteration when the start is a root", function()
      local X, Y, k = solvequad.solve(circle, sqrt(0.75), 0.5, 1e-12)
      assert.equal(0, k)
      assert.equal(sqrt(0.75), X)
      assert.equal(0.5, Y)
    end)

    it("still converges where the report's update is slow", function()
      -- the gradients meet at 60 degrees at the roots: the update converges linearly
      local X, Y, k = solvequad.solve(circle, 0.9, 0.4, 1e-12)
      assert.near(sqrt(0.75), X, 1e-11)
      assert.near(0.5, Y, 1e-11)
      assert.is_true(k <= solvequad.MAX_ITERATIONS)
    end)

    it("finds a root where the report's update cycles for ever", function()
      local q, X0, Y0 = quadratics_of(cycling)
      assert.is_nil(report(q, X0, Y0, 1e-10, 1000))
      local X, Y, k = solvequad.solve(q, X0, Y0)
      assert.is_number(X)
      local g1, g2 = G(q, X, Y)
      assert.is_true(abs(g1) <= 1e-10 and abs(g2) <= 1e-10)
      assert.is_true(k <= solvequad.MAX_ITERATIONS)
      -- and it is the root nearest the start
      local roots = {}
      local n = solvequad.roots(q, roots)
      for i = 1, n do
        local d = (roots[2 * i - 1] - X0) ^ 2 + (roots[2 * i] - Y0) ^ 2
        assert.is_true(d >= (X - X0) ^ 2 + (Y - Y0) ^ 2 - 1e-18)
      end
    end)

    it("survives a start where a gradient vanishes", function()
      local X, Y = solvequad.solve(circle, 0, 0) -- ∇G1 = ∇G2 = 0 at the origin
      assert.near(1, X * X + Y * Y, 1e-9)
      assert.near(0.5, X * X - Y * Y, 1e-9)
    end)

    it("reports quadratics without a real root", function()
      local none = { 1, 1, 0, 0, 0, 1, 1, -1, 0, 0, 0, 0 } -- X² + Y² = -1
      local X, err, k = solvequad.solve(none, 0.5, 0.5)
      assert.is_nil(X)
      assert.equal("solvequad: the quadratics have no real root", err)
      assert.is_true(k <= solvequad.MAX_ITERATIONS)
    end)

    it("never uses more than max_iterations", function()
      local q, X0, Y0 = quadratics_of(cycling)
      for _, limit in ipairs({ 1, 5, 29, 31, 40 }) do
        local X, err, k = solvequad.solve(q, X0, Y0, 1e-10, limit)
        if X then
          assert.is_true(err ~= nil and k <= limit)
        else
          assert.equal("solvequad: no convergence in " .. limit .. " iterations", err)
          assert.is_true(k <= limit)
        end
      end
    end)
  end)

  describe("roots()", function()
    it("finds all four intersections of two conics", function()
      local out = {}
      local n = solvequad.roots(circle, out, 1e-12)
      assert.equal(4, n)
      for i = 1, n do
        assert.near(0.75, out[2 * i - 1] ^ 2, 1e-12)
        assert.near(0.25, out[2 * i] ^ 2, 1e-12)
      end
    end)

    it("finds a tangent (double) intersection", function()
      -- circle X² + Y² = 1 and the parabola Y = X² - 1 - ... touching at (0, -1) and crossing twice
      local q = { 1, 1, 0, 0, 0, -1, 1, 0, 0, 0, -1, -1 } -- G2 = X² - Y - 1
      local out = {}
      local n = solvequad.roots(q, out, 1e-12)
      -- substituting X² = Y + 1: Y² + Y = 0, Y = 0 (X = ±1) or Y = -1 (X = 0, tangent)
      assert.is_true(n >= 3)
      local seen = {}
      for i = 1, n do
        local X, Y = out[2 * i - 1], out[2 * i]
        seen[("%.6f,%.6f"):format(X + 0, Y + 0):gsub("%-0%.000000", "0.000000")] = true
      end
      assert.is_true(seen["1.000000,0.000000"] and seen["-1.000000,0.000000"]
        and seen["0.000000,-1.000000"] or false)
    end)
  end)
end)
