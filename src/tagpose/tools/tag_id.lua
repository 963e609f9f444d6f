--- Tag ids in the tools' words: what one is and how one prints, as tagpose documents them
-- (docs/layouts.md: a tag id is a whole number of magnitude below 2^53 everywhere in tagpose,
-- every one exact in a double and printed back as it was read). The tools are a client of the
-- library's public fields only, so they keep the documented definition here; a spec checks it
-- against what `tagpose.layout` accepts.
-- @module tagpose.tools.tag_id

local floor, format, huge = math.floor, string.format, math.huge

local M = {}

--- What a tag id is, for messages.
M.ID = "a whole number of magnitude below 2^53"

--- 2^53: every tag id is of smaller magnitude.
M.MAX = 9007199254740992

--- True for a whole number usable as a tag id: `|id| < 2^53`.
-- @tparam any id
-- @treturn boolean
function M.is(id)
  return type(id) == "number" and id == id and id < huge and id > -huge and id == floor(id)
    and id < M.MAX and id > -M.MAX
end

--- An id as the layout files print it (`%.0f`: every id below 2^53 exactly, on every VM; `0`
-- for -0).
-- @tparam number id a tag id
-- @treturn string
function M.text(id)
  if id == 0 then return "0" end
  return format("%.0f", id)
end

return M
