local yaml = require("tagpose.formats.yaml")
local run = require("support.run")

local NULL, TAG = yaml.NULL, yaml.TAG

local function fixture(name)
  return run.read("spec/fixtures/calibration/" .. name)
end

-- decode, expecting a failure; returns the message
local function refused(text, name)
  local value, err = yaml.decode(text, name or "t.yaml")
  assert.is_nil(value, "expected a refusal of:\n" .. text)
  assert.is_string(err)
  return err
end

describe("tagpose.formats.yaml", function()
  describe("decode() on the files users have", function()
    it("reads ROS camera_calibration's ost.yaml", function()
      local doc, where = assert(yaml.decode(fixture("ost.yaml"), "ost.yaml"))
      assert.equal(640, doc.image_width)
      assert.equal(480, doc.image_height)
      assert.equal("narrow_stereo", doc.camera_name)
      assert.equal("plumb_bob", doc.distortion_model)
      assert.same({ rows = 3, cols = 3, data = { 615.925860, 0, 320.578442, 0, 617.133667,
        240.213862, 0, 0, 1 } }, doc.camera_matrix)
      assert.same({ 0.111906, -0.173451, 0.002114, 0.000813, 0 },
        doc.distortion_coefficients.data)
      assert.equal(12, #doc.projection_matrix.data)
      assert.equal(626.357483, doc.projection_matrix.data[1])
      -- where each key was
      assert.equal(4, where[doc].camera_matrix)
      assert.equal(7, where[doc.camera_matrix].data)
      assert.equal(12, where[doc.distortion_coefficients].data)
    end)

    it("reads flow sequences that span lines and plain scalars like '0.     '", function()
      local doc = assert(yaml.decode(fixture("ost_ros2.yaml"), "ost_ros2.yaml"))
      assert.same({ 913.65047, 0, 641.06519, 0, 914.21625, 359.42398, 0, 0, 1 },
        doc.camera_matrix.data)
      assert.same({ 1, 0, 0, 0, 1, 0, 0, 0, 1 }, doc.rectification_matrix.data)
      assert.equal(8, doc.distortion_coefficients.cols)
    end)

    it("reads OpenCV FileStorage: %YAML:1.0, !!opencv-matrix, 0. and exponents", function()
      local doc = assert(yaml.decode(fixture("opencv.yaml"), "opencv.yaml"))
      local k = doc.camera_matrix
      assert.equal("opencv-matrix", k[TAG])
      assert.same({ 3, 3, "d" }, { k.rows, k.cols, k.dt })
      assert.same({ 6.5746697944293521e+02, 0, 3.1950000000000000e+02, 0,
        6.5746697944293521e+02, 2.3950000000000000e+02, 0, 0, 1 }, k.data)
      assert.equal(5, #doc.distortion_coefficients.data)
      assert.equal(-5.7843597214487474e-01, doc.distortion_coefficients.data[5])
      assert.equal("Wed 08 Dec 2021 05:39:06 PM CET", doc.calibration_time)
      assert.equal(2.5000000372529030e-02, doc.square_size)
      assert.equal(1, doc.fix_aspect_ratio)
      assert.equal(18, #doc.extrinsic_parameters.data)
      assert.equal("f", doc.per_view_reprojection_errors.dt)
      -- the old form without '---'
      doc = assert(yaml.decode(fixture("opencv_kd.yml"), "opencv_kd.yml"))
      assert.equal("opencv-matrix", doc.K[TAG])
      assert.same({ -0.1, 0.01, 0, 0 }, doc.D.data)
    end)

    it("reads a ROS CameraInfo message as rostopic echo prints it", function()
      local doc = assert(yaml.decode(fixture("camera_info.yaml"), "camera_info.yaml"))
      assert.equal("camera_optical_frame", doc.header.frame_id)
      assert.equal(1638981546, doc.header.stamp.secs)
      assert.equal(false, doc.roi.do_rectify)
      assert.equal(9, #doc.K)
    end)

    it("reads apriltag_ros' tags.yaml (flow style across lines, nested)", function()
      local doc = assert(yaml.decode(fixture("tags.yaml"), "tags.yaml"))
      assert.same({ { id = 10, size = 0.15, name = "wall" }, { id = 11, size = 0.15 } },
        doc.standalone_tags)
      local bundle = doc.tag_bundles[1]
      assert.equal("CUSTOM_BUNDLE_NAME", bundle.name)
      assert.equal(3, #bundle.layout)
      assert.same({ id = 4, size = 0.05, x = 0.0548, y = -0.0522, z = -0.0004, qw = 1,
        qx = -0.0049, qy = -0.0016, qz = 0.0040 }, bundle.layout[2])
    end)
  end)

  describe("decode() values", function()
    it("reads numbers as Lua numbers, the same on every VM", function()
      local doc = assert(yaml.decode("[640, -0., .5, 6.5e+02, 1E-3, +7, 1., -.25e1, 007]"))
      assert.same({ 640, 0, 0.5, 650, 0.001, 7, 1, -2.5, 7 }, doc)
      assert.equal(-math.huge, 1 / doc[2], "-0. keeps its sign")
      -- 2^53 + 1 has 16 digits: the nearest double on every VM
      doc = assert(yaml.decode("a: 9007199254740993"))
      assert.equal(2 ^ 53, doc.a)
      assert.equal(2 ^ 53 + 2, doc.a + 2)
    end)

    it("keeps what is not a number a string, and quoted scalars strings", function()
      local doc = assert(yaml.decode(table.concat({
        "a: 0x1F", "b: 1_000", "c: '12'", 'd: "6.5e+02"', "e: 1.2.3", "f: http://x.org/a#b",
        "g: it's", "h: 'it''s'", 'i: "tab\\there \\"q\\" \\u00e9 \\x41"', "k: 1e",
      }, "\n")))
      assert.same({ a = "0x1F", b = "1_000", c = "12", d = "6.5e+02", e = "1.2.3",
        f = "http://x.org/a#b", g = "it's", h = "it's", i = 'tab\there "q" \195\169 A',
        k = "1e" }, doc)
    end)

    it("reads null, ~ and empty values as NULL, and booleans", function()
      local doc = assert(yaml.decode("a: null\nb: ~\nc:\nd: [1, ~, 3]\ne: {x: }\nf: true\n"
        .. "g: False\nh: TRUE\n"))
      assert.equal(NULL, doc.a)
      assert.equal(NULL, doc.b)
      assert.equal(NULL, doc.c)
      assert.same({ 1, NULL, 3 }, doc.d)
      assert.equal(NULL, doc.e.x)
      assert.same({ true, false, true }, { doc.f, doc.g, doc.h })
      assert.equal(NULL, (yaml.decode("# nothing but a comment\n")))
    end)

    it("reads block sequences, also at the key's indentation, and nested collections", function()
      local doc = assert(yaml.decode(table.concat({
        "---",
        "list:",
        "- 1",
        "- [2, 3]",
        "- a: 4",
        "  b: {c: [5, {d: 6}]}",
        "-",
        "  - 7",
        "  - 8",
        "-",
        "nested:",
        "  - x: 1",
        "    y: 2",
        "  - - deep",
        "...",
        "# the end",
      }, "\n")))
      assert.same({ 1, { 2, 3 }, { a = 4, b = { c = { 5, { d = 6 } } } }, { 7, 8 }, NULL },
        doc.list)
      assert.same({ { x = 1, y = 2 }, { "deep" } }, doc.nested)
    end)

    it("reads CRLF, CR-only line ends and a byte-order mark", function()
      local want = { a = 1, b = { 2, 3 } }
      assert.same(want, yaml.decode("a: 1\r\nb: [2,\r\n 3]\r\n"))
      assert.same(want, yaml.decode("a: 1\rb: [2,\r 3]\r"))
      assert.same(want, yaml.decode("\239\187\191a: 1\nb: [2, 3]\n"))
    end)

    it("reads plain and number keys, and comments everywhere", function()
      local doc = assert(yaml.decode(table.concat({
        "0: zero # a comment",
        "1.5: x",
        "'quoted key': [1, # one",
        "  2] # two",
        '"k": {a: 1, # inside',
        "  # a whole line inside",
        "  b: 2}",
      }, "\n")))
      assert.same({ [0] = "zero", [1.5] = "x", ["quoted key"] = { 1, 2 }, k = { a = 1, b = 2 } },
        doc)
    end)
  end)

  describe("decode() refuses what it does not read, with the line", function()
    local cases = {
      { "a: 1\na: 2\n", "t.yaml:2: duplicate key 'a' (first on line 1)" },
      { "{a: 1,\n a: 2}\n", "t.yaml:2: duplicate key 'a' (first on line 1)" },
      { "a: &x 1\nb: *x\n", "t.yaml:1: anchors and aliases (& and *) are not supported" },
      { "a: |\n  text\n", "t.yaml:1: block scalars (| and >) are not supported" },
      { "a: 1\n\tb: 2\n", "t.yaml:2: tab in indentation (YAML indents with spaces)" },
      { "a: 1\n  b: 2\n", "t.yaml:2: unexpected indentation" },
      { "a: b: c\n", "t.yaml:1: a mapping key inside a value ('key: value' nested on one line)" },
      { "a: [1, 2\nb: 3\n", "t.yaml:2: ',' or ']' expected in the flow sequence from line 1,"
        .. " got 'b: 3'" },
      { "a: [1, 2,\n", "t.yaml:1: flow collection from line 1 not closed" },
      { "a: {x: 1 y: 2}\n", "t.yaml:1: ',' or '}' expected in the flow mapping from line 1,"
        .. " got ': 2}'" },
      { "a: [1,, 2]\n", "t.yaml:1: empty entry in the flow collection from line 1" },
      { "a: 'open\n  more'\n", "t.yaml:1: quoted scalar not closed on its line (multi-line"
        .. " scalars are not supported)" },
      { "a: plain\n  continued\n", "t.yaml:2: unexpected indentation" },
      { "a: !!str 1\n", "t.yaml:1: tag !!str is not supported (only !!opencv-matrix)" },
      { "a: !!opencv-matrix 3\n", "t.yaml:1: !!opencv-matrix tags a mapping" },
      { "%TAG ! tag:x\n---\na: 1\n", "t.yaml:1: directive '%TAG ! tag:x' is not supported (only"
        .. " %YAML 1.x)" },
      { "a: 1\n---\nb: 2\n", "t.yaml:3: a second document (after line 2) is not supported" },
      { "? a\n: 1\n", "t.yaml:1: complex mapping keys ('? ') are not supported" },
      { "a: yes\n", "t.yaml:1: 'yes' is true or false in YAML 1.1 but a string in YAML 1.2:"
        .. " write true, false or a quoted string" },
      { "a: [1, .nan]\n", "t.yaml:1: '.nan' (not a number or infinite) is refused" },
      { "a:\n  b: -.Inf\n", "t.yaml:2: '-.Inf' (not a number or infinite) is refused" },
      { "a: 1e999\n", "t.yaml:1: the number 1e999 is out of range" },
      { 'a: "\\q"\n', "t.yaml:1: escape \\q is not supported" },
      { "a: - 1\n", "t.yaml:1: a sequence cannot start on the line of its key" },
      { "a: 1\n- 2\n", "t.yaml:2: a sequence item where a key of the mapping at line 1's"
        .. " indentation was expected" },
      { "  a: 1\nb: 2\n", "t.yaml:2: unexpected content after the document's top-level node" },
      { "just words\nmore words\n", "t.yaml:2: unexpected content after the document's"
        .. " top-level node" },
      { "- 1\nkey: 2\n", "t.yaml:2: unexpected content after the document's top-level node" },
      { "a: [1] x\n", "t.yaml:1: unexpected 'x' after the value" },
    }
    for _, case in ipairs(cases) do
      it(("%q"):format(case[1]), function()
        assert.equal(case[2], refused(case[1]))
      end)
    end

    it("bounds the nesting depth", function()
      local deep = string.rep("[", yaml.MAX_DEPTH + 1) .. string.rep("]", yaml.MAX_DEPTH + 1)
      assert.equal("t.yaml:1: nesting deeper than " .. yaml.MAX_DEPTH, refused(deep))
      local ok = string.rep("[", yaml.MAX_DEPTH - 1) .. string.rep("]", yaml.MAX_DEPTH - 1)
      assert.is_table(yaml.decode(ok))
      local lines = {}
      for i = 1, yaml.MAX_DEPTH + 1 do lines[i] = string.rep(" ", i - 1) .. "- " end
      lines[#lines + 1] = string.rep(" ", yaml.MAX_DEPTH + 1) .. "x"
      assert.truthy(refused(table.concat(lines, "\n")):find("nesting deeper than", 1, true))
    end)

    it("names the file, 'yaml' by default", function()
      assert.equal("yaml:1: anchors and aliases (& and *) are not supported",
        select(2, yaml.decode("*x")))
    end)

    it("raises on a text that is not a string", function()
      assert.has_error(function() yaml.decode(42) end,
        "bad argument #1 to 'decode' (string expected, got number)")
      assert.has_error(function() yaml.decode("a: 1", 7) end,
        "bad argument #2 to 'decode' (string expected, got number)")
    end)
  end)

  describe("decode() on large inputs", function()
    -- quadratic trimming or concatenation would take minutes here (measured, not timed)
    it("reads a long line of spaces, a long flow sequence and many keys", function()
      local spaces = string.rep(" ", 100000)
      local doc = assert(yaml.decode("a: x" .. spaces .. "y" .. spaces .. "# c\n"))
      assert.equal(100000 + 2, #doc.a)
      local items = {}
      for i = 1, 20000 do items[i] = tostring(i) end
      doc = assert(yaml.decode("a: [" .. table.concat(items, ",\n  ") .. "]\n"))
      assert.equal(20000, #doc.a)
      assert.equal(20000, doc.a[20000])
      local keys = {}
      for i = 1, 20000 do keys[i] = "k" .. i .. ": " .. i end
      doc = assert(yaml.decode(table.concat(keys, "\n")))
      assert.equal(20000, doc.k20000)
    end)
  end)
end)
