-- tagpose.layout.schur: the bundle adjustment's damped step solves its normal equations
-- whichever side it eliminates (checked against the normal equations themselves, not against
-- the other order alone), and the order chosen is the cheap one; a board calibrated with the
-- tags eliminated recovers its known glue.
local tagpose = require("tagpose")
local bundle = require("tagpose.layout.bundle")
local schur = require("tagpose.layout.schur")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local board = require("support.board")

local UPPER = require("tagpose.core.lsq").UPPER

-- A problem of `nt` tags on a board seen in `nf` frames (tag i missing from frame f when
-- (i + f) % gap == 0), its pixels projected from true poses with noise, linearised at poses
-- moved off the truth. Tag `reference` is held.
local function problem(rng, nf, nt, gap, reference)
  local camera = board.CAMERA
  local P = bundle.new(camera, nf, nt)
  local S = { fr = {}, ft = {}, tq = {}, tp = {} }
  local h = 0.015
  local free = 0
  for i = 1, nt do
    P.half[i] = h
    if i == reference then
      P.free[i] = 0
    else
      free = free + 1
      P.free[i] = free
    end
    local q = geometry.axis_angle(rng.uniform(-1, 1), rng.uniform(-1, 1), 1, 0.05 * rng.normal())
    for k = 1, 9 do S.tq[9 * (i - 1) + k] = q[k] end
    S.tp[3 * i - 2], S.tp[3 * i - 1], S.tp[3 * i] = 0.04 * (i % 4) - 0.06,
      0.04 * math.floor(i / 4) - 0.06, 0.002 * rng.normal()
  end
  local o = 0
  for f = 1, nf do
    local c = { 0.2 * rng.normal(), 0.2 * rng.normal(), -0.8 }
    local rb, tb = layouts.look_at(c, { 0, 0, 0 }, { 0, -1, 0 })
    for k = 1, 9 do S.fr[9 * (f - 1) + k] = rb[k] end
    for k = 1, 3 do S.ft[3 * (f - 1) + k] = tb[k] end
    P.first[f] = o + 1
    for i = 1, nt do
      if (i + f) % gap ~= 0 then
        o = o + 1
        P.of[o], P.ot[o] = f, i
        local q = {}
        for k = 1, 9 do q[k] = S.tq[9 * (i - 1) + k] end
        local e = { size = 2 * h, quaternion = layouts.quaternion(q),
          position = { x = S.tp[3 * i - 2], y = S.tp[3 * i - 1], z = S.tp[3 * i] } }
        for k, p in ipairs(layouts.corners(e)) do
          local x, y, z = layouts.apply(rb, p[1], p[2], p[3])
          x, y, z = x + tb[1], y + tb[2], z + tb[3]
          P.px[8 * (o - 1) + 2 * k - 1] = camera.fx * x / z + camera.cx + 0.3 * rng.normal()
          P.px[8 * (o - 1) + 2 * k] = camera.fy * y / z + camera.cy + 0.3 * rng.normal()
        end
      end
    end
    P.last[f] = o
  end
  -- linearised off the truth
  for k = 1, #S.ft do S.ft[k] = S.ft[k] + 0.001 * rng.normal() end
  for k = 1, #S.tp do S.tp[k] = S.tp[k] + 0.0005 * rng.normal() end
  bundle.cost(P, S)
  bundle.linearise(P, S)
  return P
end

-- max |(H + λ diag H) δ + g| over max |g|, H's blocks read from the problem
local function residual(P, lambda, D)
  local function block(M, at, r, c)
    if r > c then r, c = c, r end
    for k = 1, 21 do
      if UPPER[k][1] == r and UPPER[k][2] == c then
        return M[at + k] * (r == c and 1 + lambda or 1)
      end
    end
  end
  local worst, scale = 0, 0
  for f = 1, P.nframes do
    for r = 1, 6 do
      local s = P.gA[6 * (f - 1) + r]
      scale = math.max(scale, math.abs(s))
      for c = 1, 6 do s = s + block(P.A, 21 * (f - 1), r, c) * D.x[6 * (f - 1) + c] end
      for o = P.first[f], P.last[f] do
        for c = 1, 6 do s = s + P.B[36 * (o - 1) + 6 * (r - 1) + c] * D.y[6 * (P.ot[o] - 1) + c] end
      end
      worst = math.max(worst, math.abs(s))
    end
  end
  for i = 1, P.ntags do
    if P.free[i] > 0 then
      for r = 1, 6 do
        local s = P.gC[6 * (i - 1) + r]
        scale = math.max(scale, math.abs(s))
        for c = 1, 6 do s = s + block(P.C, 21 * (i - 1), r, c) * D.y[6 * (i - 1) + c] end
        for o = 1, #P.of do
          if P.ot[o] == i then
            for c = 1, 6 do
              s = s + P.B[36 * (o - 1) + 6 * (c - 1) + r] * D.x[6 * (P.of[o] - 1) + c]
            end
          end
        end
        worst = math.max(worst, math.abs(s))
      end
    end
  end
  return worst / scale
end

describe("tagpose.layout.schur", function()
  describe("step()", function()
    it("solves the damped normal equations whether it eliminates the frames or the tags",
      function()
        local rng = geometry.rng(31)
        for _, case in ipairs({ { 3, 9, 4, 1 }, { 7, 5, 3, 2 }, { 2, 12, 5, 12 } }) do
          local P = problem(rng, case[1], case[2], case[3], case[4])
          local steps = {}
          for _, side in ipairs({ "frames", "tags" }) do
            for _, lambda in ipairs({ 1e-3, 10 }) do
              P.eliminate = side
              local D = { x = {}, y = {} }
              assert.is_true(schur.step(P, lambda, D))
              local res = residual(P, lambda, D)
              assert.is_true(res < 1e-9, side .. " eliminated: residual " .. res)
              assert.equal(0, D.y[6 * case[4] - 5], "the reference is held")
              steps[side .. lambda] = D
            end
          end
          for k = 1, 6 * P.ntags do
            assert.near(steps["frames0.001"].y[k], steps["tags0.001"].y[k], 1e-9)
          end
        end
      end)
  end)

  describe("order()", function()
    it("eliminates the tags of a board seen in a few frames, the frames of a long log", function()
      local rng = geometry.rng(32)
      assert.equal("tags", schur.order(problem(rng, 4, 16, 7, 1)))
      assert.equal("frames", schur.order(problem(rng, 40, 4, 7, 1)))
    end)
  end)
end)

describe("tagpose.layout.calibrate() on a board", function()
  it("recovers a glued board from exact corners with the tags eliminated", function()
    local rng = geometry.rng(33)
    local nominal, truth = board.layouts(rng, 4, 0.03, 0.04, 1, 1, 0.3)
    local frames = board.views(truth, rng, 6, 0.6, 0)
    local order = nil
    local step = schur.step
    schur.step = function(P, lambda, D)
      order = P.eliminate or schur.order(P)
      return step(P, lambda, D)
    end
    local ok, calibrated, report = pcall(tagpose.layout.calibrate, frames, board.CAMERA, nominal)
    schur.step = step
    assert.is_true(ok, calibrated)
    assert.equal("tags", order)
    local d, r = layouts.pair_error(calibrated, truth)
    local nd = layouts.pair_error(nominal, truth)
    assert.is_true(nd > 5e-4, "the glue is visible")
    assert.is_true(d < 1e-9 and r < 1e-6, ("pairs off by %.3g m, %.3g deg"):format(d, r))
    assert.is_true(report.rms < 1e-6)
  end)
end)
