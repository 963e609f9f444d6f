-- Score layout calibration on a data set drawn like bench/dev/layout_cube (or by
-- bench/make_layout.lua): calibrate the nominal layout from calib/, then measure what issue 15
-- asks for.
--
--   lua5.4 bench/score_layout.lua DIR [--out CALIBRATED.lua|.yaml|.csv] [--robust K] [--quiet]
--
-- DIR holds camera.lua, nominal_layout.csv, truth_layout.csv, calib/corners.csv and
-- test/corners.csv, test/truth_tags.csv. Printed, for the nominal and the calibrated layout
-- (and the true one where it applies):
-- * layout: for every ordered pair of tags (i, j), tag j's centre in tag i's frame and their
--   relative rotation, against the truth (median and max over the pairs; mm and degrees, the
--   data's lengths taken as metres);
-- * test: the camera-frame centre of every tag of the body (seen or not) predicted from the
--   body pose of each test frame (`tagpose.layout.solve`), against truth_tags.csv: median and
--   95th percentile (mm), and the frames solved;
-- * time: the calibration (600 frames: os.clock, this VM) and the layout solve per test frame;
-- * the true layout written as an apriltag_ros tags.yaml and read back: the largest difference
--   from the table (mm, degrees).

local root = arg and arg[0] and arg[0]:match("^(.-)/?bench/[^/]*$")
root = (root == nil or root == "") and "." or root
package.path = root .. "/src/?.lua;" .. root .. "/src/?/init.lua;" .. package.path

local tagpose = require("tagpose")
local rotation = require("tagpose.core.rotation")
local set = dofile((arg[0]:match("^(.*)/[^/]*$") or ".") .. "/layout_set.lua")

local sqrt, deg = math.sqrt, math.deg
local check, quantile = set.check, set.quantile

local dir, out_path, quiet, options = nil, nil, false, {}
do
  local i = 1
  while arg[i] do
    if arg[i] == "--out" then
      i = i + 1
      out_path = arg[i]
    elseif arg[i] == "--quiet" then
      quiet = true
    elseif arg[i] == "--robust" then
      i = i + 1
      options.robust = tonumber(arg[i])
    else
      dir = arg[i]
    end
    i = i + 1
  end
end
if not dir then
  io.stderr:write("usage: lua bench/score_layout.lua DIR [--out CALIBRATED] [--quiet]\n")
  os.exit(2)
end

local camera = set.camera(dir .. "/camera.lua")
local nominal = check(tagpose.layout.read(dir .. "/nominal_layout.csv"))
local truth = check(tagpose.layout.read(dir .. "/truth_layout.csv"))

local function pose_of(entry)
  local q, p = entry.quaternion, entry.position
  return rotation.from_quaternion(q.w, q.x, q.y, q.z), p
end

-- pair errors of a layout against the truth: median and max (mm, degrees)
local function pairs_error(layout)
  local ids = {}
  for id in pairs(truth.tags) do ids[#ids + 1] = id end
  table.sort(ids)
  local dist, ang = {}, {}
  for _, i in ipairs(ids) do
    for _, j in ipairs(ids) do
      if i ~= j then
        local ri, pi = pose_of(layout.tags[i])
        local rj, pj = pose_of(layout.tags[j])
        local ti, qi = pose_of(truth.tags[i])
        local tj, qj = pose_of(truth.tags[j])
        local function rel(r, p, q)
          local d = { q.x - p.x, q.y - p.y, q.z - p.z }
          return r[1] * d[1] + r[4] * d[2] + r[7] * d[3], r[2] * d[1] + r[5] * d[2] + r[8] * d[3],
            r[3] * d[1] + r[6] * d[2] + r[9] * d[3]
        end
        local a1, a2, a3 = rel(ri, pi, pj)
        local b1, b2, b3 = rel(ti, qi, qj)
        dist[#dist + 1] = 1000 * sqrt((a1 - b1) ^ 2 + (a2 - b2) ^ 2 + (a3 - b3) ^ 2)
        local ra = rotation.transpose_multiply(ri, rj)
        local rb = rotation.transpose_multiply(ti, tj)
        ang[#ang + 1] = deg(rotation.angle(ra, rb))
      end
    end
  end
  return quantile(dist, 0.5), quantile(dist, 1), quantile(ang, 0.5), quantile(ang, 1)
end

local test_frames, test_ids = set.frames_of(dir .. "/test/corners.csv")
local truth_by = set.truth_by(dir .. "/test/truth_tags.csv")

-- test centre errors with a layout: median, p95 (mm), frames solved, solve time per frame (s)
local function test_error(layout)
  local t0 = os.clock()
  local bodies = {}
  for k, dets in ipairs(test_frames) do
    bodies[k] = tagpose.layout.solve(dets, camera, layout) or false
  end
  local per = (os.clock() - t0) / #test_frames
  local errs, solved = set.centre_errors(bodies, layout, truth_by, test_ids)
  return quantile(errs, 0.5), quantile(errs, 0.95), solved, per
end

local calib_frames = set.frames_of(dir .. "/calib/corners.csv")
local t0 = os.clock()
local calibrated, report = tagpose.layout.calibrate(calib_frames, camera, nominal, options)
local calib_time = os.clock() - t0
check(calibrated, report)
if out_path then check(tagpose.layout.write(out_path, calibrated)) end

-- the true layout through an apriltag_ros tags.yaml
local yaml_mm, yaml_deg = nil, nil
do
  local path = os.tmpname() .. ".yaml"
  local ok = tagpose.layout.write(path, truth)
  local back = ok and tagpose.layout.read(path)
  os.remove(path)
  if back then
    yaml_mm, yaml_deg = 0, 0
    for id, e in pairs(truth.tags) do
      local ra, pa = pose_of(e)
      local rb, pb = pose_of(back.tags[id])
      yaml_mm = math.max(yaml_mm, 1000 * sqrt((pa.x - pb.x) ^ 2 + (pa.y - pb.y) ^ 2
        + (pa.z - pb.z) ^ 2))
      yaml_deg = math.max(yaml_deg, deg(rotation.angle(ra, rb)))
    end
  end
end

local n_med, n_max, na_med, na_max = pairs_error(nominal)
local c_med, c_max, ca_med, ca_max = pairs_error(calibrated)
local tn_med, tn_p95, tn_solved = test_error(nominal)
local tt_med, tt_p95, tt_solved = test_error(truth)
local tc_med, tc_p95, tc_solved, per_frame = test_error(calibrated)

if not quiet then
  for _, id in ipairs((function()
    local ids = {}
    for id in pairs(report.tags) do ids[#ids + 1] = id end
    table.sort(ids)
    return ids
  end)()) do
    local t = report.tags[id]
    print(("tag %d: %d observations, %.2f mm off nominal (%.2f in plane, %.2f along z), turned"
      .. " %.2f deg (%.2f in plane, tilt %.2f), rms %.3f px"):format(id, t.observations,
      1000 * t.distance, 1000 * t.in_plane, 1000 * t.normal, deg(t.angle), deg(t.turn),
      deg(t.tilt), t.rms))
  end
  for _, u in ipairs(report.unplaced) do print(("tag %d not placed: %s"):format(u.id, u.reason)) end
  print(("frames %d used of %d (%d with one tag), %d iterations in %d stages, %d frames mended,"
    .. " rms %.3f -> %.3f px, sigma %.3f px, %d outliers, gauge alignment %.3f mm"):format(
    report.frames.used, report.frames.total, report.frames.single, report.iterations,
    report.stages, report.mended, report.rms_start, report.rms, report.sigma,
    report.detections.outliers, 1000 * report.alignment))
end
print(("%s (%s)"):format(dir, _VERSION .. (rawget(_G, "jit") and " " .. rawget(_G, "jit").version
  or "")))
print(("layout pairs   nominal %.2f mm / %.2f deg median, %.2f mm / %.2f deg max;"
  .. " calibrated %.3f mm / %.3f deg median, %.3f mm / %.3f deg max"):format(n_med, na_med, n_max,
  na_max, c_med, ca_med, c_max, ca_max))
print(("test centres   nominal %.2f / %.2f mm, true %.2f / %.2f mm, calibrated %.2f / %.2f mm"
  .. " (median / p95; calibrated/true %.3f / %.3f)"):format(tn_med, tn_p95, tt_med, tt_p95,
  tc_med, tc_p95, tc_med / tt_med, tc_p95 / tt_p95))
print(("test frames    solved %d / %d / %d of %d (nominal / true / calibrated)"):format(tn_solved,
  tt_solved, tc_solved, #test_frames))
print(("time           calibration %.2f s (%d frames), layout solve %.0f us per frame"):format(
  calib_time, #calib_frames, 1e6 * per_frame))
if yaml_mm then
  print(("tags.yaml      true layout written and read back: %.2g mm, %.2g deg at most"):format(
    yaml_mm, yaml_deg))
end
