-- tagpose.block with options.layout: a block is a layout of one cube. From geometry: glued
-- cubes (spec/support/blocks.lua), their copies seen by a camera, the block poses recovered; a
-- glued cube calibrated from its own log and solved again through its layout file.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local assertions = require("support.assertions")
local layouts = require("support.layouts")
local blocks_support = require("support.blocks")

local camera, TAG, BLOCK = blocks_support.camera, blocks_support.TAG, blocks_support.BLOCK
local copies, errors = blocks_support.copies, blocks_support.errors

local function median(list)
  table.sort(list)
  return list[math.ceil(#list / 2)]
end

-- a detections' copy with every id replaced by ids[id]
local function renamed(dets, ids)
  local out = {}
  for i, d in ipairs(dets) do out[i] = { id = ids[d.id], corners = d.corners } end
  return out
end

describe("tagpose.block with options.layout", function()
  it("solves copies of a glued cube in the layout's frame, to round-off on exact corners",
    function()
      local rng = geometry.rng(11)
      local _, truth = blocks_support.glued_cube(rng)
      for n = 1, 20 do
        local dets, poses = copies(truth, camera, rng, 3, 0)
        -- the sizes and the cube's side are the layout's; or the side given
        for _, block_size in ipairs({ false, 0.055 }) do
          local blocks = assert(tagpose.block.solve(dets, camera, nil, block_size or nil,
            { layout = truth }))
          assert.equal(3, #blocks, "scene " .. n)
          assert.same({}, blocks.skipped)
          for c, e in ipairs(errors(blocks, poses)) do
            assert.is_true(e and e.centre < 1e-9 and e.angle < 1e-6, "scene " .. n .. " copy " .. c)
          end
        end
      end
    end)

  it("gives what options.faces gives: the layout tagpose.layout.cube builds from it", function()
    local rng = geometry.rng(12)
    local faces = { [11] = "+x", [12] = "-x", [13] = "+y", [14] = "-y", [15] = "+z",
      [16] = { { 0, 1, 0 }, { -1, 0, 0 }, { 0, 0, 1 } } } -- -z, turned
    local cube = tagpose.layout.cube(TAG, BLOCK, faces)
    for n = 1, 20 do
      local dets = copies(cube, camera, rng, 2, 0.3)
      local a = assert(tagpose.block.solve(dets, camera, TAG, BLOCK, { faces = faces }))
      local b = assert(tagpose.block.solve(dets, camera, nil, nil, { layout = cube }))
      assert.equal(#a, #b, "scene " .. n)
      for i = 1, #a do
        assert.vector_near(a[i].position, b[i].position, 1e-12, "scene " .. n)
        assert.rotation_near(a[i].rotation, b[i].rotation, 1e-9, "scene " .. n)
        assert.same(a[i].tags, b[i].tags)
        assert.same(a[i].tag_faces, b[i].tag_faces)
      end
    end
  end)

  it("takes the standard cube written as a symmetric layout as the default it is", function()
    local rng = geometry.rng(13)
    local standard = tagpose.layout.cube(TAG, BLOCK)
    standard.symmetric = true
    local ids = {}
    for id = 0, 5 do ids[id] = 7 end -- any id is any face's
    for n = 1, 20 do
      local dets = renamed(copies(standard, camera, rng, 3, 0.3), ids)
      local a = assert(tagpose.block.solve(dets, camera, TAG, BLOCK))
      local b = assert(tagpose.block.solve(dets, camera, nil, nil, { layout = standard }))
      assert.equal(#a, #b, "scene " .. n)
      for i = 1, #a do
        assert.same(a[i].position, b[i].position)
        assert.same(a[i].rotation, b[i].rotation)
        assert.same(a[i].tag_faces, b[i].tag_faces)
      end
    end
  end)

  it("follows a symmetric layout changed between calls, as a layout never seen before", function()
    local rng = geometry.rng(16)
    local layout = tagpose.layout.cube(TAG, BLOCK)
    layout.symmetric = true
    local dets = copies(layout, camera, rng, 2, 0.3)
    local function copy(t)
      if type(t) ~= "table" then return t end
      local out = {}
      for k, v in pairs(t) do out[k] = copy(v) end
      return out
    end
    -- the layout table changed in place solves as a fresh copy of it does
    local function solve(what)
      local a = assert(tagpose.block.solve(dets, camera, nil, nil, { layout = layout }))
      local b = assert(tagpose.block.solve(dets, camera, nil, nil, { layout = copy(layout) }))
      assert.same(b, a, what)
      return a
    end
    local given = solve("as given")
    assert.equal(2, #given)
    -- every tag smaller: the orbit's size
    for _, t in pairs(layout.tags) do t.size = 0.9 * TAG end
    local smaller = solve("smaller tags")
    assert.is_true(smaller[1].position.z < given[1].position.z)
    -- one tag left, 2 mm off its face's centre: the orbit's places
    for id = 1, 5 do layout.tags[id] = nil end
    layout.tags[0].position.y = 0.002
    local off = solve("one tag off centre")
    assert.are_not.same(smaller[1].position, off[1].position)
    -- a centred tag beside it: not symmetric any more
    layout.tags[2] = copy(tagpose.layout.cube(0.9 * TAG, BLOCK).tags[2])
    assert.equal("bad argument #5 to 'solve' (options.layout: not symmetric: the cube's "
      .. "rotations put tags[0] and tags[2] in one place 0.002 apart (leave out symmetric = "
      .. "true when the ids tell the tags apart))", assertions.raised(function()
        tagpose.block.solve(dets, camera, nil, nil, { layout = layout })
      end, "block_layout_spec.lua"))
  end)

  it("skips a detection whose id is not in the layout, and says so", function()
    local rng = geometry.rng(14)
    local _, truth = blocks_support.glued_cube(rng)
    local dets = copies(truth, camera, rng, 1, 0)
    dets[#dets + 1] = { id = 9, corners = dets[1].corners }
    local blocks = assert(tagpose.block.solve(dets, camera, nil, nil, { layout = truth }))
    assert.equal(1, #blocks)
    assert.same({ { index = #dets, reason = "block: tag id 9 is not in options.layout" } },
      blocks.skipped)
  end)

  describe("a cube calibrated from its own log", function()
    it("goes back into block.solve through its layout file: near the truth, far better than "
      .. "the nominal cube", function()
        local rng = geometry.rng(2)
        local nominal, truth = blocks_support.glued_cube(rng)
        local log = blocks_support.calibration_log(truth, camera, rng, 60, 0.3)
        local calibrated = assert(tagpose.layout.calibrate(log, camera, nominal))
        local path = os.tmpname() .. ".yaml"
        assert(tagpose.layout.write(path, calibrated))
        local read = assert(tagpose.layout.read(path))
        os.remove(path)
        local centre, angle, count = {}, {}, {}
        for _, name in ipairs({ "nominal", "calibrated", "truth" }) do
          centre[name], angle[name], count[name] = {}, {}, 0
        end
        local layout_of = { nominal = nominal, calibrated = read, truth = truth }
        for _ = 1, 40 do
          -- other frames: three copies of the glued cube, 0.3 px of corner noise
          local dets, poses = copies(truth, camera, rng, 3, 0.3)
          for name, layout in pairs(layout_of) do
            local blocks = assert(tagpose.block.solve(dets, camera, nil, nil,
              { layout = layout }))
            count[name] = count[name] + #blocks
            for _, e in ipairs(errors(blocks, poses)) do
              table.insert(centre[name], e and e.centre or math.huge)
              table.insert(angle[name], e and e.angle or 180)
            end
          end
          -- the file holds the calibrated layout (its quaternions normalised once more)
          local a = tagpose.block.solve(dets, camera, nil, nil, { layout = calibrated })
          local b = tagpose.block.solve(dets, camera, nil, nil, { layout = read })
          assert.vector_near(a[1].position, b[1].position, 1e-12)
        end
        local c, a = {}, {}
        for name in pairs(layout_of) do
          c[name], a[name] = median(centre[name]), median(angle[name])
        end
        local said = ("centre medians %.2f, %.2f, %.2f mm; rotation %.2f, %.2f, %.2f° "
          .. "(nominal, calibrated, true cube)"):format(c.nominal * 1000, c.calibrated * 1000,
          c.truth * 1000, a.nominal, a.calibrated, a.truth)
        assert.is_true(c.calibrated < 0.5 * c.nominal and a.calibrated < 0.6 * a.nominal, said)
        assert.is_true(c.calibrated < 1.1 * c.truth and a.calibrated < a.truth + 0.1, said)
        -- one block per copy
        assert.equal(120, count.calibrated)
        assert.equal(120, count.truth)
      end)
  end)

  describe("refuses", function()
    -- a cube of side 0.055 with tags of 0.024, tag 3 of 0.018, and what is wrong with it
    local function cube(change)
      local layout = tagpose.layout.cube({ [3] = 0.018, default = TAG }, BLOCK)
      if change then change(layout.tags) end
      return layout
    end
    local good = cube()
    local dets = copies(good, camera, geometry.rng(15), 1, 0)
    local function turned(tags, id, axis, degrees)
      local e = tags[id]
      local r = geometry.mul(layouts.matrix(e.quaternion),
        geometry.axis_angle(axis[1], axis[2], axis[3], math.rad(degrees)))
      tags[id] = { size = e.size, position = e.position, quaternion = layouts.quaternion(r) }
    end
    -- tag 0 (+x) tilted 30° about its y; tag 1 (-x) 10 mm out of its face
    local tilted = cube(function(tags) turned(tags, 0, { 0, 1, 0 }, 30) end)
    local out = cube(function(tags) tags[1].position.x = -0.0375 end)
    -- symmetric, but tag 2 turned 3° on its face; tag 3 smaller; tag 2 2 mm off its face's
    -- centre
    local askew = cube(function(tags) turned(tags, 2, { 0, 0, 1 }, 3) end)
    local mixed = cube()
    local shifted = cube(function(tags) tags[2].position.z = 0.002 end)
    local one = tagpose.layout.cube(TAG, BLOCK)
    askew.symmetric, mixed.symmetric, one.symmetric = true, true, true
    local BECAUSE = " (with a layout, tag_size may be nil: the layout gives each tag's size))"
    local cases = {
      { { TAG }, "bad argument #3 to 'solve' (tag_size is 0.024, but "
        .. "options.layout.tags[3].size is 0.018" .. BECAUSE },
      { { { default = TAG, [3] = 0.02 } }, "bad argument #3 to 'solve' (tag_size[3] is 0.02, "
        .. "but options.layout.tags[3].size is 0.018" .. BECAUSE },
      { { 0.02, nil, { layout = one } }, "bad argument #3 to 'solve' (tag_size is 0.02, but the "
        .. "tags of options.layout are of size 0.024" .. BECAUSE },
      { { nil, 0.06 }, "bad argument #4 to 'solve' (block_size 0.06 contradicts "
        .. "options.layout: tags[0] is 0.0275 from the centre along +x and 0 from that axis, "
        .. "where a face's centre is at block_size/2 = 0.03)" },
      { { nil, 0.02 }, "bad argument #4 to 'solve' (block_size 0.02 contradicts "
        .. "options.layout: tags[0] is 0.0275 from the centre along +x and 0 from that axis, "
        .. "where a face's centre is at block_size/2 = 0.01)" },
      { { nil, nil, { layout = tilted } }, "bad argument #5 to 'solve' (options.layout.tags[0]: "
        .. "a block's tags lie on the cube's faces, this one's z axis is 30.0° from the inward "
        .. "normal of the nearest (+x))" },
      { { nil, nil, { layout = out } }, "bad argument #5 to 'solve' (options.layout: not a "
        .. "cube: tags[1] is 0.0375 from the centre along -x and 0 from that axis, where the "
        .. "tags make a cube of side 0.055)" },
      { { nil, nil, { layout = askew } }, "bad argument #5 to 'solve' (options.layout.tags[2]: "
        .. "a symmetric layout's tags are turned by the cube's rotations, this one is 3° from "
        .. "the nearest)" },
      { { nil, nil, { layout = mixed } }, "bad argument #5 to 'solve' (options.layout.tags[3]"
        .. ".size: a symmetric layout's tags are of one size, got 0.024 and 0.018)" },
      { { nil, nil, { layout = { symmetric = true, tags = { [0] = good.tags[0],
        [2] = shifted.tags[2] } } } }, "bad argument #5 to 'solve' (options.layout: not "
        .. "symmetric: the cube's rotations put tags[0] and tags[2] in one place 0.002 apart "
        .. "(leave out symmetric = true when the ids tell the tags apart))" },
      { { nil, nil, { layout = { symmetric = 1, tags = good.tags } } }, "bad argument #5 to "
        .. "'solve' (options.layout.symmetric: boolean expected, got number 1)" },
      { { nil, nil, { layout = { tags = { [2] = { size = -1 } } } } }, "bad argument #5 to "
        .. "'solve' (options.layout.tags[2].size: positive number expected, got number -1)" },
      { { nil, nil, { layout = { tags = {} } } }, "bad argument #5 to 'solve' "
        .. "(options.layout.tags: no tag (a layout of one cube))" },
      { { nil, nil, { layout = "cube.yaml" } }, "bad argument #5 to 'solve' (options.layout: "
        .. "layout {tags = {[id] = {size =, position =, quaternion =}}} expected, got string)" },
      { { TAG, BLOCK, { layout = good, faces = { [0] = "+x" } } }, "bad argument #5 to "
        .. "'solve' (options.faces and options.layout: give one (faces names the layout "
        .. "tagpose.layout.cube(tag_size, block_size, faces)))" },
      { { nil, BLOCK, { up = "auto" } }, "bad argument #3 to 'solve' (positive number expected "
        .. "for tag_size, got nil)" },
      { { { [1] = 0.02 }, BLOCK, { faces = { [2] = "+x" } } }, "bad argument #3 to 'solve' "
        .. "(tag_size has no size for tag id 2 of options.faces and no default)" },
    }
    for i, case in ipairs(cases) do
      it(case[2], function()
        local a = case[1]
        local options = a[3] or { layout = good }
        assert.equal(case[2], assertions.raised(function()
          tagpose.block.solve(dets, camera, a[1], a[2], options)
        end, "block_layout_spec.lua"), "case " .. i)
      end)
    end
  end)
end)
