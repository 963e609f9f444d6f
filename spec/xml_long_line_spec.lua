-- Reading XML stays linear in the length of a line, and still names the right line of what it
-- refuses. The OpenCV values' reader looked for the next line end from every value, and the
-- XML reader for the next `&` from every text, each scanning the rest of the line (of the file,
-- when it has no `&`), so that one line of 960 KB took seconds; now each line end and each `&`
-- is found once (measured, not timed here: bench/tool_costs.lua prints the figures).
local xml = require("tagpose.formats.xml")
local calibration = require("tagpose.formats.calibration")

-- an OpenCV FileStorage XML whose distortion coefficients are n numbers on one line, followed
-- on the same line by `tail`
local function storage(n, tail)
  local items = {}
  for i = 1, n do items[i] = ("%.6f"):format(i / 7) end
  return table.concat({
    '<?xml version="1.0"?>',
    "<opencv_storage>",
    '<camera_matrix type_id="opencv-matrix"><rows>3</rows><cols>3</cols><dt>d</dt>',
    "<data>600 0 320 0 600 240 0 0 1</data></camera_matrix>",
    '<distortion_coefficients type_id="opencv-matrix"><rows>1</rows><cols>' .. n
      .. "</cols><dt>d</dt>",
    "<data>" .. table.concat(items, " ") .. tail .. "</data></distortion_coefficients>",
    "</opencv_storage>",
  }, "\n")
end

describe("tagpose.formats.xml", function()
  describe("decode() on long lines", function()
    it("names the line of a refusal at the end of a long line, and after it", function()
      local long = string.rep("<b>1</b>", 2000)
      local cases = {
        { "<a>" .. long .. "<c>1 & 2</c></a>", "f.xml:1: '&' that starts no reference" },
        { "<a>\n" .. long .. "\n<c>1 & 2</c></a>", "f.xml:3: '&' that starts no reference" },
        { "<a>\n" .. long .. "<c x='<'/></a>", "f.xml:2: '<' in the value of attribute 'x'" },
        { "<a>\n" .. long .. "&bogus;</a>", "f.xml:2: unknown entity reference '&bogus;'" },
      }
      for _, c in ipairs(cases) do
        local v, err = xml.decode(c[1], "f.xml")
        assert.is_nil(v)
        assert.equal(c[2], err:sub(1, #c[2]))
      end
    end)
  end)
end)

describe("tagpose.formats.calibration", function()
  describe("decode() of OpenCV XML on long lines", function()
    it("names the line of a value at the end of a line of 2000 values, and after it", function()
      local cases = {
        { storage(2000, " oops"), "long.xml:6: distortion_coefficients.data[2001]: number" },
        { storage(2000, "\n\n oops"), "long.xml:8: distortion_coefficients.data[2001]: number" },
        -- the line ends inside a quoted string are counted
        { storage(2000, ' "a\nb\nc" .nan'), "long.xml:8: '.nan' (not a number or infinite)" },
        { storage(2000, ' "a\nb'), "long.xml:6: a string is not closed" },
      }
      for _, c in ipairs(cases) do
        local camera, err = calibration.decode(c[1], "long.xml")
        assert.is_nil(camera)
        assert.equal("calibration: " .. c[2], err:sub(1, #c[2] + 13))
      end
    end)
  end)
end)
