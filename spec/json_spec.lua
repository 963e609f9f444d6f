local json = require("tagpose.formats.json")

-- decode expecting a refusal; returns the message
local function refused(text, name)
  local v, err = json.decode(text, name or "f.json")
  assert.is_nil(v, "expected a refusal of:\n" .. text)
  return err
end

describe("tagpose.formats.json", function()
  describe("decode()", function()
    it("reads objects, arrays, strings, numbers and literals, with the line of each entry",
      function()
        local text = table.concat({
          "{",
          '  "tags": [',
          '    {"ID": 1, "pose": {"x": -1.5e-3, "y": 0, "z": 12345678901234567890}},',
          '    {"ID": 2, "ok": true, "no": false, "none": null}',
          "  ],",
          '  "name": "field \\"A\\" \\u00e9\\ud83d\\ude00\\n"',
          "}",
        }, "\n")
        local doc, where = assert(json.decode(text, "f.json"))
        assert.equal(1, doc.tags[1].ID)
        assert.equal(-1.5e-3, doc.tags[1].pose.x)
        assert.equal(1.2345678901234567e19, doc.tags[1].pose.z)
        assert.same({ true, false, json.NULL }, { doc.tags[2].ok, doc.tags[2].no,
          doc.tags[2].none })
        assert.equal('field "A" \195\169\240\159\152\128\n', doc.name)
        assert.same({ tags = 2, name = 6 }, where[doc])
        assert.same({ 3, 4 }, where[doc.tags])
        assert.same({ x = 3, y = 3, z = 3 }, where[doc.tags[1].pose])
      end)

    it("reads every number as the nearest double, the same on every VM", function()
      local cases = { { "0", 0 }, { "-0", -0.0 }, { "1e2", 100 }, { "0.1", 0.1 },
        { "6.5746697944293521e+02", 6.5746697944293521e+02 }, { "-2E-3", -2e-3 },
        { "4.9406564584124654e-324", 4.9406564584124654e-324 } }
      for _, c in ipairs(cases) do
        local v = assert(json.decode("[" .. c[1] .. "]"))
        assert.equal(c[2], v[1], c[1])
      end
    end)

    it("reads what OpenCV's FileStorage writes in its JSON: // comments, \\'", function()
      local doc, where = assert(json.decode('{\n    // flags: +fix_k4\n    "s": "c\\\'d"\n}'))
      assert.equal("c'd", doc.s)
      assert.equal(3, where[doc].s)
    end)

    it("gives null as the caller's value when asked", function()
      local null = {}
      local doc = assert(json.decode('{"a": null, "b": [null]}', "f.json", null))
      assert.equal(null, doc.a)
      assert.equal(null, doc.b[1])
    end)

    it("skips a byte-order mark and counts \\r\\n and \\r as line ends", function()
      local doc, where = assert(json.decode('\239\187\191{\r\n"a": 1,\r"b": 2}'))
      assert.same({ a = 2, b = 3 }, where[doc])
    end)

    it("refuses what is not JSON, with the line", function()
      local cases = {
        { '{"a": 1,\n "b": 2,\n}', "f.json:3: a trailing comma before '}'" },
        { '{\n"a": 1,\n"a": 2}', "f.json:3: duplicate key 'a' (first on line 2)" },
        { "{'a': 1}", "f.json:1: a key (a string in double quotes) expected, got '''" },
        { "{a: 1}", "f.json:1: a key (a string in double quotes) expected, got 'a'" },
        { '{"a" 1}', "f.json:1: ':' expected, got '1'" },
        { "[1 2]", "f.json:1: ',' or ']' expected, got '2'" },
        { "[01]", "f.json:1: a number with a leading zero" },
        { "[1.]", "f.json:1: a digit expected in a number, got ']'" },
        { "[.5]", "f.json:1: a digit expected in a number, got '.'" },
        { "[+1]", "f.json:1: a value expected, got '+1'" },
        { "[1e999]", "f.json:1: number 1e999 is beyond the range of doubles" },
        { '{"x":\n .Nan}', "f.json:2: '.Nan' (not a number or infinite) is refused" },
        { '{"x": -.Inf}', "f.json:1: '-.Inf' (not a number or infinite) is refused" },
        { "[NaN]", "f.json:1: a value expected, got 'NaN'" },
        { "[tru]", "f.json:1: a value expected, got 'tru'" },
        { '["a\tb"]', "f.json:1: control character (byte 9) in a string: escape it" },
        { '["a\\x41"]', "f.json:1: unknown escape \\x in a string" },
        { '["\\ud83d"]', "f.json:1: a lone UTF-16 surrogate in \\u" },
        { '["\\u12"]', "f.json:1: \\u needs four hexadecimal digits" },
        { '["abc', "f.json:1: a string is not closed" },
        { "[1,\n", "f.json:2: a value expected, got the end of the text" },
        { "{}\n{}", "f.json:2: unexpected content after the value: '{'" },
        { "  \n ", "f.json:2: no value: the text is empty" },
        { "/* c */ 1", "f.json:1: a value expected, got '/'" },
      }
      for _, c in ipairs(cases) do
        assert.equal(c[2], refused(c[1]), c[1])
      end
    end)

    it("refuses nesting deeper than MAX_DEPTH, at once", function()
      local ok = string.rep("[", json.MAX_DEPTH) .. string.rep("]", json.MAX_DEPTH)
      assert.is_table(json.decode(ok))
      local deep = string.rep("[", 100000)
      assert.equal("f.json:1: nesting deeper than 64 levels", refused(deep))
    end)

    it("raises on arguments that are not strings", function()
      assert.has_error(function() json.decode(nil) end,
        "bad argument #1 to 'decode' (string expected, got nil)")
      assert.has_error(function() json.decode("1", 2) end,
        "bad argument #2 to 'decode' (string expected, got number)")
    end)
  end)
end)
