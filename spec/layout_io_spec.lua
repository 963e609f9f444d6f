-- tagpose.layout.read / write: Lua data files, apriltag_ros tags.yaml (and its tag frame), CSV.
local tagpose = require("tagpose")
local yaml = require("tagpose.formats.yaml")
local geometry = require("support.geometry")
local layouts = require("support.layouts")
local assertions = require("support.assertions")
local run = require("support.run")

local dir = run.tmpdir()

local function file(name, text)
  return run.write(dir .. "/" .. name, text)
end

-- apriltag_ros' corners p0..p3 of a tag of side s in its own frame
local function ros_corners(s)
  local h = s / 2
  return { { -h, -h, 0 }, { h, -h, 0 }, { h, h, 0 }, { -h, h, 0 } }
end

-- the corners of an apriltag_ros layout entry {id, size, x, y, z, qw, qx, qy, qz} in the body
local function ros_body_corners(t)
  local r = layouts.matrix({ w = t.qw, x = t.qx, y = t.qy, z = t.qz })
  local out = {}
  for i, c in ipairs(ros_corners(t.size)) do
    local x, y, z = layouts.apply(r, c[1], c[2], c[3])
    out[i] = { x + t.x, y + t.y, z + t.z }
  end
  return out
end

local function pixels(camera, rb, tb, points)
  local out = {}
  for i, p in ipairs(points) do
    local x, y, z = layouts.apply(rb, p[1], p[2], p[3])
    x, y, z = x + tb[1], y + tb[2], z + tb[3]
    out[i] = { camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy }
  end
  return out
end

local function same_poses(a, b, tol_m, tol_deg)
  for id, e in pairs(a.tags) do
    local o = assert(b.tags[id], "tag " .. id)
    assert.equal(e.size, o.size)
    assert.vector_near(e.position, o.position, tol_m, "tag " .. id)
    assert.rotation_near(layouts.matrix(e.quaternion), layouts.matrix(o.quaternion), tol_deg,
      "tag " .. id)
  end
  for id in pairs(b.tags) do assert.is_table(a.tags[id]) end
end

describe("tagpose.layout", function()
  local rng = geometry.rng(31)
  local _, glued = layouts.cube(rng, 0.0229, 0.0548, 2, 3, 0.5)
  local camera = { fx = 307.22, fy = 305.74, cx = 157.14, cy = 117.87 }

  describe("write() and read() an apriltag_ros tags.yaml", function()
    it("puts each corner where apriltag_ros puts it (its tag frame, half a turn about x)",
      function()
        local path = dir .. "/cube.yaml"
        assert(tagpose.layout.write(path, glued))
        local f = assert(io.open(path, "r"))
        local doc = assert(yaml.decode(f:read("*a"), path))
        f:close()
        local list = doc.tag_bundles[1].layout
        assert.equal(6, #list)
        local rb = geometry.axis_angle(1, 1, 0.3, math.rad(130))
        local tb = { 0.01, -0.02, 0.3 }
        for _, t in ipairs(list) do
          -- the file's own numbers, read the apriltag_ros way: corner p_k is tagpose's c_k
          local ros = ros_body_corners(t)
          local ours = layouts.corners(glued.tags[t.id])
          for k = 1, 4 do
            assert.vector_near(ours[k], ros[k], 1e-15, "tag " .. t.id .. " corner " .. k)
          end
          -- and so in the image
          local a, b = pixels(camera, rb, tb, ours), pixels(camera, rb, tb, ros)
          for k = 1, 4 do
            assert.near(a[k][1], b[k][1], 1e-10)
            assert.near(a[k][2], b[k][2], 1e-10)
          end
        end
      end)

    it("reads apriltag_ros' numbers into tagpose's tag frame", function()
      local path = file("bundle.yaml", table.concat({
        "standalone_tags:",
        "  [",
        "    {id: 10, size: 0.15, name: 'wall'}",
        "  ]",
        "tag_bundles:",
        "  [",
        "    {",
        "      name: 'board',",
        "      layout:",
        "        [",
        "          {id: 0, size: 0.05, x: 0.0000, y: 0.0000, z: 0.0000, qw: 1.0000, qx: 0.0000,"
          .. " qy: 0.0000, qz: 0.0000},",
        "          {id: 4, size: 0.05, x: 0.0548, y: -0.0522, z: -0.0004, qw: 1.0000, qx: -0.0049,"
          .. " qy: -0.0016, qz: 0.0040},",
        "          {id: 3, size: 0.04, x: -0.0580, y: -0.0553, z: 0.0033, qw: 0.7071, qx: 0.7071,"
          .. " qy: 0.0, qz: 0.0}",
        "        ]",
        "    }",
        "  ]",
      }, "\n") .. "\n")
      local layout = assert(tagpose.layout.read(path))
      assert.equal("board", layout.name)
      local raw = {
        { id = 0, size = 0.05, x = 0, y = 0, z = 0, qw = 1, qx = 0, qy = 0, qz = 0 },
        { id = 4, size = 0.05, x = 0.0548, y = -0.0522, z = -0.0004, qw = 1, qx = -0.0049,
          qy = -0.0016, qz = 0.0040 },
        { id = 3, size = 0.04, x = -0.0580, y = -0.0553, z = 0.0033, qw = 0.7071, qx = 0.7071,
          qy = 0, qz = 0 },
      }
      for _, t in ipairs(raw) do
        local ros, ours = ros_body_corners(t), layouts.corners(layout.tags[t.id])
        for k = 1, 4 do assert.vector_near(ros[k], ours[k], 1e-15, "tag " .. t.id) end
      end
      -- a frame solved with the layout read is the body's pose
      local rb = geometry.axis_angle(0.2, 1, 0.1, math.rad(160))
      local tb = { 0.02, 0.01, 0.5 }
      local dets = layouts.detections(layout, camera, rb, tb, rng, 0, 85)
      assert.is_true(#dets >= 2)
      local body = assert(tagpose.layout.solve(dets, camera, layout))
      assert.vector_near(tb, body.position, 1e-9)
    end)

    it("picks a bundle by name, and asks for one when there are several", function()
      local text = "tag_bundles:\n  [\n    {name: 'a', layout: [{id: 1, size: 0.1, x: 0, y: 0,"
        .. " z: 0, qw: 1, qx: 0, qy: 0, qz: 0}]},\n    {name: 'b', layout: [{id: 2, size: 0.2,"
        .. " x: 0, y: 0, z: 0, qw: 1, qx: 0, qy: 0, qz: 0}]}\n  ]\n"
      local path = file("two.yaml", text)
      local none, why = tagpose.layout.read(path)
      assert.is_nil(none)
      assert.matches("two.yaml:1: 2 bundles %(a, b%): name the one to read", why)
      local b = assert(tagpose.layout.read(path, "b"))
      assert.equal(0.2, b.tags[2].size)
      assert.is_nil(b.tags[1])
    end)
  end)

  describe("write() and read()", function()
    for _, ext in ipairs({ "lua", "yaml", "csv" }) do
      it("keep the poses through a ." .. ext .. " file", function()
        local path = dir .. "/round." .. ext
        assert(tagpose.layout.write(path, glued))
        same_poses(glued, assert(tagpose.layout.read(path)), 1e-17, 1e-12)
      end)
    end

    it("read a Lua layout as data, never running it", function()
      local path = file("run.lua", "return { tags = {}, x = (function() LAYOUT_RAN = true end)() }")
      local none, why = tagpose.layout.read(path)
      assert.is_nil(none)
      assert.matches("run.lua:1: ", why)
      assert.is_nil(rawget(_G, "LAYOUT_RAN"))
    end)

    it("refuse malformed files with the line", function()
      local cases = {
        { "size.lua", "return {\n  tags = {\n    [0] = { size = -1, position = { x = 0, y = 0,"
          .. " z = 0 },\n      quaternion = { w = 1, x = 0, y = 0, z = 0 } },\n  },\n}\n",
          "size.lua:3: tags%[0%].size: positive number expected" },
        { "key.lua", "return {\n  tags = {},\n  tgas = {},\n}\n", "key.lua:3: unknown key tgas" },
        { "id.lua", "return { tags = {\n  [1.5] = {} } }\n", "id.lua:2: tags: key 1.5 is not" },
        { "qw.yaml", "tag_bundles:\n  - name: cube\n    layout:\n      - {id: 0, size: 0.02, x: 0,"
          .. " y: 0, z: 0, qx: 0, qy: 0, qz: 0}\n", "qw.yaml:4: qw: number expected" },
        { "flow.yaml", "tag_bundles: [\n  {name: 'x', layout: [ {id: 0, size: 0.02,\n",
          "flow.yaml:%d+:" },
        { "none.yaml", "standalone_tags: []\n", "none.yaml:1: a list tag_bundles" },
        { "x.csv", "id,size,x,y,z,qw,qx,qy,qz\n0,0.02,0,0,0,1,0,0,0\n1,0.02,zero,0,0,1,0,0,0\n",
          "x.csv:3: column x is not a number" },
        { "twice.csv", "id,size,x,y,z,qw,qx,qy,qz\n0,0.02,0,0,0,1,0,0,0\n0,0.02,0,0,0,1,0,0,0\n",
          "twice.csv:3: tag 0 is listed twice" },
        { "head.csv", "id,size,x,y,z,qw,qx,qy\n", "head.csv:1: header has no column qz" },
      }
      for _, c in ipairs(cases) do
        local none, why = tagpose.layout.read(file(c[1], c[2]))
        assert.is_nil(none, c[1])
        assert.matches(c[3], why, 1, false, c[1])
      end
      local none, why = tagpose.layout.read(file("layout.txt", "x"))
      assert.is_nil(none)
      assert.matches("%.lua, %.yaml, %.yml, %.csv or %.json expected", why)
      none, why = tagpose.layout.read(dir .. "/missing.lua")
      assert.is_nil(none)
      assert.matches("^layout: ", why)
      local name = "layout_io_spec.lua"
      assert.equal("bad argument #1 to 'read' (string expected, got nil)",
        assertions.raised(function() tagpose.layout.read() end, name))
      assert.matches("^bad argument #2 to 'write' %(layout.tags",
        assertions.raised(function() tagpose.layout.write(dir .. "/x.lua", {}) end, name))
    end)
  end)

  describe("encode()", function()
    it("gives the text write() writes, in each format, and writes nothing", function()
      local cube = tagpose.layout.cube(0.024, 0.03)
      cube.name = "cube"
      for _, ext in ipairs({ "lua", "yaml", "yml", "csv" }) do
        local path = dir .. "/encoded." .. ext
        local text = assert(tagpose.layout.encode(path, cube))
        assert.is_nil(io.open(path, "rb"))
        assert(tagpose.layout.write(path, cube))
        local f = assert(io.open(path, "rb"))
        assert.equal(f:read("*a"), text)
        f:close()
      end
    end)

    it("refuses what write() refuses, before any file", function()
      local none, why = tagpose.layout.encode(dir .. "/x.txt", { tags = {} })
      assert.is_nil(none)
      assert.equal("layout: " .. dir .. "/x.txt: .lua, .yaml, .yml or .csv expected", why)
      local name = "layout_io_spec.lua"
      assert.equal("bad argument #1 to 'encode' (string expected, got nil)",
        assertions.raised(function() tagpose.layout.encode(nil, { tags = {} }) end, name))
      assert.matches("^bad argument #2 to 'encode' %(layout.tags",
        assertions.raised(function() tagpose.layout.encode(dir .. "/x.lua", {}) end, name))
    end)
  end)

  describe("cube()", function()
    it("places the tags as tagpose.block's faces do", function()
      local faces = require("support.faces").FACES
      local cube = tagpose.layout.cube(0.024, 0.055)
      for k, f in ipairs(faces) do
        local e = cube.tags[k - 1]
        assert.vector_near({ 0.0275 * f.n[1], 0.0275 * f.n[2], 0.0275 * f.n[3] }, e.position, 1e-15)
        assert.rotation_near(f.r, layouts.matrix(e.quaternion), 1e-12)
      end
    end)
  end)
end)
