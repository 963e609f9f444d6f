-- docs/layouts.md finds the camera on the field one way, through the facade: every example that
-- prints where the camera is inverts the layout's pose with `tagpose.transform.inverse` (the page
-- had a second, by hand, `-Rᵀt`), and none waits for the facade ("once the facade has it") or
-- goes around it for `transform` and `rotation`. The examples themselves run in
-- spec/field_spec.lua and spec/docs_formats_spec.lua.
local run = require("support.run")
local docs = require("support.docs")

describe("docs/layouts.md", function()
  local text = run.read("docs/layouts.md")
  local blocks = {}
  for _, b in ipairs(docs.fenced(text)) do
    if b.lang == "lua" then blocks[#blocks + 1] = b end
  end

  it("says nothing is awaited of the facade", function()
    assert.is_nil(text:find("once the facade", 1, true))
  end)

  it("takes the camera on the field from transform.inverse in every example", function()
    local printing = 0
    for _, b in ipairs(blocks) do
      assert.is_nil(b.text:find("Rᵀt", 1, true), "line " .. b.line)
      assert.is_nil(b.text:find("R[1][1] * t.x", 1, true), "line " .. b.line)
      if b.text:find("camera at", 1, true) then
        printing = printing + 1
        assert.is_truthy(b.text:find("transform.inverse(body)", 1, true), "line " .. b.line)
      end
    end
    assert.equal(2, printing)
  end)

  it("reaches transform and rotation through the facade", function()
    for _, b in ipairs(blocks) do
      assert.is_nil(b.text:find('require("tagpose.transform")', 1, true), "line " .. b.line)
      assert.is_nil(b.text:find('require("tagpose.core.rotation")', 1, true), "line " .. b.line)
    end
  end)
end)
