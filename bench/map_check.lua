-- The map check of a drive log against the move its meta.json says one tag was given: the
-- moved tag must come first, its (dx, dy, dz) within TOLERANCE of the true move.
--
--   lua5.4 bench/map_check.lua DIR CHECK.csv     (CHECK.csv from tagpose-localize --map-check)
--
-- Prints the first rows and the verdict; exits 1 when the moved tag is not first or is off by
-- more than TOLERANCE. A log whose meta.json moved no tag passes when it prints.
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local json = require("tagpose.formats.json")

local TOLERANCE = 0.04 -- m

local dir, path = arg[1], arg[2]
local f = assert(io.open(dir .. "/meta.json"))
local meta = assert(json.decode(f:read("*a"), "meta.json"))
f:close()
local rows = {}
for line in io.lines(path) do
  local id, dx, dy, dz, d, n = line:match("^(%d+),([^,]+),([^,]+),([^,]+),([^,]+),(%d+)$")
  if id then
    rows[#rows + 1] = { id = tonumber(id), dx = tonumber(dx), dy = tonumber(dy),
      dz = tonumber(dz), d = tonumber(d), n = tonumber(n) }
  end
end
for k = 1, math.min(3, #rows) do
  local r = rows[k]
  print(("map check: tag %d seen %.3f %.3f %.3f m from its place (%.3f m, %d frames)")
    :format(r.id, r.dx, r.dy, r.dz, r.d, r.n))
end
local moved = meta.moved_tag
-- (a log that moved no tag says `"moved_tag": null`)
if not moved or moved == json.NULL then return end
local t, p = moved["true"], moved.published
local mx, my, mz = t[1] - p[1], t[2] - p[2], t[3] - p[3]
local first = rows[1]
local off = first and first.id == moved.id
  and math.sqrt((first.dx - mx) ^ 2 + (first.dy - my) ^ 2 + (first.dz - mz) ^ 2)
if off and off <= TOLERANCE then
  print(("map check: the moved tag %d first, %.3f m from its true move (%.3f %.3f %.3f)")
    :format(moved.id, off, mx, my, mz))
else
  print(("map check: FAILED: tag %d was moved by (%.3f %.3f %.3f); first is %s")
    :format(moved.id, mx, my, mz, first and ("tag " .. first.id) or "nothing"))
  os.exit(1)
end
