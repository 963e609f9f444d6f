-- A tag with no value must be refused, not written into the shared NULL: the NULL table is one
-- value for every document, and a tag stored in it would change how every later document
-- reads (an empty `camera_matrix:` taken for an !!opencv-matrix).
local yaml = require("tagpose.formats.yaml")
local calibration = require("tagpose.formats.calibration")

local NULL, TAG = yaml.NULL, yaml.TAG

describe("tagpose.formats.yaml", function()
  describe("decode() of a tag on an empty value", function()
    for _, case in ipairs({
      { "a: !!opencv-matrix\n", "t.yaml:1: !!opencv-matrix tags a mapping" },
      { "a: !!opencv-matrix # no value\nb: 1\n", "t.yaml:1: !!opencv-matrix tags a mapping" },
      { "a: [!!opencv-matrix ~]\n", "t.yaml:1: !!opencv-matrix tags a mapping" },
      { "a: {k: !!opencv-nd-matrix null}\n", "t.yaml:1: !!opencv-nd-matrix tags a mapping" },
    }) do
      it("refuses " .. case[1]:gsub("\n", "\\n") .. " and leaves NULL untagged", function()
        assert.same({ nil, case[2] }, { yaml.decode(case[1], "t.yaml") })
        assert.is_nil(rawget(NULL, TAG))
        assert.is_nil(next(NULL))
      end)
    end

    it("reads a later document the same as before it", function()
      local text = "camera_matrix:\nK: 1\n"
      local before = { calibration.decode(text, "a.yaml") }
      yaml.decode("a: !!opencv-matrix\n", "t.yaml")
      yaml.decode("a: [!!opencv-matrix ~]\n", "t.yaml")
      assert.same(before, { calibration.decode(text, "a.yaml") })
      assert.matches("unknown key 'K' %(a ROS camera_calibration file has", before[2])
    end)
  end)
end)
