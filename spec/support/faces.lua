-- The faces of the lab's blocks, written out from the data set's convention (block frame: axes
-- along the face normals; tag z into the block; side tags upright), independently of tagpose:
-- the outward normal and the tag frame R_f = [tag_x tag_y tag_z] (columns) in the block frame,
-- flat row-major.
local F = {}

F.FACES = {
  { name = "+x", n = { 1, 0, 0 }, r = { 0, 0, -1, 1, 0, 0, 0, -1, 0 } },
  { name = "-x", n = { -1, 0, 0 }, r = { 0, 0, 1, -1, 0, 0, 0, -1, 0 } },
  { name = "+y", n = { 0, 1, 0 }, r = { -1, 0, 0, 0, 0, -1, 0, -1, 0 } },
  { name = "-y", n = { 0, -1, 0 }, r = { 1, 0, 0, 0, 0, 1, 0, -1, 0 } },
  { name = "+z", n = { 0, 0, 1 }, r = { 1, 0, 0, 0, -1, 0, 0, 0, -1 } },
  { name = "-z", n = { 0, 0, -1 }, r = { 1, 0, 0, 0, 1, 0, 0, 0, 1 } },
}

F.BY_NAME = {}
for _, f in ipairs(F.FACES) do F.BY_NAME[f.name] = f end

return F
