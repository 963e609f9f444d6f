-- Misuse of plot.draw and plot.poses is blamed on their caller (the position in the message is
-- the caller's line), for the options checked in a helper as for the others: the title, the
-- sizes and the unit used to be blamed on tagpose.tools.plot itself.
local plot = require("tagpose.tools.plot")

local HERE = debug.getinfo(1, "S").short_src

-- the error of f(), which calls plot (not as a tail call, which Lua 5.1 would blame on a
-- "(tail call)" frame: this file must be the caller)
local function error_of(f)
  local ok, err = pcall(f)
  assert.is_false(ok)
  return err
end

describe("tagpose.tools.plot", function()
  local cases = {
    { "draw", function() local r = plot.draw(plot.recorder(), { title = 5 }); return r end,
      "bad argument #2 to 'draw' (options.title: string expected, got number 5)" },
    { "draw", function() local r = plot.draw(plot.recorder(), { width = 10 }); return r end,
      "bad argument #2 to 'draw' (options.width: number >= 100 expected, got number 10)" },
    { "draw", function() local r = plot.draw(plot.recorder(), { length_unit = true }); return r end,
      "bad argument #2 to 'draw' (options.length_unit: string expected, got boolean)" },
    { "draw", function() local r = plot.draw(3); return r end,
      "bad argument #1 to 'draw' (a recorder expected, got number)" },
    { "poses", function() local r = plot.poses({}, { panel_height = 0 }); return r end,
      "bad argument #2 to 'poses' (options.panel_height: number >= 100 expected, got number 0)" },
    { "poses", function() local r = plot.poses({}, { title = {} }); return r end,
      "bad argument #2 to 'poses' (options.title: string expected, got table)" },
    { "poses", function() local r = plot.poses({}, { rotation = "euler" }); return r end,
      "bad argument #2 to 'poses' (options.rotation: 'quaternion' or 'rpy' expected, got string"
      .. " euler)" },
  }
  for _, case in ipairs(cases) do
    describe(case[1] .. "()", function()
      it("blames its caller: " .. case[3], function()
        local err = error_of(case[2])
        assert.equal(HERE .. ":", err:sub(1, #HERE + 1))
        assert.equal(case[3], (err:gsub("^[^:]*:%d+: ", "")))
      end)
    end)
  end
end)
