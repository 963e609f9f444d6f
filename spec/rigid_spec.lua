local rigid = require("tagpose.rigid")
local lsq = require("tagpose.core.lsq")
local geometry = require("support.geometry")

local sqrt, rad = math.sqrt, math.rad

local camera = { fx = 600, fy = 590, cx = 321.5, cy = 238.5 }

-- a rigid body: the corners of two unit-spaced squares on two faces of a cube
local BODY = {
  -0.4, 0.4, -1, 0.4, 0.4, -1, 0.4, -0.4, -1, -0.4, -0.4, -1,
  -1, 0.4, 0.4, -1, 0.4, -0.4, -1, -0.4, -0.4, -1, -0.4, 0.4,
}
local N = 8

local function project(cam, r, t, scale)
  local px = {}
  for k = 1, N do
    local a = { BODY[3 * k - 2] * scale, BODY[3 * k - 1] * scale, BODY[3 * k] * scale }
    local x = r[1] * a[1] + r[2] * a[2] + r[3] * a[3] + t[1]
    local y = r[4] * a[1] + r[5] * a[2] + r[6] * a[3] + t[2]
    local z = r[7] * a[1] + r[8] * a[2] + r[9] * a[3] + t[3]
    local xd, yd = geometry.distort(cam, x / z, y / z)
    px[2 * k - 1], px[2 * k] = cam.fx * xd + cam.cx, cam.fy * yd + cam.cy
  end
  return px
end

local function scaled(scale)
  local out = {}
  for i = 1, #BODY do out[i] = BODY[i] * scale end
  return out
end

-- a random pose with both squares facing the camera
local function random_pose(rng)
  local base = geometry.axis_angle(1, -1, 0, rad(135))
  local r = geometry.mul(geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
    rad(rng.uniform(0, 20))), base)
  local t = { rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(0.3, 1) }
  return r, t
end

local function perturbed(rng, r, t, angle, shift)
  local p = geometry.mul(geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(),
    angle), r)
  return p, { t[1] + shift * rng.normal(), t[2] + shift * rng.normal(),
    t[3] + shift * rng.normal() }
end

describe("tagpose.rigid", function()
  describe("fit()", function()
    for _, cam in ipairs({ camera, { fx = 600, fy = 590, cx = 321.5, cy = 238.5,
      distortion = { k1 = -0.3, k2 = 0.1, p1 = 1e-3, p2 = -5e-4 } },
      { fx = 400, fy = 400, cx = 320, cy = 240, model = "fisheye",
        distortion = { k1 = 0.05, k2 = -0.01 } } }) do
      it("recovers an exact pose from a start 15 degrees and 2 cm off ("
        .. (cam.model or (cam.distortion and "brown" or "pinhole")) .. ")", function()
        local rng = geometry.rng(11)
        for _ = 1, 40 do
          local r, t = random_pose(rng)
          local px = project(cam, r, t, 0.05)
          local start, s = perturbed(rng, r, t, rad(15), 0.02)
          local body = rigid.fit(lsq.pack(cam), scaled(0.05), px, N,
            { r = start, tx = s[1], ty = s[2], tz = s[3] })
          assert.rotation_near(r, start, 1e-8)
          assert.vector_near(t, { body.tx, body.ty, body.tz }, 1e-10)
          assert.is_true(body.cost < 1e-16)
        end
      end)
    end

    it("minimises the pixel error with noise (no smaller error near the result)", function()
      local rng = geometry.rng(12)
      for _ = 1, 20 do
        local r, t = random_pose(rng)
        local px = project(camera, r, t, 0.05)
        for i = 1, #px do px[i] = px[i] + 0.5 * rng.normal() end
        local est = { r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9] }
        local C = lsq.pack(camera)
        local body = rigid.fit(C, scaled(0.05), px, N, { r = est, tx = t[1], ty = t[2], tz = t[3] })
        local tx, ty, tz, cost = body.tx, body.ty, body.tz, body.cost
        assert.near(cost, rigid.cost(C, scaled(0.05), px, 1, N, est, tx, ty, tz), 1e-9)
        for _ = 1, 20 do
          local p, s = perturbed(rng, est, { tx, ty, tz }, rad(0.05), 1e-5)
          assert.is_true(rigid.cost(C, scaled(0.05), px, 1, N, p, s[1], s[2], s[3])
            >= cost - 1e-9)
        end
      end
    end)

    it("holds a body axis near a direction with the prior", function()
      local rng = geometry.rng(13)
      local r, t = random_pose(rng)
      local px = project(camera, r, t, 0.05)
      for i = 1, #px do px[i] = px[i] + 0.3 * rng.normal() end
      -- the body's z axis, in the camera, a degree off its truth: pulled there by the prior
      local up = geometry.mul(geometry.axis_angle(1, 0, 0, rad(1)), r)
      local u = { up[3], up[6], up[9] }
      local est = { r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9] }
      local prior = rigid.prior()
      prior.axis_z, prior.up_x, prior.up_y, prior.up_z, prior.axis_weight = 1, u[1], u[2], u[3],
        1e6
      rigid.fit(lsq.pack(camera), scaled(0.05), px, N, { r = est, tx = t[1], ty = t[2], tz = t[3] },
        nil, prior)
      local z = { est[3], est[6], est[9] }
      local c = z[1] * u[1] + z[2] * u[2] + z[3] * u[3]
      assert.is_true(sqrt(1 - c * c) < 1e-5)
    end)

    it("reports a start with a point behind the camera", function()
      local r = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }
      local px = project(camera, r, { 0, 0, 1 }, 0.05)
      local body = rigid.fit(lsq.pack(camera), scaled(0.05), px, N,
        { r = r, tx = 0, ty = 0, tz = -1 })
      assert.equal(math.huge, body.cost)
    end)
  end)
end)
