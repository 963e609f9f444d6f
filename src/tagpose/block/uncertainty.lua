--- Blocks: how far to trust a block's pose — its covariance and, for a block seen with one
-- face, the probability that its orientation is the true one of the two.
--
-- - A block fitted jointly (two or more faces, or one face with `up`): `σ² H⁻¹` of the joint
--   fit's normal equations at its pose, the up and floor priors included (their weights are
--   the frame's noise over their tolerances, so that they enter as the tolerances' variances).
-- - A tag taken as a block without a fit (one face, no `up`): the tag pose's covariance
--   (`tagpose.uncertainty`, with its ambiguity term) moved to the block centre `c = t + o`,
--   `o` the centre relative to the tag: `δc = δt + δω × o`.
--
-- The confidence: 1 with two or more faces (one pose); with one face, the tag's branch
-- probability, or with `up` the two fits' Laplace evidence (their costs, priors included, and
-- the log-determinants of their normal equations). σ² is `options.sigma`², else the frame's
-- estimate from its blocks' pixel residuals (`8k - 6` degrees of freedom for a fit of `k` tags,
-- 2 for a tag alone), the default standing in for the degrees of freedom they lack
-- (`tagpose.uncertainty.noise`): a frame with a block of two faces or more has 10 or more and
-- is judged by its own residuals. The confidences take σ²; the covariances take κ σ², κ the
-- factor that makes their 95 % ellipsoid hold 95 % when σ² is an estimate
-- (`tagpose.uncertainty.ellipsoid`, Student's F; 1 for a given σ).
-- Covariances are nested 6×6, in the order (x, y, z, rx, ry, rz), as a tag's.
-- @module tagpose.block.uncertainty

local uncertainty = require("tagpose.uncertainty")
local fit = require("tagpose.block.fit")

local huge = math.huge

local M = {}

require("tagpose.core.compat").interpret_module()

--- σ² (px²) of a frame's block covariances and confidences; also sets `fr.ellipsoid`, the
-- factor κ on the covariances (`tagpose.uncertainty.noise`).
-- @tparam table fr the frame record (`tagpose.block.frame`)
-- @tparam {table,...} found the blocks found, `{h =, other =}` each
-- @treturn number σ²
function M.noise(fr, found)
  local sse, dof = 0, 0
  for i = 1, #found do
    local h = found[i].h
    local k = #h.members
    sse, dof = sse + h.sse, dof + (k > 1 and 8 * k - 6 or 2)
  end
  local sigma2, kappa = uncertainty.noise(sse, fr.settings.sigma, dof)
  fr.ellipsoid = kappa
  return sigma2
end

local normal = {} -- a joint fit's normal equations
local tag_cov -- scratch: a tag's covariance before it is moved (made on first use)

-- A hypothesis's covariance, κ σ² H⁻¹, and the ln det of its normal equations (nil for a tag
-- not fitted).
local function fitted_covariance(fr, h, sigma2)
  local cost = fit.normal(fr, h, normal)
  if not (cost < huge) then return nil end
  return uncertainty.from_normal(normal, (fr.ellipsoid or 1) * sigma2, 0)
end

-- A one-face block's covariance from its tag's candidate a (assessed: its chord factor and
-- chord set): the tag's covariance, times κ, moved to the centre.
local function tag_covariance(fr, a, sigma2)
  local kappa, t = fr.ellipsoid or 1, a.tag
  local C = uncertainty.from_normal(t.normal, kappa * sigma2, kappa * t.k, t.chord, tag_cov)
  tag_cov = C
  return uncertainty.move(C, a.x - a.tag.tx, a.y - a.tag.ty, a.z - a.tag.tz)
end

--- Set `covariance` and `confidence` on a block's table (and its alternative's).
-- @tparam table fr the frame record
-- @tparam table f the block found, `{h =, other =}`
-- @tparam table b its public table (`alternative` set when it has one)
-- @tparam number sigma2 σ² (`noise`)
function M.attach(fr, f, b, sigma2)
  local h, o, a = f.h, f.other, b.alternative
  if h.fitted then
    local cov, ld = fitted_covariance(fr, h, sigma2)
    b.covariance, b.confidence = cov, 1
    if o and a then
      local ocov, old = fitted_covariance(fr, o, sigma2)
      a.covariance = ocov
      local conf = 0.5
      if cov and ocov then
        conf = uncertainty.probability((o.cost - h.cost) / (2 * sigma2) + 0.5 * (old - ld))
      end
      b.confidence, a.confidence = conf, 1 - conf
    end
    return
  end
  -- a tag alone: its candidates' branch probability and covariances
  local ca = fr.dets[h.members[1]].cands[h.cands[1]]
  local cb = o and fr.dets[o.members[1]].cands[o.cands[1]]
  uncertainty.assess(ca.tag, cb and cb.tag, sigma2)
  b.covariance = tag_covariance(fr, ca, sigma2)
  b.confidence = ca.tag.confidence
  if cb and a then
    a.covariance = tag_covariance(fr, cb, sigma2)
    a.confidence = cb.tag.confidence
  end
end

return M
