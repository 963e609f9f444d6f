--- A small YAML reader for the calibration and layout files users have.
--
-- It reads exactly the YAML that ROS `camera_calibration` (`ost.yaml`), OpenCV's FileStorage
-- (`%YAML:1.0`, `!!opencv-matrix`) and apriltag_ros (`tags.yaml`) write, and refuses anything
-- else with the line number, so that nothing is read differently from what the file says:
--
-- * the `%YAML` directive (`%YAML 1.2` and OpenCV's `%YAML:1.0`), a `---` line before the
--   document and a `...` or `---` line after it; `#` comments;
-- * block mappings (nesting by indentation, spaces only) and block sequences (`- item`, also
--   at the indentation of the key that owns them);
-- * flow sequences `[a, b]` and flow mappings `{k: v}`, nested, across any number of lines,
--   with comments between their entries;
-- * plain scalars, `'single'` (`''` for a quote) and `"double"`-quoted scalars (escapes
--   `\\ \" \/ \b \f \n \r \t \0 \xHH \uHHHH \UHHHHHHHH`), each on one line;
-- * the tags `!!opencv-matrix` and `!!opencv-nd-matrix` on a mapping.
--
-- Refused, with the line: anchors and aliases, block scalars (`|`, `>`), complex keys (`?`),
-- other tags and directives, plain or quoted scalars continued on the next line, tabs in
-- indentation, duplicate keys, a second document, nesting deeper than `MAX_DEPTH`, the
-- YAML 1.1 booleans `yes/no/on/off` (unquoted: YAML 1.1 and 1.2 readers disagree on them), and
-- `.nan`, `.inf`, `-.inf` (a calibration never holds them; nothing downstream must meet them).
--
-- Values: a mapping is a Lua table by key, a sequence a Lua array, `null`, `~` and an empty
-- value are `NULL` (never `nil`, so that arrays have no holes and a key given without a value
-- is still seen), `true`/`false` (also `True`, `TRUE`, ...) booleans, and a plain scalar that is
-- a decimal number (`640`, `-0.`, `.5`, `6.5e+02`, `1E-3`) a Lua number, the same on every VM
-- (an integer of 16 digits or more, which Lua 5.3's integers would keep exact and doubles
-- round, is read as the nearest double everywhere); other scalars are strings. A plain key is
-- resolved the same way (`0: x` has the number key 0). A tagged mapping carries its tag name
-- without the `!!` under the key `TAG`.
--
-- The reader runs in time linear in the text and never calls back into Lua code it reads. Its
-- parts: `tagpose.formats.yaml.scanner` (lines, indentation, directives; the reading state),
-- `tagpose.formats.yaml.scalar` (what a scalar means, quoting, tags), `tagpose.formats.yaml.block`
-- (block mappings and sequences) and `tagpose.formats.yaml.flow` (`[...]` and `{...}`).
-- @module tagpose.formats.yaml

local failure = require("tagpose.formats.failure")
local scanner = require("tagpose.formats.yaml.scanner")
local scalar = require("tagpose.formats.yaml.scalar")
local block = require("tagpose.formats.yaml.block")

local M = {}

--- The value of `null`, `~` and empty values (a unique table; compare with `==`).
M.NULL = scalar.NULL

--- The key under which a tagged mapping holds its tag (`"opencv-matrix"`): a unique table,
-- so it never collides with a key of the file; skip it when iterating with `pairs`.
M.TAG = scalar.TAG

--- Deepest nesting of collections read (deeper input is refused).
M.MAX_DEPTH = 64

local function parse(text, name)
  return block.document(scanner.open(text, name, M.MAX_DEPTH))
end

--- Decode a YAML document.
-- @tparam string text the document
-- @tparam[opt="yaml"] string name the file's name, for messages
-- @treturn any the value: a table for a mapping or sequence, a number, string, boolean or
--   `NULL`
-- @treturn table where each key was read: `lines[container][key]` is the line of a mapping's
--   key or of a sequence's item (`container` a table of the value)
-- @return nil, string `"name:LINE: reason"` when the text is not YAML this reader accepts
-- @raise `bad argument #n to 'decode' (...)` when `text` or `name` is not a string
-- @usage
-- local doc, where = yaml.decode("camera_matrix: !!opencv-matrix\n  rows: 3\n", "cal.yaml")
-- print(doc.camera_matrix[yaml.TAG], doc.camera_matrix.rows) --> opencv-matrix 3
-- print(where[doc].camera_matrix)                            --> 1
function M.decode(text, name)
  failure.check(text, name, true)
  return failure.protect(parse, text, name or "yaml")
end

return M
