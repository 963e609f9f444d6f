-- tagpose.calibration on the files users have: OpenCV FileStorage in YAML, XML and JSON (as
-- OpenCV 4.6 writes them), ROS and ROS 2, Kalibr camchains. The fixtures and their truth
-- (the numbers each was written with) come from bench/make_format_fixtures.py.
local calibration = require("tagpose.formats.calibration")
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local run = require("support.run")

local FIXTURES = "spec/fixtures/calibration/"
local TRUTH = dofile(FIXTURES .. "truth.lua")

local BROWN = { "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6" }
local FISHEYE = { "k1", "k2", "k3", "k4" }

local function exact(expected, got, what)
  assert(expected == got, ("%s: %.17g written, %s read"):format(what, expected,
    type(got) == "number" and ("%.17g"):format(got) or tostring(got)))
end

-- decode expecting a refusal; returns the message
local function refused(text, name, camera)
  local cam, err = calibration.decode(text, name, camera)
  assert.is_nil(cam, "expected a refusal of " .. name)
  return err
end

local function fixture(name)
  return run.read(FIXTURES .. name)
end

-- a text with its first match of `pattern` replaced (checked to be there)
local function edit(text, pattern, replacement)
  local out, n = text:gsub(pattern, replacement, 1)
  assert(n == 1, "no " .. pattern)
  return out
end

-- the pose of a known tag through a camera, solved back: the lens must be the file's
local function round_trip(camera, seed)
  local rng = geometry.rng(seed)
  for _ = 1, 10 do
    local r, t = geometry.random_pose(rng, camera, 0.05, { width = 120, max_tilt = 0.8,
      u = rng.uniform(0.4, 0.6) * 2 * camera.cx, v = rng.uniform(0.4, 0.6) * 2 * camera.cy })
    local corners = assert(geometry.project(camera, r, t, 0.05))
    local pose = assert(tagpose.solve(corners, camera, 0.05))
    assert.vector_near({ x = t[1], y = t[2], z = t[3] }, pose.position, 1e-6, "seed " .. seed)
  end
end

describe("tagpose.calibration.read() of the files users have", function()
  describe("reads each fixture to the last digit", function()
    local names = {}
    for key in pairs(TRUTH) do names[#names + 1] = key end
    table.sort(names)
    for i, key in ipairs(names) do
      it(key, function()
        local t = TRUTH[key]
        local file, which = key:match("^([^:]+):?(.*)$")
        local camera, info = calibration.read(FIXTURES .. file, which ~= "" and which or nil)
        assert(camera, info)
        for _, k in ipairs({ "fx", "fy", "cx", "cy" }) do exact(t[k], camera[k], k) end
        assert.equal(t.model, camera.model)
        local names_of = t.model == "fisheye" and FISHEYE or BROWN
        local n = 0
        for j, v in ipairs(t.d) do
          exact(v, camera.distortion[names_of[j]], names_of[j])
          n = n + 1
        end
        for _ in pairs(camera.distortion) do n = n - 1 end
        assert.equal(0, n, "coefficients beyond the file's")
        for _, k in ipairs({ "format", "distortion_model", "width", "height", "name", "camera",
          "rostopic", "timeshift_cam_imu" }) do
          assert.equal(t[k], info[k], k)
        end
        for _, k in ipairs({ "ignored", "projection", "T_cam_imu" }) do
          if t[k] then assert.same(t[k], info[k], k) end
        end
        round_trip(camera, 100 + i)
      end)
    end
  end)

  describe("OpenCV FileStorage XML and JSON", function()
    it("read the three encodings of one calibration as the same camera", function()
      for _, base in ipairs({ "opencv_tutorial", "opencv_tutorial_fisheye" }) do
        local yml = { calibration.read(FIXTURES .. base .. ".yml") }
        for _, ext in ipairs({ "xml", "json" }) do
          local other = { calibration.read(FIXTURES .. base .. "." .. ext) }
          assert.same(yml[1], other[1], ext)
          other[2].path = yml[2].path
          assert.same(yml[2], other[2], ext)
        end
      end
    end)

    it("are told by their text when the name has no known ending", function()
      for _, ext in ipairs({ "xml", "json" }) do
        local camera, info = calibration.decode(fixture("opencv_tutorial." .. ext), "calib.txt")
        assert(camera, info)
        assert.equal("opencv", info.format)
      end
    end)

    it("list the many keys they do not read", function()
      local keys = {}
      for i = 1, 3000 do keys[i] = ("<extra_%04d>%d</extra_%04d>"):format(i, i, i) end
      local text = edit(fixture("opencv_float.xml"), "</opencv_storage>",
        table.concat(keys, "\n") .. "\n</opencv_storage>")
      local camera, info = assert(calibration.decode(text, "many.xml"))
      assert.equal(500.25, camera.fx)
      assert.equal(3000, #info.ignored)
      assert.equal("extra_2999", info.ignored[2999])
    end)

    local xml = fixture("opencv_tutorial.xml")
    local json = fixture("opencv_tutorial.json")
    local cases = {
      { edit(xml, "<dt>d</dt>", "<dt>u</dt>"), "c.xml:16: camera_matrix.dt: 'd' or 'f' (one"
        .. " channel of doubles or floats) expected, got string u" },
      { edit(xml, " 0%. 1%.</data>", " 1.</data>"), "c.xml:17: camera_matrix: 3x3 = 9 numbers"
        .. " expected, got 8" },
      { edit(xml, "\n    1%.1471823305217260e%+03", "\n    abc"), "c.xml:19:"
        .. " camera_matrix.data[5]: number expected, got string abc" },
      { edit(xml, "\n    1%.1471823305217260e%+03", "\n    .Nan"), "c.xml:19: '.Nan' (not a"
        .. " number or infinite) is refused" },
      { edit(xml, "1%.1476932613597107e%+03", "1e-320"), "c.xml:13: K: fx: a focal length in"
        .. " pixels between 1e-09 and 1e+12 expected, got number " .. tostring(1e-320) },
      { edit(xml, "<fisheye_model>0", "<fisheye_model>2"), "c.xml:12: fisheye_model: 0 or 1"
        .. " expected, got number 2" },
      { edit(edit(xml, "<distortion_coefficients ", "<distortion_coefficents "),
        "</distortion_coefficients>", "</distortion_coefficents>"), "c.xml:20: unknown key"
        .. " 'distortion_coefficents' (did you mean distortion_coefficients?)" },
      { edit(xml, 'type_id="opencv%-matrix">\n  <rows>3</rows>\n  <cols>3',
        'type_id="opencv-matrix" id="1">\n  <rows>3</rows>\n  <cols>3'), "c.xml:13:"
        .. " <camera_matrix>: attribute 'id' (OpenCV writes only type_id)" },
      { edit(xml, '<camera_matrix type_id="opencv%-matrix">', "<camera_matrix>"), "c.xml:13:"
        .. " camera_matrix: an opencv-matrix expected, got table" },
      { edit(xml, "<rows>3</rows>", "<rows>3</rows>\n  <rows>3</rows>"), "c.xml:15: <rows> given"
        .. " twice in <camera_matrix> (first on line 14)" },
      { edit(xml, "</flags>", "</flag>"), "c.xml:11: </flag> does not close <flags> (line 11)" },
      { edit(xml, "<opencv_storage>", "<storage>"):gsub("</opencv_storage>", "</storage>"),
        "c.xml:2: the root element is <storage>, not <opencv_storage>: not an OpenCV"
          .. " FileStorage file" },
      { edit(xml, "<camera_matrix", "<K>1</K>\n<camera_matrix"), "c.xml:14: two camera"
        .. " matrices: K (line 13) and camera_matrix" },
      { edit(json, '"dt": "d"', '"dt": "u"'), "c.json:17: camera_matrix.dt: 'd' or 'f' (one"
        .. " channel of doubles or floats) expected, got string u" },
      { edit(json, '"fisheye_model": 0,', '"fisheye_model": 0,,'), "c.json:12: a key (a string"
        .. " in double quotes) expected, got ','" },
      { edit(json, '"type_id": "opencv%-matrix",\n        "rows": 3,\n        "cols": 3',
        '"rows": 3,\n        "cols": 3'), "c.json:13: camera_matrix: an opencv-matrix expected,"
          .. " got table" },
      { edit(json, "0%.0, 1%.0 %]", "0.0, 2.0 ]"), "c.json:13: K: a camera matrix [[fx, s, cx],"
        .. " [0, fy, cy], [0, 0, 1]] expected" },
      { edit(json, '"camera_matrix"', '"camera_matrx"'), "c.json:13: unknown key"
        .. " 'camera_matrx' (did you mean camera_matrix?)" },
      { "[1, 2]", "c.json:1: an object of calibration entries expected"
        .. " ({\"camera_matrix\": ...})" },
      { '<?xml version="1.0"?>\n<opencv_storage>\n<a>1</a>\n</opencv_storage>\n', "c.xml:1: no"
        .. " camera matrix (camera_matrix, cameraMatrix or K, an opencv-matrix)" },
    }
    for i, case in ipairs(cases) do
      it("refuse what is wrong with its line, case " .. i, function()
        local name = case[1]:match("^<") and "c.xml" or "c.json"
        assert.equal("calibration: " .. case[2], refused(case[1], name))
      end)
    end
  end)

  describe("Kalibr camchains", function()
    it("read cam0 by default, another when named, and list the chain", function()
      local path = FIXTURES .. "kalibr_camchain.yaml"
      local cam0, info0 = assert(calibration.read(path))
      local same = assert(calibration.read(path, "cam0"))
      assert.same(cam0, same)
      local _, info1 = assert(calibration.read(path, "cam1"))
      assert.same({ "cam0", "cam1" }, info0.cameras)
      assert.same({ "cam0", 1 }, { info0.camera, info0.cam_overlaps[1] })
      assert.same({ "cam1", 0 }, { info1.camera, info1.cam_overlaps[1] })
      assert.equal(16, #info1.T_cn_cnm1)
      assert.equal(-0.11007, info1.T_cn_cnm1[4])
      assert.same({ 0, 0, 0, 1 }, { info1.T_cn_cnm1[13], info1.T_cn_cnm1[14],
        info1.T_cn_cnm1[15], info1.T_cn_cnm1[16] })
    end)

    it("refuse a camera the chain does not have, and a camera named for another format",
      function()
        local camera, err = calibration.read(FIXTURES .. "kalibr_camchain.yaml", "cam2")
        assert.is_nil(camera)
        assert.equal("calibration: " .. FIXTURES .. "kalibr_camchain.yaml:1: no camera cam2 in"
          .. " the chain (it has cam0, cam1)", err)
        camera, err = calibration.read(FIXTURES .. "ros1_ost.yaml", "cam1")
        assert.is_nil(camera)
        assert.equal("calibration: " .. FIXTURES .. "ros1_ost.yaml: camera 'cam1' named, but this"
          .. " is not a Kalibr camchain (an ros file has one camera)", err)
        assert.has_error(function() calibration.read(FIXTURES .. "ros1_ost.yaml", 1) end,
          "bad argument #2 to 'read' (string expected for the camera's name, got number)")
      end)

    local chain = fixture("kalibr_camchain.yaml")
    local imucam = fixture("kalibr_camchain_imucam.yaml")
    local cases = {
      { edit(chain, "camera_model: pinhole", "camera_model: omni"), "c.yaml:3: cam0.camera_model:"
        .. " the omni model is not supported (tagpose has the pinhole camera with radtan or"
        .. " equidistant distortion)" },
      { edit(chain, "distortion_model: radtan", "distortion_model: fov"), "c.yaml:6:"
        .. " cam0.distortion_model: the fov model is not supported (radtan, equidistant or"
        .. " none)" },
      { edit(chain, "  intrinsics:", "  intrinsic:"), "c.yaml:7: cam0: unknown key 'intrinsic'"
        .. " (did you mean intrinsics?)" },
      { edit(chain, ", 248%.37534060980727%]", "]"), "c.yaml:7: cam0.intrinsics: 4 numbers"
        .. " expected, got 3" },
      { edit(chain, ", 0%.07395907389290132", ""), "c.yaml:4: cam0.distortion_coeffs:"
        .. " distortion_model radtan has 4 coefficients, the file gives 3" },
      { edit(chain, "resolution: %[752, 480%]", "resolution: [752.5, 480]"), "c.yaml:8:"
        .. " cam0.resolution: [width, height] in whole pixels expected" },
      { chain .. "imu0:\n  rostopic: /imu\n", "c.yaml:23: unknown key 'imu0' (a Kalibr camchain"
        .. " has cam0, cam1, ...)" },
      { edit(chain, "  %- %[0%.0, 0%.0, 0%.0, 1%.0%]\n", ""), "c.yaml:11: cam1.T_cn_cnm1: 4 rows of"
        .. " 4 numbers expected, got table", "cam1" },
      { edit(chain, "458%.6548807207614", "-458.6548807207614"), "c.yaml:7: K: positive focal"
        .. " lengths expected, got fx = " .. -458.6548807207614 .. ", fy = " .. 457.2966964634893 },
      { edit(imucam, "timeshift_cam_imu: %-0%.004928295416049713", "timeshift_cam_imu: soon"),
        "c.yaml:37: cam0.timeshift_cam_imu: number expected, got string soon" },
    }
    for i, case in ipairs(cases) do
      it("refuse what is wrong with its line, case " .. i, function()
        assert.equal("calibration: " .. case[2], refused(case[1], "c.yaml", case[3]))
      end)
    end
  end)

  describe("a plain solve", function()
    it("loads none of the readers of these formats", function()
      local lua = run.quote(run.lua())
      local code = [[
        package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
        local tagpose = require("tagpose")
        assert(tagpose.solve({ { 280, 280 }, { 360, 280 }, { 360, 200 }, { 280, 200 } },
          { fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5 }, 0.024))
        for _, m in ipairs({ "json", "xml", "wpilib", "calibration.storage",
          "calibration.kalibr" }) do
          if package.loaded["tagpose.formats." .. m] then print("loaded " .. m) end
        end
        print("done")
      ]]
      local out, status = run.run(lua .. " -e " .. run.quote(code) .. " 2>&1")
      assert.equal(0, status, out)
      assert.equal("done\n", out)
    end)
  end)
end)
