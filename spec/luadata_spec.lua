local luadata = require("tagpose.formats.luadata")

local function refused(text)
  local value, err = luadata.decode(text, "c.lua")
  assert.is_nil(value, "expected a refusal of:\n" .. text)
  return err
end

describe("tagpose.formats.luadata", function()
  describe("decode()", function()
    it("reads a table constructor of literals, with comments", function()
      local text = table.concat({
        "-- a camera",
        "--[==[ a long",
        "  comment ]==]",
        "return {",
        "  fx = 883.98, fy = -2.5e-1; cx = .5, cy = 3.,",
        "  distortion = { k1 = -0.28, [\"k2\"] = 0.07 },",
        "  [5] = 'three', 'first', \"se\\tcond\\65\\x42\\\\\",",
        "  long = [[",
        "two",
        "lines]], [=[a]]b]=],",
        "  none = nil, yes = true, no = false, [0] = 0, [-1] = -1,",
        "}",
      }, "\n")
      local v, where, at = assert(luadata.decode(text, "c.lua"))
      assert.same({ fx = 883.98, fy = -0.25, cx = 0.5, cy = 3,
        distortion = { k1 = -0.28, k2 = 0.07 }, [5] = "three", "first", "se\tcondAB\\",
        long = "two\nlines", "a]]b", yes = true, no = false, [0] = 0, [-1] = -1 }, v)
      assert.equal(4, at)
      assert.equal(5, where[v].fx)
      assert.equal(6, where[v.distortion].k2)
      assert.equal(10, where[v][3])
      assert.equal(11, where[v].none)
    end)

    it("counts CRLF and CR-only line ends as one line each", function()
      local _, where = assert(luadata.decode("return {\r\n a = 1,\r\n b = 2 }", "c.lua"))
      local v = assert(luadata.decode("return {\r a = 1,\r b = 2 }", "c.lua"))
      assert.same({ a = 1, b = 2 }, v)
      local w = select(2, luadata.decode("return {\r a = 1,\r b = 2 }", "c.lua"))
      for _, lines in pairs(where) do assert.equal(3, lines.b) end
      for _, lines in pairs(w) do assert.equal(3, lines.b) end
    end)

    it("refuses what is not data, with its line", function()
      local cases = {
        { "while true do end", "c.lua:1: a loop ('while') is not data: 'return { ... }'"
          .. " expected" },
        { "return {\n s = string.rep('x', 2^30) }", "c.lua:2: a global variable"
          .. " ('string.rep') is not data" },
        { "return { fx = tonumber('5') }", "c.lua:1: a call ('tonumber(...)') is not data" },
        { "return { fx = huge }", "c.lua:1: a global variable ('huge') is not data" },
        { "return {\n\n fx = 1 + 2 }", "c.lua:3: an operator ('+') is not data" },
        { "return { fx = 600 * 2 }", "c.lua:1: an operator ('*') is not data" },
        { "return { f = function() end }", "c.lua:1: a function ('function') is not data" },
        { "local c = {}\nreturn c", "c.lua:1: a statement ('local') is not data: 'return"
          .. " { ... }' expected" },
        { "camera = { fx = 1 }", "c.lua:1: an assignment or a call ('camera') is not data:"
          .. " 'return { ... }' expected" },
        { "return {\n fx = 1,\n fx = 2 }", "c.lua:3: key 'fx' given twice (first on line 2)" },
        { "return { 5, [1] = 6 }", "c.lua:1: key [1] given twice (first on line 1)" },
        { "return { fx = 0x10 }", "c.lua:1: hexadecimal numeral 0x10: write the decimal value" },
        { "return { fx = 1 fy = 2 }", "c.lua:1: ',' or '}' expected, got 'fy'" },
        { "return { fx = 1\n", "c.lua:2: table from line 1 not closed" },
        { "return { fx = 1,", "c.lua:1: a value expected, got the end of the file" },
        { "return { a = 'open\n' }", "c.lua:1: unfinished string (a line end inside quotes)" },
        { "return { a = [[ open }", "c.lua:1: long string from line 1 not closed" },
        { "return {} {}", "c.lua:1: unexpected '{' after the returned value" },
        { "return { a = - 'x' }", "c.lua:1: an operator ('-') is not data" },
        { "return { a = 1 .. 2 }", "c.lua:1: an operator ('..') is not data" },
        { "return { a = ... }", "c.lua:1: '...' is not data" },
        { "return { a = (1) }", "c.lua:1: a parenthesised expression is not data" },
        { "return { [nil] = 1 }", "c.lua:1: a nil key" },
        { "", "c.lua:1: the file is empty: 'return { ... }' expected" },
        { "return { a = '\\z' }", "c.lua:1: escape \\z is not read (write the character or"
          .. " \\ddd)" },
      }
      for _, case in ipairs(cases) do
        assert.equal(case[2], refused(case[1]), case[1])
      end
    end)

    it("bounds the nesting", function()
      local deep = "return " .. string.rep("{", luadata.MAX_DEPTH + 1)
        .. string.rep("}", luadata.MAX_DEPTH + 1)
      assert.equal("c.lua:1: tables nested deeper than " .. luadata.MAX_DEPTH, refused(deep))
    end)

    it("raises on a text that is not a string", function()
      assert.has_error(function() luadata.decode(nil) end,
        "bad argument #1 to 'decode' (string expected, got nil)")
    end)
  end)
end)
