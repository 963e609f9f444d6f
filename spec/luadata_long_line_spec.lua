-- Reading stays linear in the length of a line: the lexer used to look for the next line end
-- from every token, scanning the rest of the line each time, so that one line of 50000
-- numbers (a calibration or layout file written by a script without line breaks, 440 KB,
-- under calibration.MAX_BYTES) took 396 s of CPU on Lua 5.4 (measured, not timed: it takes a
-- fraction of a second now).
local luadata = require("tagpose.formats.luadata")

describe("tagpose.formats.luadata", function()
  describe("decode() on long lines", function()
    it("reads 50000 values on one line, and counts the lines around them", function()
      local items = {}
      for i = 1, 50000 do items[i] = tostring(i - 0.5) end
      local text = "-- one line\r\nreturn { " .. table.concat(items, ", ") .. ", k = 'x' }\n"
      local v, where, at = assert(luadata.decode(text, "long.lua"))
      assert.equal(50000, #v)
      assert.equal(49999.5, v[50000])
      assert.equal(2, at)
      assert.equal(2, where[v][50000])
      assert.equal(2, where[v].k)
    end)

    it("reads a long comment and a long string of many lines, counting each line end", function()
      local lines = {}
      for i = 1, 20000 do lines[i] = ("line %d"):format(i) end
      local body = table.concat(lines, "\n")
      local text = "--[[" .. body .. "]] return {\r\n a = [==[\n" .. body .. "]==],\n\r b = 1 }"
      local v, where = assert(luadata.decode(text, "long.lua"))
      assert.equal(body, v.a)
      assert.equal(20001, where[v].a)
      assert.equal(40002, where[v].b)
    end)
  end)
end)
