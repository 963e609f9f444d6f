-- Units a user can plausibly mistake are said, not taken: degrees for radians, milliseconds
-- for seconds, millimetres for metres.
local tagpose = require("tagpose")

local camera = { fx = 313.9, fy = 313.9, cx = 159.5, cy = 119.5 }

describe("units", function()
  it("refuses an up_tolerance in degrees (block.solve takes radians)", function()
    assert.has_error(function()
      tagpose.block.solve({}, camera, 0.024, 0.055, { up = { 0, -1, 0 }, up_tolerance = 2 })
    end, "bad argument #5 to 'solve' (options.up_tolerance: angle in radians, above 0 and at "
      .. "most π/2 (math.rad(2) is 2°) expected, got number 2)")
    assert.is_table(tagpose.block.solve({}, camera, 0.024, 0.055,
      { up = { 0, -1, 0 }, up_tolerance = math.rad(2) }))
  end)

  it("refuses a block in millimetres around tags in metres", function()
    assert.has_error(function() tagpose.block.solve({}, camera, 0.024, 55) end)
  end)

  it("says when a tracker's times look like milliseconds", function()
    local tr = tagpose.tracker.new(camera, 0.024)
    local corners = { { 100, 140 }, { 140, 140 }, { 140, 100 }, { 100, 100 } }
    local warning
    for k = 0, 4 do
      warning = warning or tr:update({ { id = 1, corners = corners } }, 95 * k).warning
    end
    assert.truthy(warning and warning:find("milliseconds", 1, true))
  end)
end)
