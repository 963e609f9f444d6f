local calibration = require("tagpose.formats.calibration")
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local run = require("support.run")

local FIXTURES = "spec/fixtures/calibration/"

local function tmpfile(name, text)
  local base = os.tmpname()
  os.remove(base)
  return run.write(base .. "-" .. name, text)
end

-- decode a text expecting a refusal; returns the message
local function refused(text, name)
  local camera, err = calibration.decode(text, name)
  assert.is_nil(camera, "expected a refusal of:\n" .. text)
  return err
end

-- the pose of a known tag through a camera, solved back: the lens must be used
local function round_trip(camera, seed)
  local rng = geometry.rng(seed)
  local cam = { fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy,
    model = camera.model, distortion = camera.distortion }
  for _ = 1, 20 do
    local r, t = geometry.random_pose(rng, cam, 0.05, { width = 120, max_tilt = 0.8,
      u = rng.uniform(0.25, 0.75) * 2 * cam.cx, v = rng.uniform(0.25, 0.75) * 2 * cam.cy })
    local corners = assert(geometry.project(cam, r, t, 0.05))
    local pose = assert(tagpose.solve(corners, camera, 0.05))
    assert.vector_near({ x = t[1], y = t[2], z = t[3] }, pose.position, 1e-6, "seed " .. seed)
  end
end

describe("tagpose.formats.calibration", function()
  describe("read() of ROS camera_calibration YAML", function()
    it("reads ost.yaml: K, plumb_bob D, size, name, R and P", function()
      local camera, info = assert(calibration.read(FIXTURES .. "ost.yaml"))
      assert.same({ fx = 615.925860, fy = 617.133667, cx = 320.578442, cy = 240.213862,
        model = "pinhole", distortion = { k1 = 0.111906, k2 = -0.173451, p1 = 0.002114,
          p2 = 0.000813, k3 = 0 } }, camera)
      assert.same({ "ros", 640, 480, "narrow_stereo", "plumb_bob" },
        { info.format, info.width, info.height, info.name, info.distortion_model })
      assert.same({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, info.rectification)
      assert.same({ 626.357483, 0, 321.270066, 0, 0, 628.176575, 240.573935, 0, 0, 0, 1, 0 },
        info.projection)
      round_trip(camera, 11)
    end)

    it("reads the rational model's 8 coefficients in OpenCV's order", function()
      local camera = assert(calibration.read(FIXTURES .. "ost_ros2.yaml"))
      assert.same({ k1 = 0.398432, k2 = -2.640219, p1 = -0.000341, p2 = 0.000169,
        k3 = 1.497264, k4 = 0.282131, k5 = -2.474021, k6 = 1.425553 }, camera.distortion)
      assert.same({ 913.65047, 914.21625, 641.06519, 359.42398 },
        { camera.fx, camera.fy, camera.cx, camera.cy })
    end)

    it("reads equidistant as the fisheye model", function()
      local camera = assert(calibration.read(FIXTURES .. "fisheye_ost.yaml"))
      assert.equal("fisheye", camera.model)
      assert.same({ k1 = -0.0114, k2 = 0.0505, k3 = -0.0487, k4 = 0.0098 }, camera.distortion)
      round_trip(camera, 12)
    end)

    it("reads a CameraInfo message as rostopic echo prints it", function()
      local camera, info = assert(calibration.read(FIXTURES .. "camera_info.yaml"))
      assert.same({ 615.92586, 617.133667, 320.578442, 240.213862 },
        { camera.fx, camera.fy, camera.cx, camera.cy })
      assert.equal(0.111906, camera.distortion.k1)
      assert.same({ "camera_info", 640, 480, "camera_optical_frame" },
        { info.format, info.width, info.height, info.name })
      -- ROS 2 prints lower-case keys and block sequences
      camera = assert(calibration.decode(table.concat({
        "height: 480", "width: 640", "distortion_model: plumb_bob",
        "d:", "- 0.1", "- 0.0", "- 0.0", "- 0.0", "- 0.0",
        "k:", "- 600.0", "- 0.0", "- 320.0", "- 0.0", "- 610.0", "- 240.0", "- 0.0", "- 0.0",
        "- 1.0",
      }, "\n"), "info.yaml"))
      assert.same({ 600, 610, 320, 240, 0.1 }, { camera.fx, camera.fy, camera.cx, camera.cy,
        camera.distortion.k1 })
    end)
  end)

  describe("read() of OpenCV FileStorage YAML", function()
    it("reads calibrateCamera's output and lists what it does not read", function()
      local camera, info = assert(calibration.read(FIXTURES .. "opencv.yaml"))
      assert.same({ fx = 6.5746697944293521e+02, fy = 6.5746697944293521e+02, cx = 319.5,
        cy = 239.5, model = "pinhole", distortion = { k1 = -4.1802327176423804e-01,
          k2 = 5.0715244063187526e-01, p1 = 0, p2 = 0, k3 = -5.7843597214487474e-01 } }, camera)
      assert.same({ "opencv", 640, 480, "plumb_bob" },
        { info.format, info.width, info.height, info.distortion_model })
      assert.same({ "avg_reprojection_error", "board_height", "board_width", "calibration_time",
        "extrinsic_parameters", "fix_aspect_ratio", "flags", "nr_of_frames",
        "per_view_reprojection_errors", "square_size" }, info.ignored)
      round_trip(camera, 13)
    end)

    it("reads K and D, and the fisheye model of fisheye_model: 1", function()
      local camera = assert(calibration.read(FIXTURES .. "opencv_kd.yml"))
      assert.same({ fx = 500, fy = 500, cx = 320, cy = 240, model = "pinhole",
        distortion = { k1 = -0.1, k2 = 0.01, p1 = 0, p2 = 0 } }, camera)
      local text = run.read(FIXTURES .. "opencv_kd.yml") .. "fisheye_model: 1\n"
      camera = assert(calibration.decode(text, "fisheye.yml"))
      assert.equal("fisheye", camera.model)
      assert.same({ k1 = -0.1, k2 = 0.01, k3 = 0, k4 = 0 }, camera.distortion)
    end)

    it("accepts 12 or 14 coefficients whose thin-prism and tilt terms are 0", function()
      local function file(d)
        return "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
          .. "   dt: d\n   data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n"
          .. "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: " .. #d .. "\n"
          .. "   dt: d\n   data: [ " .. table.concat(d, ", ") .. " ]\n"
      end
      local camera = assert(calibration.decode(file({ -0.2, 0.1, 0, 0, 0.01, 0.001, 0, 0,
        0, 0, 0, 0, 0, 0 }), "c.yml"))
      assert.same({ k1 = -0.2, k2 = 0.1, p1 = 0, p2 = 0, k3 = 0.01, k4 = 0.001, k5 = 0,
        k6 = 0 }, camera.distortion)
      assert.equal("calibration: c.yml:8: distortion_coefficients: coefficient 9 of 12 is"
        .. " 0.001: the thin-prism and tilted models (s1..s4, tx, ty) are not supported",
        refused(file({ -0.2, 0.1, 0, 0, 0.01, 0, 0, 0, 0.001, 0, 0, 0 }), "c.yml"))
    end)
  end)

  describe("read() of Lua camera files, as data", function()
    it("reads the camera, its size, name, unit and tag sizes", function()
      local path = tmpfile("camera.lua", table.concat({
        "-- the robot's camera",
        "return {",
        "  fx = 700, fy = 701, cx = 639.5, cy = 359.5, width = 1280, height = 720,",
        "  distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4 },",
        "  name = 'front', unit = 'm', block_size = 0.055,",
        "  tag_size = { [0] = 0.05, [7] = 0.1, default = 0.024 },",
        "}",
      }, "\n"))
      local camera, info = assert(calibration.read(path))
      os.remove(path)
      assert.same({ fx = 700, fy = 701, cx = 639.5, cy = 359.5, model = "pinhole",
        distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4, k3 = 0 } }, camera)
      assert.same({ format = "lua", path = path, width = 1280, height = 720, name = "front",
        unit = "m", block_size = 0.055, tag_size = { [0] = 0.05, [7] = 0.1, default = 0.024 } },
        info)
      round_trip(camera, 14)
    end)

    it("takes the distortion as OpenCV's distCoeffs array too, the same camera", function()
      local named = assert(calibration.decode("return { fx = 700, fy = 700, cx = 639.5,"
        .. " cy = 359.5, distortion = { k1 = -0.28, k2 = 0.07, p1 = 5e-4, p2 = -3e-4,"
        .. " k3 = 0.01 } }", "a.lua"))
      local array = assert(calibration.decode("return { fx = 700, fy = 700, cx = 639.5,"
        .. " cy = 359.5, distortion = { -0.28, 0.07, 5e-4, -3e-4, 0.01 } }", "b.lua"))
      assert.same(named, array)
      local fisheye = assert(calibration.decode("return { fx = 300, fy = 300, cx = 320,"
        .. " cy = 240, model = 'fisheye', distortion = { -0.01, 0.05, -0.04, 0.01 } }", "f.lua"))
      assert.same({ k1 = -0.01, k2 = 0.05, k3 = -0.04, k4 = 0.01 }, fisheye.distortion)
    end)

    it("reads every camera file of the repository", function()
      for _, path in ipairs({ "examples/data/camera.lua", "spec/fixtures/exact/camera.lua" }) do
        local camera, info = assert(calibration.read(path))
        assert.is_number(camera.fx)
        assert.equal(0.024, info.tag_size)
      end
    end)

    it("refuses a misspelled key, naming the likely intended one", function()
      local base = "fx = 700, fy = 700, cx = 320, cy = 240"
      local cases = {
        { "return {\n " .. base .. ",\n fxx = 1 }",
          "c.lua:3: unknown key 'fxx' (did you mean fx?)" },
        { "return { " .. base .. ", tag_sise = 0.024 }", "c.lua:1: unknown key 'tag_sise' (did"
          .. " you mean tag_size?)" },
        { "return { " .. base .. ", k1 = -0.2 }", "c.lua:1: unknown key 'k1' (did you mean"
          .. " distortion.k1?)" },
        { "return { " .. base .. ", distortion = { K1 = -0.2 } }", "c.lua:1: distortion: unknown"
          .. " key 'K1' (did you mean 'k1'?)" },
        { "return { " .. base .. ", distortion = { k1 = -0.2, kk2 = 1 } }", "c.lua:1:"
          .. " distortion: unknown key 'kk2' (did you mean 'k2'?)" },
        { "return { " .. base .. ", model = 'fisheye', distortion = { p1 = 0.1 } }", "c.lua:1:"
          .. " distortion: unknown key 'p1' (the fisheye model has k1, k2, k3, k4)" },
        { "return { " .. base .. ", distortion = { -0.2, 0.1, 0 } }", "c.lua:1: distortion:"
          .. " 4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]) expected, got 3" },
        { "return { " .. base .. ", distortion = { -0.2, k2 = 0.1 } }", "c.lua:1: distortion:"
          .. " named coefficients (k1 = ...) or an array in OpenCV's order, not both" },
        { "return { " .. base .. ", foo = 1 }", "c.lua:1: unknown key 'foo' (a camera file has"
          .. " fx, fy, cx, cy, model, distortion, width, height, name, tag_size, block_size,"
          .. " unit)" },
        { "return { fy = 700, cx = 320, cy = 240 }", "c.lua:1: no fx (the focal length in"
          .. " pixels)" },
        { "return { " .. base .. ", tag_size = -1 }", "c.lua:1: tag_size: positive number"
          .. " expected, got number -1" },
        { "return { " .. base .. ", tag_size = { [3] = 0.1, defualt = 0.2 } }", "c.lua:1:"
          .. " tag_size: unknown key 'defualt' (did you mean 'default'?)" },
        { "return { " .. base .. ", tag_size = { [1.5] = 0.1 } }", "c.lua:1: tag_size: unknown"
          .. " key [1.5] (tag ids are whole numbers >= 0, or 'default')" },
        { "return { " .. base .. ", model = 'brown' }", "c.lua:1: model: 'pinhole' or"
          .. " 'fisheye' expected, got string brown" },
        { "return { " .. base .. ", width = 640.5 }", "c.lua:1: width: whole number of pixels"
          .. " expected, got number 640.5" },
        { "return 42", "c.lua:1: a camera table expected, got number 42" },
        -- what every solve would refuse is refused at read, with its line
        { "return {\n fx = 1e-320, fy = 700, cx = 320, cy = 240 }", "c.lua:2: fx: a focal length"
          .. " in pixels between 1e-09 and 1e+12 expected, got number " .. tostring(1e-320) },
        { "return { fx = 700, fy = 700,\n cx = 320, cy = -2e12 }", "c.lua:2: cy: a principal"
          .. " point coordinate in pixels within 1e+12 expected, got number " .. tostring(-2e12) },
      }
      for _, case in ipairs(cases) do
        assert.equal("calibration: " .. case[2], refused(case[1], "c.lua"), case[1])
      end
    end)

    it("never runs the file: a loop, a call or a global is refused at once", function()
      assert.equal("calibration: c.lua:1: a loop ('while') is not data: 'return { ... }'"
        .. " expected", refused("while true do end", "c.lua"))
      assert.equal("calibration: c.lua:1: a global variable ('string.rep') is not data",
        refused("return { fx = string.rep('x', 2 ^ 31) }", "c.lua"))
      assert.equal("calibration: c.lua:2: a global variable ('os.exit') is not data",
        refused("return {\n fx = os.exit(1) }", "c.lua"))
    end)
  end)

  describe("read() refuses malformed YAML calibrations with the line", function()
    local ost = run.read(FIXTURES .. "ost.yaml")
    local cases = {
      { ost:gsub("distortion_coefficients", "distortion_coeficients"), "c.yaml:9: unknown key"
        .. " 'distortion_coeficients' (did you mean distortion_coefficients?)" },
      { ost:gsub("cols: 5", "cols: 4"), "c.yaml:12: distortion_coefficients: 1x4 = 4 numbers"
        .. " expected, got 5" },
      { ost:gsub("plumb_bob", "rational_polynomial"), "c.yaml:9: distortion_model"
        .. " rational_polynomial has 8 coefficients, the file gives 5" },
      { ost:gsub("plumb_bob", "kannala"), "c.yaml:8: distortion_model: 'plumb_bob',"
        .. " 'rational_polynomial' or 'equidistant' expected, got string kannala" },
      { ost:gsub("  rows: 3\n  cols: 3\n  data: %[615", "  rows: 3\n  colz: 3\n  data: [615", 1),
        "c.yaml:4: camera_matrix: no cols" },
      { ost:gsub("0%.111906", "'a'"), "c.yaml:12: distortion_coefficients.data[1]: number"
        .. " expected, got string a" },
      { ost:gsub("615%.925860", "-615.9"), "c.yaml:4: K: positive focal lengths expected, got"
        .. " fx = -615.9, fy = 617.133667" },
      { ost:gsub("615%.925860", "1e-320"), "c.yaml:4: K: fx: a focal length in pixels between"
        .. " 1e-09 and 1e+12 expected, got number " .. tostring(1e-320) },
      { ost:gsub("0%.111906", ".nan"), "c.yaml:12: '.nan' (not a number or infinite) is"
        .. " refused" },
      { "camera_matrix: [1, 2]\n", "c.yaml:1: camera_matrix: a mapping {rows, cols, data}"
        .. " expected, got table" },
      { "image_width: 640\n", "c.yaml:1: no camera matrix: not a ROS camera_calibration file"
        .. " (camera_matrix), a CameraInfo message (K), an OpenCV FileStorage file"
        .. " (camera_matrix: !!opencv-matrix) or a Kalibr camchain (cam0: {camera_model,"
        .. " intrinsics, ...})" },
      { "camra_matrix: 1\n", "c.yaml:1: unknown key 'camra_matrix' (did you mean"
        .. " camera_matrix?)" },
      { run.read(FIXTURES .. "opencv_kd.yml"):gsub("dt: d", "dt: u", 1), "c.yaml:5: K.dt: 'd'"
        .. " or 'f' (one channel of doubles or floats) expected, got string u" },
      { run.read(FIXTURES .. "opencv_kd.yml") .. "camera_matrix: !!opencv-matrix\n  rows: 1\n",
        "c.yaml:12: two camera matrices: K (line 2) and camera_matrix" },
      { run.read(FIXTURES .. "opencv_kd.yml") .. "distortion_coefficents: 1\n", "c.yaml:12:"
        .. " unknown key 'distortion_coefficents' (did you mean distortion_coefficients?)" },
      { run.read(FIXTURES .. "camera_info.yaml"):gsub("binning_x: 0", "binning_x: 2"),
        "c.yaml:14: binning_x number 2: binned images are not supported (the camera matrix is"
          .. " that of the full image)" },
      { run.read(FIXTURES .. "camera_info.yaml"):gsub("x_offset: 0", "x_offset: 16"),
        "c.yaml:17: roi.x_offset number 16: a region of interest is not supported (the corners"
          .. " would need its offset)" },
    }
    for i, case in ipairs(cases) do
      it("case " .. i, function()
        assert.equal("calibration: " .. case[2], refused(case[1], "c.yaml"))
      end)
    end
  end)

  describe("read()", function()
    it("reports a file it cannot open or that is too large", function()
      local camera, err = calibration.read("/nonexistent/ost.yaml")
      assert.is_nil(camera)
      assert.truthy(err:find("^calibration: /nonexistent/ost.yaml"), err)
      local path = tmpfile("big.yaml", "a: 1\n" .. string.rep("#", calibration.MAX_BYTES))
      camera, err = calibration.read(path)
      os.remove(path)
      assert.is_nil(camera)
      assert.equal("calibration: " .. path .. ": larger than " .. calibration.MAX_BYTES
        .. " bytes (a calibration is a few lines)", err)
    end)

    it("raises on a path that is not a string", function()
      assert.has_error(function() calibration.read(42) end,
        "bad argument #1 to 'read' (string expected, got number)")
    end)
  end)
end)
