local poly = require("tagpose.core.poly")

-- the polynomial with the given roots (and leading coefficient 1), constant first
local function from_roots(roots)
  local c = { 1 }
  for _, r in ipairs(roots) do
    local nc = {}
    for k = 1, #c + 1 do nc[k] = (c[k - 1] or 0) - r * (c[k] or 0) end
    c = nc
  end
  return c
end

describe("tagpose.core.poly", function()
  describe("roots()", function()
    it("finds the real roots of quartics", function()
      local out = {}
      local n = poly.roots(from_roots({ 1, 2, 3, 4 }), 4, out)
      assert.equal(4, n)
      for i = 1, 4 do assert.near(i, out[i], 1e-12) end
      -- (y² + 1)(y - 1)(y + 2) = y^4 + y^3 - y^2 + y - 2
      n = poly.roots({ -2, 1, -1, 1, 1 }, 4, out)
      assert.equal(2, n)
      assert.near(-2, out[1], 1e-12)
      assert.near(1, out[2], 1e-12)
      -- no real root: y^4 + 1
      assert.equal(0, poly.roots({ 1, 0, 0, 0, 1 }, 4, out))
    end)

    it("finds every real root up to degree 6, spread or clustered", function()
      local out = {}
      for _, roots in ipairs({ { -3, -1, 0.5, 2, 7, 11 }, { 0.1, 0.2, 0.3, 0.4, 0.5 },
        { -1e3, 1e-3, 1, 2, 3 }, { 5 } }) do
        local n = poly.roots(from_roots(roots), #roots, out)
        assert.equal(#roots, n)
        for i = 1, n do assert.near(roots[i], out[i], 1e-9 * (1 + math.abs(roots[i]))) end
      end
    end)

    it("drops vanishing leading coefficients and counts a double root once", function()
      local out = {}
      -- 2 - 3y + y² with two vanishing higher coefficients
      assert.equal(2, poly.roots({ 2, -3, 1, 0, 0 }, 4, out))
      assert.near(1, out[1], 1e-14)
      assert.near(2, out[2], 1e-14)
      -- (y - 1)² (y + 1): the double root at a critical point
      local n = poly.roots(from_roots({ 1, 1, -1 }), 3, out)
      assert.equal(2, n)
      assert.near(-1, out[1], 1e-12)
      assert.near(1, out[2], 1e-6)
    end)
  end)

  describe("value()", function()
    it("evaluates by Horner's rule", function()
      assert.equal(2 - 3 * 5 + 25, poly.value({ 2, -3, 1 }, 2, 5))
    end)
  end)
end)
