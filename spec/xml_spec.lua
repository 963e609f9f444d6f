local xml = require("tagpose.formats.xml")

-- decode expecting a refusal; returns the message
local function refused(text, name)
  local v, err = xml.decode(text, name or "f.xml")
  assert.is_nil(v, "expected a refusal of:\n" .. text)
  return err
end

describe("tagpose.formats.xml", function()
  describe("decode()", function()
    it("reads elements, attributes and text, with the line of each child", function()
      local root = assert(xml.decode(table.concat({
        '<?xml version="1.0"?>',
        "<!-- written by hand -->",
        "<storage a='1' b=\"x &amp; y\">",
        "  <m type_id=\"opencv-matrix\">",
        "    <rows>3</rows><empty/>",
        "    <data>",
        "      1. 2 &lt;3&gt;</data></m>",
        "  <?skipped instruction?>",
        "  <s>\"a b\" c</s> <!-- between -->",
        "</storage>",
      }, "\n"), "f.xml"))
      assert.equal("storage", root.name)
      assert.equal(3, root.line)
      assert.same({ a = "1", b = "x & y" }, root.attributes)
      assert.equal(2, #root)
      local m, s = root[1], root[2]
      assert.same({ 4, 9 }, root.lines)
      assert.same({ "m", "s" }, { m.name, s.name })
      assert.same({ type_id = "opencv-matrix" }, m.attributes)
      assert.same({ "rows", "empty", "data" }, { m[1].name, m[2].name, m[3].name })
      assert.same({ 5, 5, 6 }, m.lines)
      assert.same({ "3" }, { m[1][1] })
      assert.equal(0, #m[2])
      -- text as written (references checked, not replaced), from the line it starts on
      assert.equal("\n      1. 2 &lt;3&gt;", m[3][1])
      assert.equal(6, m[3].lines[1])
      assert.equal("1. 2 <3>", xml.unescape("1. 2 &lt;3&gt;"))
      assert.equal('"a b" c', s[1])
    end)

    it("unescapes every reference XML has, and refuses others", function()
      assert.equal("<>&\"' \n\195\169\240\159\152\128",
        xml.unescape("&lt;&gt;&amp;&quot;&apos; &#10;&#xe9;&#x1F600;"))
      assert.same({ nil, "unknown entity reference '&nbsp;' (XML has &lt; &gt; &amp; &quot; &apos;"
        .. " and &#N;)" }, { xml.unescape("a&nbsp;b") })
      assert.same({ nil, "'&' that starts no reference (write &amp;)" }, { xml.unescape("a & b") })
      assert.same({ nil, "'&#0;' is not a character" }, { xml.unescape("&#0;") })
    end)

    it("refuses what it does not read, with the line", function()
      local cases = {
        { "<a>\n<b>\n</a>", "f.xml:3: </a> does not close <b> (line 2)" },
        { "<a>\n<b></b>", "f.xml:2: element <a> (line 1) is not closed" },
        { "<a></a>\n<b/>", "f.xml:2: unexpected content after the root element <a>" },
        { "<a>x</a>\ny", "f.xml:2: unexpected content after the root element <a>" },
        { "x<a/>", "f.xml:1: an element ('<') expected, got 'x'" },
        { "", "f.xml:1: no root element: the text is empty" },
        { '<!DOCTYPE a [<!ENTITY e "x">]>\n<a>&e;</a>', "f.xml:1: a document type declaration"
          .. " (<!DOCTYPE) is not read" },
        { "<a>\n<![CDATA[x]]></a>", "f.xml:2: a CDATA section is not read: write the text with"
          .. " &lt; and &amp;" },
        { "<a>\n1 & 2</a>", "f.xml:2: '&' that starts no reference (write &amp;)" },
        { "<a>&bogus;</a>", "f.xml:1: unknown entity reference '&bogus;' (XML has &lt; &gt;"
          .. " &amp; &quot; &apos; and &#N;)" },
        { "<a x='1' x='2'/>", "f.xml:1: attribute 'x' given twice" },
        { "<a x=1/>", "f.xml:1: the value of attribute 'x' must be quoted" },
        { "<a x='<'/>", "f.xml:1: '<' in the value of attribute 'x'" },
        { "<a x='1'y='2'/>", "f.xml:1: white space, '>' or '/>' expected in a tag" },
        { "<a>\n<!-- open </a>", "f.xml:2: a comment is not closed ('-->' expected)" },
        { "<a>< b/></a>", "f.xml:1: an element name expected after '<'" },
        { "<\195\169/>", "f.xml:1: an element name expected after '<'" },
      }
      for _, c in ipairs(cases) do
        assert.equal(c[2], refused(c[1]), c[1])
      end
    end)

    it("refuses nesting deeper than MAX_DEPTH, at once", function()
      local n = xml.MAX_DEPTH
      assert.is_table(xml.decode(string.rep("<a>", n) .. string.rep("</a>", n)))
      assert.equal("f.xml:1: nesting deeper than 64 levels", refused(string.rep("<a>", 100000)))
    end)

    it("names the line of a refusal that follows a long line",
      function()
        local long = "<a>" .. string.rep("<b>1</b>", 20000) .. "\n<c></a>"
        assert.equal("f.xml:2: </a> does not close <c> (line 2)", refused(long))
      end)

    it("raises on arguments that are not strings", function()
      assert.has_error(function() xml.decode(false) end,
        "bad argument #1 to 'decode' (string expected, got boolean)")
    end)
  end)
end)
