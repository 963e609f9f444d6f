-- tagpose.tools.tag_id: the tools' tag ids are the library's (docs/layouts.md), checked
-- against what tagpose.layout accepts and how it prints an id.
local tagpose = require("tagpose")
local tag_id = require("tagpose.tools.tag_id")

local TAG = { size = 1, position = { x = 0, y = 0, z = 0 },
  quaternion = { w = 1, x = 0, y = 0, z = 0 } }

-- whether tagpose.layout takes `id` as a tag id, and the CSV line it writes for it
local function library(id)
  local ok, text = pcall(tagpose.layout.encode, "ids.csv", { tags = { [id] = TAG } })
  return ok, ok and text:match("\n([^,\n]*),") or nil
end

describe("tagpose.tools.tag_id", function()
  local values = { 0, -0.0, 1, -1, 7, 586, 2 ^ 31, -2 ^ 31, 2 ^ 53 - 1, -(2 ^ 53 - 1), 2 ^ 53,
    -2 ^ 53, 1e19, 1.5, -0.5, 1 / 0, -1 / 0, "3", true }

  it("is() takes what tagpose.layout takes as an id", function()
    for _, v in ipairs(values) do
      local ok = type(v) == "number" and v == v and library(v)
      assert(tag_id.is(v) == (ok and true or false), tostring(v))
    end
    assert.is_false(tag_id.is(0 / 0))
  end)

  it("text() prints an id as the layout files do", function()
    for _, v in ipairs(values) do
      if tag_id.is(v) then
        local _, text = library(v)
        assert.equal(text, tag_id.text(v))
      end
    end
    assert.equal("0", tag_id.text(-0.0))
    assert.equal("9007199254740991", tag_id.text(2 ^ 53 - 1))
  end)
end)
