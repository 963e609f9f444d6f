-- options.order = "opencv": corners as OpenCV's and ArUco's detectors give them (top-left,
-- top-right, bottom-right, bottom-left of the printed tag), checked against an independent
-- projection of the tag's corners in that order.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local rotation = require("tagpose.core.rotation")

local camera = { fx = 700, fy = 705, cx = 330.2, cy = 236.8 }
local SIZE = 0.05

-- the pixels of the printed tag's top-left, top-right, bottom-right and bottom-left corners
-- (tag frame x right, y down: top-left is (-s/2, -s/2)), projected by hand
local function opencv_corners(r, t)
  local h = SIZE / 2
  local out = {}
  for i, c in ipairs({ { -h, -h }, { h, -h }, { h, h }, { -h, h } }) do
    local x = r[1] * c[1] + r[2] * c[2] + t[1]
    local y = r[4] * c[1] + r[5] * c[2] + t[2]
    local z = r[7] * c[1] + r[8] * c[2] + t[3]
    out[i] = { camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy }
  end
  return out
end

describe("options.order", function()
  it("takes OpenCV's order and gives the pose of the detection order, to 1e-12", function()
    local rng = geometry.rng(2024)
    for _ = 1, 50 do
      local r, t = geometry.random_pose(rng, camera, SIZE, { width = rng.uniform(30, 200) })
      local pose = assert(tagpose.solve(opencv_corners(r, t), camera, SIZE,
        { order = "opencv" }))
      assert.vector_near(t, pose.position, 1e-12 * (1 + t[3]))
      assert.is_true(rotation.angle(r, rotation.from_nested(pose.rotation)) < 1e-12)
      -- the same corners reversed are the detection order
      local c = opencv_corners(r, t)
      local same = assert(tagpose.solve({ c[4], c[3], c[2], c[1] }, camera, SIZE))
      assert.same(same.position, pose.position)
    end
  end)

  it("says how to convert when OpenCV's corners are passed in the default order", function()
    local r, t = geometry.random_pose(geometry.rng(5), camera, SIZE, { width = 80 })
    local pose, err = tagpose.solve(opencv_corners(r, t), camera, SIZE)
    assert.is_nil(pose)
    assert.truthy(err:find("options.order = 'opencv'", 1, true))
  end)

  it("names a corner in the order given, and refuses an unknown order", function()
    local r, t = geometry.random_pose(geometry.rng(6), camera, SIZE, { width = 80 })
    local c = opencv_corners(r, t)
    c[2] = { 0 / 0, 1 }
    local _, err = tagpose.solve(c, camera, SIZE, { order = "opencv" })
    assert.equal("tagpose: corner 2 is not finite", err)
    assert.has_error(function() tagpose.solve(c, camera, SIZE, { order = "aruco" }) end,
      "bad argument #4 to 'solve' (options.order: 'apriltag' or 'opencv' expected, got "
        .. "string aruco)")
  end)

  it("works the same in the tracker", function()
    local r, t = geometry.random_pose(geometry.rng(7), camera, SIZE, { width = 80 })
    local tr = tagpose.tracker.new(camera, SIZE, { order = "opencv" })
    local seen = tr:update({ { id = 3, corners = opencv_corners(r, t) } }, 0)
    assert.vector_near(t, seen[1].pose.position, 1e-9)
  end)
end)
