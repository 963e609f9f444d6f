--- The one internal pipeline for a square: from its four raw pixel corners to its candidate
-- poses. `tagpose.solve` is argument checks, this pipeline, a choice between the candidates and
-- the shaping of the result; blocks (and other multi-tag fits) call the pipeline directly, so
-- the corners are read once and the camera checked once.
--
-- Stages (each a function of the workspace; nothing is shared between them but the workspace):
--
-- 1. `prepare`: the camera packed for the kernels (`tagpose.core.lsq`), the corners normalised and
--    undistorted (`tagpose.camera`), their shape checked and the proximate depths found
--    (`tagpose.core.square.shape`, the report's eight equations);
-- 2. `seed` (`method = "seed"`): the report's reduction to two quadratics, solveQuad from the
--    proximate solution (`tagpose.core.solvequad`), the pose of its root: one candidate;
-- 3. `refined` (the default): both poses of the planar ambiguity from the image's local shape
--    (`tagpose.core.ippe`), each refined over all four corners through the lens
--    (`tagpose.core.refine`); where those starts put a corner behind the camera, the report's pose
--    and its mirror, then the proximate pose and its mirror, start the refinements instead;
--    then `order`: the better candidate first, and whether the other is a second minimum.
--
-- A workspace (`new`) holds the flat pixel corners `px` (`{u1, v1, ..., u4, v4}`, filled by the
-- caller), the normalised corners `m`, the proximate depths, the quadratics' coefficients, the
-- packed camera `C`, and two candidate records `first` and `second`:
-- `{r = flat rotation (row-major, tag → camera), tx, ty, tz, sse, linearisations,
-- qw, qx, qy, qz, normal, confidence, k, chord}` — the pose, its sum of squared pixel residuals
-- over the corners (math.huge where its start led nowhere), the linearisations spent on it, its
-- quaternion, the normal equations of its last linearisation (`tagpose.core.lsq`'s layout), and
-- the uncertainty's record of it (`tagpose.uncertainty.assess` fills the last three).
-- @module tagpose.core.pipeline

local camera_model = require("tagpose.core.camera")
local lsq = require("tagpose.core.lsq")
local square = require("tagpose.core.square")
local solvequad = require("tagpose.core.solvequad")
local ippe = require("tagpose.core.ippe")
local refine = require("tagpose.core.refine")
local rotation = require("tagpose.core.rotation")
local pose = require("tagpose.core.pose")

local huge = math.huge
local to_quaternion = rotation.to_quaternion

local M = {}

--- solveQuad's threshold when it only starts the refined method: the refinement converges to
-- the same pose from any start this close, so solving the quadratics to the report's 1e-10
-- would be work thrown away. (The refined method starts from `tagpose.core.ippe`'s poses; the
-- report's method is its fallback start.)
M.REFINED_TOLERANCE = 1e-7

--- A candidate pose record (see the module's header).
-- @treturn table
function M.candidate()
  return { r = { 1, 0, 0, 0, 1, 0, 0, 0, 1 }, tx = 0, ty = 0, tz = 0, sse = huge,
    linearisations = 0, qw = 1, qx = 0, qy = 0, qz = 0, normal = {}, confidence = 1, k = 0,
    chord = { 0, 0, 0, 0, 0, 0 } }
end

--- A workspace: the pipeline's scratch and its two candidates (see the module's header).
-- @treturn table
function M.new()
  return { px = {}, m = {}, depth = {}, q = {}, C = {}, first = M.candidate(),
    second = M.candidate(), count = 0, iterations = 0, linearisations = 0 }
end

--- Stage 1: pack the camera, normalise and undistort the corners in `w.px`, check their shape.
-- @tparam table w a workspace with its corners in `w.px`
-- @tparam table camera a checked camera
-- @treturn true
-- @return nil, string when the corners cannot be a square's (the message says why)
function M.prepare(w, camera)
  local C, px, m = lsq.pack(camera, w.C), w.px, w.m
  if C.lens == lsq.NONE then
    local fx, fy, cx, cy = C.fx, C.fy, C.cx, C.cy
    m[1], m[2], m[3], m[4] = (px[1] - cx) / fx, (px[2] - cy) / fy, (px[3] - cx) / fx,
      (px[4] - cy) / fy
    m[5], m[6], m[7], m[8] = (px[5] - cx) / fx, (px[6] - cy) / fy, (px[7] - cx) / fx,
      (px[8] - cy) / fy
  else
    for i = 1, 4 do
      local x, y = camera_model.normalise(camera, px[2 * i - 1], px[2 * i])
      if not x then return nil, y .. " (corner " .. i .. ")" end
      m[2 * i - 1], m[2 * i] = x, y
    end
  end
  local l1, l2, l3, l4 = square.shape(m)
  if not l1 then return nil, l2 end
  local depth = w.depth
  depth[1], depth[2], depth[3], depth[4] = l1, l2, l3, l4
  return true
end

-- The report's pose of the prepared corners into `cand`; true, or nil and why. Sets
-- w.iterations (solveQuad's).
local function report_pose(w, cand, half, tol, max_it)
  local depth, m = w.depth, w.m
  local X0, Y0 = square.proximate(depth[1], depth[2], depth[3], depth[4])
  local X, Y, iterations = solvequad.solve(square.quadratics(m, w.q), X0, Y0, tol, max_it)
  if not X then
    w.iterations = iterations
    return nil, Y
  end
  w.iterations = iterations
  local tx, ty, tz = square.pose(m, X, Y, half, cand.r)
  if not tx then return nil, ty end
  cand.tx, cand.ty, cand.tz = tx, ty, tz
  return true
end

--- Stage 2, the report's method: its pose as the one candidate `w.first` (`w.count` = 1; its
-- `sse` is left for the caller, who measures the error of this pose as it likes).
-- @tparam table w a prepared workspace
-- @tparam number half half the tag side
-- @tparam number tol solveQuad's threshold
-- @tparam int max_it solveQuad's bound
-- @treturn true
-- @return nil, string when solveQuad finds no root, or the root's pose is not a square's
function M.seed(w, half, tol, max_it)
  w.count, w.linearisations = 1, 0
  local ok, why = report_pose(w, w.first, half, tol, max_it)
  if not ok then return nil, why end
  return true
end

-- Refine the start in w.first over the corners, and the mirror of the result in w.second.
local function minima(w, half)
  local a, b = w.first, w.second
  refine.refine(w.C, w.px, half, a)
  refine.mirror(a.r, a.tx, a.ty, a.tz, b.r)
  b.tx, b.ty, b.tz = a.tx, a.ty, a.tz
  refine.refine(w.C, w.px, half, b)
end

-- The refined method's fallback, when the local starts put a corner behind the camera (at
-- round-off, on tiny or extreme tags): the report's pose and its mirror, else the proximate
-- pose and its mirror. `spent`: the linearisations already used, counted to the first
-- candidate.
local function fallback(w, half, tol, max_it, spent)
  local a = w.first
  local ok = report_pose(w, a, half, tol, max_it)
  local depth = w.depth
  if not ok then
    local tx, ty, tz = square.proximate_pose(w.m, depth[1], depth[2], depth[3], depth[4], half,
      a.r)
    if not tx then return nil, ty end
    a.tx, a.ty, a.tz = tx, ty, tz
  end
  minima(w, half)
  if not (a.sse < huge or w.second.sse < huge) and ok then
    spent = spent + a.linearisations + w.second.linearisations
    local tx, ty, tz = square.proximate_pose(w.m, depth[1], depth[2], depth[3], depth[4], half,
      a.r)
    if tx then
      a.tx, a.ty, a.tz = tx, ty, tz
      minima(w, half)
    end
  end
  a = w.first
  a.linearisations = a.linearisations + spent
  return true
end

-- Two quaternions (q ~ -q) closer than this in chord are one minimum reached twice (an angle
-- below 1e-6 rad).
local SAME_CHORD2 = 2.5e-13

--- Stage 3's last step: the better candidate first (the lower `sse`), and whether the other is
-- a second minimum (`w.count` 2) or the same one reached twice, or nothing (`w.count` 1).
-- Fills the candidates' quaternions and `w.linearisations`.
-- @tparam table w a workspace with both candidates refined
-- @treturn true
-- @return nil, string when neither start led to a pose
function M.order(w)
  local a, b = w.first, w.second
  if not (a.sse < huge) then
    if not (b.sse < huge) then
      return nil, "refine: no pose puts every corner in front of the camera"
    end
    -- only the second start led to a pose: it is the one
    a, b = b, a
  end
  a.qw, a.qx, a.qy, a.qz = to_quaternion(a.r)
  local count = 1
  if b.sse < huge then
    b.qw, b.qx, b.qy, b.qz = to_quaternion(b.r)
    local dw, dx, dy, dz = a.qw - b.qw, a.qx - b.qx, a.qy - b.qy, a.qz - b.qz
    local ow, ox, oy, oz = a.qw + b.qw, a.qx + b.qx, a.qy + b.qy, a.qz + b.qz
    local dp, dm = dw * dw + dx * dx + dy * dy + dz * dz, ow * ow + ox * ox + oy * oy + oz * oz
    if (dp < dm and dp or dm) > SAME_CHORD2 then count = 2 end
    -- the better first (of one minimum reached twice, the better-converged copy)
    if b.sse < a.sse then a, b = b, a end
  end
  w.first, w.second, w.count = a, b, count
  w.linearisations = a.linearisations + b.linearisations
  return true
end

--- Stage 3, the refined method: both local minima of the planar ambiguity, refined over all
-- four corners, ordered (`order`).
-- @tparam table w a prepared workspace
-- @tparam number half half the tag side
-- @tparam number tol solveQuad's threshold (for the fallback start)
-- @tparam int max_it solveQuad's bound
-- @treturn true
-- @return nil, string when no start leads to a pose
function M.refined(w, half, tol, max_it)
  local a, b, depth = w.first, w.second, w.depth
  w.iterations = 0
  local spent = 0
  local tx, ty, tz = ippe.poses(w.m, depth[1], depth[2], depth[3], depth[4], half, a.r, b.r)
  if tx then
    a.tx, a.ty, a.tz, b.tx, b.ty, b.tz = tx, ty, tz, tx, ty, tz
    refine.refine(w.C, w.px, half, a)
    refine.refine(w.C, w.px, half, b)
    if a.sse < huge or b.sse < huge then return M.order(w) end
    spent = a.linearisations + b.linearisations
  end
  local ok, why = fallback(w, half, tol, max_it, spent)
  if not ok then return nil, why end
  return M.order(w)
end

local sqrt = math.sqrt

-- Is a candidate's pose finite, and its error?
local function is_finite(c)
  local r = c.r
  local s = c.tx + c.ty + c.tz + sqrt(c.sse / 4)
  for i = 1, 9 do s = s + r[i] end
  return s == s and s < huge and s > -huge
end

--- The refined method's last stage: the better candidate finite, and the other minimum kept
-- only when it is finite too (else `w.count` 1).
-- @tparam table w a workspace after `refined`
-- @treturn true
-- @return nil, string when the better candidate is not finite
function M.finite(w)
  if not is_finite(w.first) then return nil, "tagpose: no finite pose for these corners" end
  if w.count == 2 and not is_finite(w.second) then w.count = 1 end
  return true
end

--- The report's method's last stage: its candidate's quaternion, RMS reprojection error (px),
-- finiteness, and the normal equations and `sse` at it (what the uncertainty reads).
-- @tparam table w a workspace after `seed`
-- @tparam table camera the checked camera
-- @tparam number half half the tag side
-- @treturn number the candidate's RMS reprojection error (px)
-- @return nil, string when the pose or its error is not finite
function M.finish_seed(w, camera, half)
  local a = w.first
  a.qw, a.qx, a.qy, a.qz = to_quaternion(a.r)
  local err = pose.reprojection_error(w.C, a.r, a.tx, a.ty, a.tz, half, w.px)
  if not pose.is_finite(a, err) then return nil, "tagpose: no finite pose for these corners" end
  a.sse = refine.normal(camera, w.px, half, a.r, a.tx, a.ty, a.tz, a.normal)
  return err
end

--- The whole refined pipeline for one tag whose corners are in `w.px`, with the default
-- solveQuad settings: its candidates, the better in `w.first` and the other minimum, when
-- there is one, in `w.second` (`w.count` 2), each finite. For the callers that solve many tags
-- (blocks, layouts) and keep both poses.
-- @tparam table w a workspace with its corners in `w.px`
-- @tparam table camera a checked camera
-- @tparam number half half the tag side
-- @treturn true
-- @return nil, string when the corners give no finite pose (the message says why)
function M.tag(w, camera, half)
  local ok, why = M.prepare(w, camera)
  if ok then ok, why = M.refined(w, half, M.REFINED_TOLERANCE, solvequad.MAX_ITERATIONS) end
  if not ok then return nil, why end
  return M.finite(w)
end

return M
