-- tagpose.layout.read of WPILib field maps: each tag's frame turned into tagpose's, checked on
-- geometry: the corners a tag has by WPILib's definition of its frame (x out of the face, z
-- up), projected into cameras placed on the field, solved with the layout read, give back the
-- cameras. The field and its truth (its poses, WPILib's frames) come from
-- bench/make_format_fixtures.py.
local tagpose = require("tagpose")
local layouts = require("support.layouts")
local assertions = require("support.assertions")
local run = require("support.run")

local FIELD = "spec/fixtures/field/wpilib_field.json"
local TRUTH = dofile("spec/fixtures/field/truth.lua")
local SIZE = 0.1651

local dir = run.tmpdir()

local function file(name, text)
  return run.write(dir .. "/" .. name, text)
end

-- the corners c1..c4 (the printed tag's bottom-left, bottom-right, top-right, top-left, seen
-- from the front) of a tag as WPILib defines its frame: x out of the face, y to the right as
-- seen from the front (z up, right-handed), in the field frame
local function wpilib_corners(t, s)
  local q = t.quaternion
  local r = layouts.matrix({ w = q[1], x = q[2], y = q[3], z = q[4] })
  local h = s / 2
  local out = {}
  for i, c in ipairs({ { 0, -h, -h }, { 0, h, -h }, { 0, h, h }, { 0, -h, h } }) do
    local x, y, z = layouts.apply(r, c[1], c[2], c[3])
    out[i] = { x + t.position[1], y + t.position[2], z + t.position[3] }
  end
  return out, { r[1], r[4], r[7] } -- and the face's outward normal
end

local CAMERA = { fx = 910, fy = 910, cx = 639.5, cy = 359.5, width = 1280, height = 720 }

-- the detections of the field's tags that face a camera at c looking at target (field frame,
-- z up), through WPILib's definition of the tags; and the camera's field -> camera pose
local function view(c, target)
  local rb, tb = layouts.look_at(c, target, { 0, 0, 1 })
  local dets = {}
  for id = 1, 8 do
    local corners, n = wpilib_corners(TRUTH[id], SIZE)
    local p = TRUTH[id].position
    local facing = n[1] * (c[1] - p[1]) + n[2] * (c[2] - p[2]) + n[3] * (c[3] - p[3]) > 0
    local px, inside = {}, facing
    for k, x in ipairs(corners) do
      local u, v, w = layouts.apply(rb, x[1], x[2], x[3])
      u, v, w = u + tb[1], v + tb[2], w + tb[3]
      px[k] = { CAMERA.fx * u / w + CAMERA.cx, CAMERA.fy * v / w + CAMERA.cy }
      inside = inside and w > 0 and px[k][1] > 0 and px[k][1] < CAMERA.width
        and px[k][2] > 0 and px[k][2] < CAMERA.height
    end
    if inside then dets[#dets + 1] = { id = id, corners = px } end
  end
  return dets, rb, tb
end

describe("tagpose.layout.read() of a WPILib field map", function()
  local field = assert(tagpose.layout.read(FIELD, { size = SIZE }))

  it("reads every tag, its centre to the last digit", function()
    for id, t in pairs(TRUTH) do
      local e = assert(field.tags[id], "tag " .. id)
      assert.equal(SIZE, e.size)
      assert.same({ x = t.position[1], y = t.position[2], z = t.position[3] }, e.position)
    end
    for id in pairs(field.tags) do assert.is_table(TRUTH[id]) end
  end)

  it("puts each corner where WPILib's tag frame puts it", function()
    for id, t in pairs(TRUTH) do
      local theirs, ours = wpilib_corners(t, SIZE), layouts.corners(field.tags[id])
      for k = 1, 4 do
        assert.vector_near(theirs[k], ours[k], 1e-14, "tag " .. id .. " corner " .. k)
      end
    end
  end)

  it("gives back cameras placed on the field, from their views of its tags", function()
    -- camera, the point it looks at, tags it must see (it may see others)
    local views = {
      { { 3.0, 4.8, 1.0 }, { 0, 4.8, 1.4 }, { 1, 2 } },         -- facing the blue wall
      { { 12.5, 3.9, 0.9 }, { 16.5, 4.3, 1.3 }, { 3 } },          -- the red wall
      { { 8.0, 2.5, 1.2 }, { 8.3, 0, 1.2 }, { 4 } },              -- a side wall
      { { 3.3, 5.6, 0.9 }, { 4.6, 4.0, 0.3 }, { 6 } },            -- a tag tilted up
      { { 12.4, 5.0, 0.2 }, { 11.9, 4.0, 0.3 }, { 7 } },          -- a tag tilted down
      { { 2.0, 0.6, 0.8 }, { 3.1, 2.0, 0.5 }, { 8 } },
    }
    for i, v in ipairs(views) do
      local dets, rb, tb = view(v[1], v[2])
      local seen = {}
      for _, d in ipairs(dets) do seen[d.id] = true end
      for _, id in ipairs(v[3]) do assert.is_true(seen[id], "view " .. i .. " sees tag " .. id) end
      local body = assert(tagpose.layout.solve(dets, CAMERA, field))
      assert.vector_near(tb, body.position, 1e-7, "view " .. i)
      assert.rotation_near(rb, body.rotation, 1e-7, "view " .. i)
      assert.is_true(body.error < 1e-6, "view " .. i)
    end
  end)

  describe("refuses", function()
    local text = run.read(FIELD)
    local function edit(pattern, replacement)
      local out, n = text:gsub(pattern, replacement, 1)
      assert(n == 1, "no " .. pattern)
      return out
    end
    local cases = {
      { edit('"ID": 2', '"Id": 2'), "f.json:22: tags[2]: unknown key 'Id' (did you mean 'ID'?)" },
      { edit('"ID": 2', '"ID": 1'), "f.json:21: tag 1 is listed twice (first on line 3)" },
      { edit('"ID": 2', '"ID": 2.5'), "f.json:22: tags[2].ID: a tag id (a whole number >= 0,"
        .. " below 2^53) expected, got number 2.5" },
      { edit('"x": 0%.0381', '"x": "0.0381"'), "f.json:7: tag 1.pose.translation.x: number"
        .. " expected, got string 0.0381" },
      { edit('"W": 1%.0,\n', ""), "f.json:12: tag 1.pose.rotation.quaternion: no W" },
      { edit('"W": 1%.0,', '"W": 0.0,'):gsub('"Z": 0%.0\n', '"Z": 0\n', 1), "f.json:12: tag"
        .. " 1.pose.rotation.quaternion: zero quaternion" },
      { edit('"length": 16%.541', '"length": -16.541'), "f.json:149: field.length: positive"
        .. " number of metres expected, got number -16.541" },
      { edit('"field":', '"feild":'), "f.json:148: the field map: unknown key 'feild' (it has"
        .. " tags)" },
      { '{"tags": []}', "f.json:1: tags: the array is empty" },
      { '{"tags": {"ID": 1}}', "f.json:1: tags: an array of {ID, pose} expected, got table" },
      { edit('"y": 5%.5479', '"y": 5.5479,'), "f.json:26: a key (a string in double quotes)"
        .. " expected, got ','" },
    }
    for i, c in ipairs(cases) do
      it("what is wrong, with its line: case " .. i, function()
        local path = file("f.json", c[1])
        local none, why = tagpose.layout.read(path, { size = SIZE })
        assert.is_nil(none)
        assert.equal("layout: " .. path:gsub("f%.json$", "") .. c[2], why)
      end)
    end

    it("an id of 2^53 or more, as every layout format does", function()
      for _, id in ipairs({ "9007199254740992", "1152921504606846976", "1e19" }) do
        local path = file("f.json", edit('"ID": 2', '"ID": ' .. id))
        local none, why = tagpose.layout.read(path, { size = SIZE })
        assert.is_nil(none, id)
        assert.matches('^layout: .*f%.json:22: tags%[2%]%.ID: a tag id %(a whole number >= 0,'
          .. ' below 2%^53%) expected, got number ', why, 1, false, id)
      end
      local path = file("f.json", edit('"ID": 2', '"ID": 9007199254740991'))
      assert.is_table(assert(tagpose.layout.read(path, { size = SIZE })).tags[2 ^ 53 - 1])
    end)

    it("a zero quaternion, but not one whose squares overflow", function()
      -- (1e200, 1e200, 0, 0) is a half turn about x, as (1, 1, 0, 0) is: turned into
      -- tagpose's tag frame, (s, s, 0, 0)·(0.5, -0.5, -0.5, 0.5) = (s, 0, -s, 0)
      local s = math.sqrt(0.5)
      for _, scale in ipairs({ "1e200", "3e307", "1e-3", "1" }) do
        local path = file("f.json", edit('"W": 1%.0,\n(%s*)"X": 0%.0,', '"W": ' .. scale
          .. ',\n%1"X": ' .. scale .. ','))
        local q = assert(tagpose.layout.read(path, { size = SIZE })).tags[1].quaternion
        assert.quaternion_near({ w = s, x = 0, y = -s, z = 0 }, q, 1e-15, scale)
      end
      for _, scale in ipairs({ "1e-200", "1e-7" }) do
        local path = file("f.json", edit('"W": 1%.0,', '"W": ' .. scale .. ','))
        local none, why = tagpose.layout.read(path, { size = SIZE })
        assert.is_nil(none, scale)
        assert.equal("layout: " .. path .. ":12: tag 1.pose.rotation.quaternion: zero"
          .. " quaternion", why)
      end
    end)

    it("a field map read without the tags' size, or with a bundle", function()
      local none, why = tagpose.layout.read(FIELD)
      assert.is_nil(none)
      assert.equal("layout: " .. FIELD .. ": a WPILib field map gives no tag size: read it with"
        .. " {size = S}, the side of the tags' black squares in metres (0.1651 for the 2024 and"
        .. " later FRC fields)", why)
      none, why = tagpose.layout.read(FIELD, { size = SIZE, bundle = "blue" })
      assert.is_nil(none)
      assert.equal("layout: " .. FIELD .. ": a WPILib field map has no bundles", why)
    end)

    it("a size for a file that gives each tag's own", function()
      local path = file("t.csv", "id,size,x,y,z,qw,qx,qy,qz\n0,0.02,0,0,0,1,0,0,0\n")
      local none, why = tagpose.layout.read(path, { size = SIZE })
      assert.is_nil(none)
      assert.equal("layout: " .. path .. ": size is for WPILib field maps (.json): this file"
        .. " gives each tag's size", why)
      assert.is_table(tagpose.layout.read(path, {}))
    end)

    it("options it does not take, raising at the caller", function()
      local name = "wpilib_spec.lua"
      local misuses = {
        { { sise = 1 }, "bad argument #2 to 'read' (options.sise: unknown key (did you mean"
          .. " 'size'?))" },
        { { size = -1 }, "bad argument #2 to 'read' (options.size: positive number expected, got"
          .. " number -1)" },
        { { bundle = 3 }, "bad argument #2 to 'read' (options.bundle: string expected, got"
          .. " number 3)" },
        { 42, "bad argument #2 to 'read' (options table expected, got number)" },
      }
      for _, c in ipairs(misuses) do
        assert.equal(c[2], assertions.raised(function() tagpose.layout.read(FIELD, c[1]) end,
          name))
      end
    end)
  end)

  it("takes the bundle of a tags.yaml in the options too", function()
    local path = file("two.yaml", "tag_bundles:\n  [\n    {name: 'a', layout: [{id: 1, size: 0.1,"
      .. " x: 0, y: 0, z: 0, qw: 1, qx: 0, qy: 0, qz: 0}]},\n    {name: 'b', layout: [{id: 2,"
      .. " size: 0.2, x: 0, y: 0, z: 0, qw: 1, qx: 0, qy: 0, qz: 0}]}\n  ]\n")
    local b = assert(tagpose.layout.read(path, { bundle = "b" }))
    assert.same(assert(tagpose.layout.read(path, "b")), b)
    assert.equal(0.2, b.tags[2].size)
  end)
end)
