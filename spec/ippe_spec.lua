local ippe = require("tagpose.core.ippe")
local square = require("tagpose.core.square")
local refine = require("tagpose.core.refine")
local geometry = require("support.geometry")

local cameras = {
  { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5, width = 640, height = 480 },
  { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5, width = 320, height = 240 },
  { fx = 1210.3, fy = 1195.7, cx = 655.2, cy = 351.9, width = 1280, height = 720 },
}

-- normalised corners of an exact projection, and the proximate depths
local function corners(camera, r, t, s)
  local px = geometry.project(camera, r, t, s)
  if not px then return nil end
  local m = {}
  for i = 1, 4 do
    m[2 * i - 1], m[2 * i] = (px[i][1] - camera.cx) / camera.fx, (px[i][2] - camera.cy) / camera.fy
  end
  return m, square.shape(m)
end

local function max_diff(a, b)
  local d = 0
  for i = 1, 9 do d = math.max(d, math.abs(a[i] - b[i])) end
  return d
end

-- both poses of exact corners: one is the truth, the other its normal reflected about the line
-- of sight (the mirror), both at the true translation
local function check_exact(camera, r, t, s, tol, label)
  local m, l1, l2, l3, l4 = corners(camera, r, t, s)
  assert.is_table(m, label)
  local ra, rb = {}, {}
  local tx, ty, tz = ippe.poses(m, l1, l2, l3, l4, s / 2, ra, rb)
  assert.is_number(tx, label)
  local mirror = refine.mirror(r, t[1], t[2], t[3], {})
  local da, db = max_diff(ra, r), max_diff(rb, r)
  local found, other = ra, rb
  if db < da then found, other = rb, ra end
  assert.is_true(math.min(da, db) <= tol, label .. (": nearest pose %.3g off"):format(
    math.min(da, db)))
  assert.is_true(max_diff(other, mirror) <= tol, label .. (": other pose %.3g off the mirror")
    :format(max_diff(other, mirror)))
  assert.vector_near(t, { tx, ty, tz }, 1e-12 * t[3], label)
  -- both proper rotations
  for _, q in ipairs({ found, other }) do
    assert.rotation_near(q, q, 0, label)
    local det = q[1] * (q[5] * q[9] - q[6] * q[8]) - q[2] * (q[4] * q[9] - q[6] * q[7])
      + q[3] * (q[4] * q[8] - q[5] * q[7])
    assert.near(1, det, 1e-12, label)
  end
end

describe("tagpose.core.ippe", function()
  it("gives the exact pose and its mirror for exact corners", function()
    local rng = geometry.rng(2024)
    local n = 0
    while n < 600 do
      local camera = cameras[n % #cameras + 1]
      local s = rng.log_uniform(1e-3, 1e3)
      local width = rng.log_uniform(10, camera.height)
      local r, t = geometry.random_pose(rng, camera, s, { width = width })
      if geometry.project(camera, r, t, s) then
        n = n + 1
        check_exact(camera, r, t, s, 1e-10, ("case %d (width %.1f px)"):format(n, width))
      end
    end
  end)

  it("keeps its precision on tags nearly face-on to their line of sight", function()
    -- there the two poses are close and `s` (about the tilt) is small: the corners' own
    -- rounding moves the tilt by ~1e-15 / tilt, and a formula through 1 - |G|² would lose half
    -- the digits on top (1e-4 off for a 12 px tag tilted 0.004 degrees)
    local rng = geometry.rng(99)
    for n = 1, 200 do
      local camera = cameras[n % #cameras + 1]
      local tilt = 10 ^ rng.uniform(-6, 0)
      local width = rng.log_uniform(12, 300)
      local r, t = geometry.random_pose(rng, camera, 0.024, { tilt = tilt, width = width })
      check_exact(camera, r, t, 0.024, 1e-10 + 1e-13 / tilt,
        ("case %d (tilt %.2g rad, width %.0f px)"):format(n, tilt, width))
    end
  end)

  it("gives R = I twice for a face-on tag at the image centre", function()
    local camera = cameras[1]
    local id = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }
    local m, l1, l2, l3, l4 = corners(camera, id, { 0, 0, 0.3 }, 0.024)
    local ra, rb = {}, {}
    local tx, ty, tz = ippe.poses(m, l1, l2, l3, l4, 0.012, ra, rb)
    assert.rotation_near(id, ra, 1e-12)
    assert.rotation_near(id, rb, 1e-12)
    assert.vector_near({ 0, 0, 0.3 }, { tx, ty, tz }, 1e-15)
  end)

  it("refuses degenerate depths", function()
    local m = { -0.1, 0.1, 0.1, 0.1, 0.1, -0.1, -0.1, -0.1 }
    local ok, why = ippe.poses(m, 0, 0, 0, 0, 0.012, {}, {})
    assert.is_nil(ok)
    assert.equal("ippe: degenerate corners", why)
    ok, why = ippe.poses(m, 1, 1, 1, 1, 0, {}, {})
    assert.is_nil(ok)
    assert.equal("ippe: degenerate corners", why)
  end)
end)
