--- The cube: its 24 rotations, the names of its faces, the choice of one frame among its
-- symmetric equivalents, and the layout of the standard cube.
--
-- A block frame has its origin at the cube's centre and its axes along the face normals.
-- Rotations are flat, row-major 3×3 arrays (see `tagpose.rotation`). The cube's rotation group
-- is the 24 signed permutation matrices with determinant +1; when the faces cannot be told
-- apart, the frames `R·G` for every `G` of the group are the same block.
--
-- A face is named by its outward normal: `"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`. A tag
-- lies on a face with its z axis into the block, so a tag whose frame in the block frame is
-- `G` sits on the face with outward normal `-G·e_z` (`face_of`). Where the tags sit on the
-- faces is a layout's business: `layout` places the standard cube's tags (the public
-- `tagpose.layout.cube`), and a block is any layout of tags on a cube (`tagpose.block.body`).
-- @module tagpose.rigid.cube

local rotation = require("tagpose.core.rotation")
local args = require("tagpose.core.args")
local model = require("tagpose.rigid.model")

local abs, min = math.abs, math.min
local is_positive, describe, size_of = args.is_positive, args.describe, args.size_of

local M = {}

-- Raise a misuse at the caller of `layout`.
local function raise(n, fname, message)
  args.raise(n, fname, message, 3)
end

-- The column permutations p (row i has its entry in column p[i]) and their parities; a rotation
-- of the cube is a permutation with signs on its rows whose product is the parity.
local PERMUTATIONS = { { 1, 2, 3 }, { 1, 3, 2 }, { 2, 1, 3 }, { 2, 3, 1 }, { 3, 1, 2 },
  { 3, 2, 1 } }
local PARITY = { 1, -1, -1, 1, 1, -1 }

--- The 24 rotations of the cube, flat row-major; `ROTATIONS[1]` is the identity. Constants:
-- never write into them.
M.ROTATIONS = {}

-- BY_PATTERN[(p - 1) * 8 + bits + 1]: the index into ROTATIONS of permutation p with the rows'
-- signs as bits 1, 2, 4 (set = negative)
local BY_PATTERN = {}

for p = 1, 6 do
  local perm = PERMUTATIONS[p]
  for i = 0, 1 do
    for j = 0, 1 do
      for k = 0, 1 do
        local s1, s2, s3 = 1 - 2 * i, 1 - 2 * j, 1 - 2 * k
        if s1 * s2 * s3 == PARITY[p] then
          local g = { 0, 0, 0, 0, 0, 0, 0, 0, 0 }
          g[perm[1]], g[3 + perm[2]], g[6 + perm[3]] = s1, s2, s3
          M.ROTATIONS[#M.ROTATIONS + 1] = g
          BY_PATTERN[(p - 1) * 8 + i + 2 * j + 4 * k + 1] = #M.ROTATIONS
        end
      end
    end
  end
end

local ROTATIONS = M.ROTATIONS

--- The face names, in the order of the axes: `"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`.
-- A constant.
M.FACE_NAMES = {}

--- The outward normal `{x, y, z}` of each face, by name. Constants.
M.NORMALS = {}

for axis, letter in ipairs({ "x", "y", "z" }) do
  for _, sign in ipairs({ 1, -1 }) do
    local name = (sign > 0 and "+" or "-") .. letter
    local n = { 0, 0, 0 }
    n[axis] = sign
    M.FACE_NAMES[#M.FACE_NAMES + 1], M.NORMALS[name] = name, n
  end
end

local NORMAL_NAMES = M.FACE_NAMES

--- `INVERSE[k]` is the index of the inverse (transpose) of `ROTATIONS[k]`.
M.INVERSE = {}

--- The cube rotation nearest to a 3×3 matrix (the one maximising `trace(Gᵀ·r)`).
-- For each column permutation the best signs are those of the entries it picks, with the
-- smallest entry's sign turned when they would make a reflection.
-- @tparam {number,...} r flat 3×3
-- @treturn int index into `ROTATIONS`
-- @treturn number the angle between `r` and that rotation, radians (when `r` is a rotation)
function M.nearest(r)
  -- the best permutation (few live values: LuaJIT compiles this loop)
  local best, score = 1, -math.huge
  for p = 1, 6 do
    local perm = PERMUTATIONS[p]
    local a1, a2, a3 = r[perm[1]], r[3 + perm[2]], r[6 + perm[3]]
    local s = abs(a1) + abs(a2) + abs(a3)
    -- signs that make a reflection: the smallest entry's sign is turned
    if (a1 * a2 * a3 < 0) == (PARITY[p] == 1) then
      s = s - 2 * min(abs(a1), abs(a2), abs(a3))
    end
    if s > score then best, score = p, s end
  end
  -- its signs
  local perm = PERMUTATIONS[best]
  local a1, a2, a3 = r[perm[1]], r[3 + perm[2]], r[6 + perm[3]]
  local n1, n2, n3 = a1 < 0, a2 < 0, a3 < 0
  if (a1 * a2 * a3 < 0) == (PARITY[best] == 1) then
    local b1, b2, b3 = abs(a1), abs(a2), abs(a3)
    if b1 <= b2 and b1 <= b3 then
      n1 = not n1
    elseif b2 <= b3 then
      n2 = not n2
    else
      n3 = not n3
    end
  end
  local bits = (n1 and 1 or 0) + (n2 and 2 or 0) + (n3 and 4 or 0)
  local c = 0.5 * (score - 1)
  if c > 1 then c = 1 elseif c < -1 then c = -1 end
  return BY_PATTERN[(best - 1) * 8 + bits + 1], math.acos(c)
end

for k, g in ipairs(ROTATIONS) do
  M.INVERSE[k] = M.nearest({ g[1], g[4], g[7], g[2], g[5], g[8], g[3], g[6], g[9] })
end

--- The cube rotation a nested 3×3 matrix is (to within `angle`), as an index into `ROTATIONS`.
-- @tparam any m `{{r11, r12, r13}, {r21, r22, r23}, {r31, r32, r33}}`
-- @tparam[opt=1e-6] number angle how far from it `m` may be, radians
-- @treturn int|nil the index, or nil when `m` is not a table of finite rows or is further (in
--   the Frobenius norm, as a rotation that far would be)
function M.of_nested(m, angle)
  if type(m) ~= "table" then return nil end
  local flat = {}
  for i = 1, 3 do
    local row = m[i]
    if type(row) ~= "table" then return nil end
    for j = 1, 3 do
      local v = row[j]
      if not (type(v) == "number" and v == v and abs(v) < math.huge) then return nil end
      flat[(i - 1) * 3 + j] = v
    end
  end
  -- the nearest, and how far: ‖m − G‖² = 4 (1 − cos θ) for a rotation m at angle θ from G
  local k = M.nearest(flat)
  local g, d2 = ROTATIONS[k], 0
  for i = 1, 9 do d2 = d2 + ((flat[i] - g[i]) * (flat[i] - g[i])) end
  if not (d2 <= 4 * (1 - math.cos(angle or 1e-6)) + 1e-15) then return nil end
  return k
end

--- Name of the face whose outward normal is `(nx, ny, nz)` (the nearest axis direction).
-- @tparam number nx
-- @tparam number ny
-- @tparam number nz
-- @treturn string `"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"` or `"-z"`
function M.face_name(nx, ny, nz)
  local ax, ay, az = nx < 0 and -nx or nx, ny < 0 and -ny or ny, nz < 0 and -nz or nz
  if ax >= ay and ax >= az then return NORMAL_NAMES[nx >= 0 and 1 or 2] end
  if ay >= az then return NORMAL_NAMES[ny >= 0 and 3 or 4] end
  return NORMAL_NAMES[nz >= 0 and 5 or 6]
end

--- The face a tag sits on, from its rotation `g` in the block frame: outward normal `-g·e_z`.
-- @tparam {number,...} g flat 3×3 (a cube rotation, or near one)
-- @treturn string face name
function M.face_of(g)
  return M.face_name(-g[3], -g[6], -g[9])
end

--- The symmetric equivalent `r·G` of a block rotation that is nearest to a reference rotation.
-- @tparam {number,...} r flat block → camera rotation
-- @tparam {number,...} ref flat reference rotation (e.g. the block's rotation last frame)
-- @tparam {number,...} out array to fill (may be `r`; not `ref`)
-- @treturn {number,...} out
local relative = {} -- scratch: rᵀ·ref

function M.closest(r, ref, out)
  -- G = nearest(rᵀ·ref)
  local g = ROTATIONS[(M.nearest(rotation.transpose_multiply(r, ref, relative)))]
  return rotation.multiply(r, g, out)
end

--- The face axis of a block rotation nearest a direction: the column of `r` most parallel or
-- anti-parallel to `(ux, uy, uz)` (ties go to the earlier column), unrolled.
-- @tparam {number,...} r flat block → camera rotation
-- @tparam number ux the direction, camera frame (need not be unit)
-- @tparam number uy
-- @tparam number uz
-- @treturn int k the column (1, 2 or 3)
-- @treturn number the column's dot product with the direction (its sign: which way it points)
function M.nearest_axis(r, ux, uy, uz)
  local d1 = r[1] * ux + r[4] * uy + r[7] * uz
  local d2 = r[2] * ux + r[5] * uy + r[8] * uz
  local d3 = r[3] * ux + r[6] * uy + r[9] * uz
  if abs(d1) >= abs(d2) and abs(d1) >= abs(d3) then return 1, d1 end
  if abs(d2) >= abs(d3) then return 2, d2 end
  return 3, d3
end

--- The canonical frame among a block rotation's 24 equivalents: block z is the face axis
-- (signed column of `r`) closest to `up`, block x the remaining face axis closest to `ahead`,
-- y = z × x. Ties go to the earlier column and to `+` before `-`.
-- @tparam {number,...} r flat block → camera rotation
-- @tparam number ux up, camera frame (need not be unit)
-- @tparam number uy
-- @tparam number uz
-- @tparam number ax ahead, camera frame (e.g. the direction from the camera to the block)
-- @tparam number ay
-- @tparam number az
-- @tparam {number,...} out array to fill (may be `r`)
-- @treturn {number,...} out
function M.canonical(r, ux, uy, uz, ax, ay, az, out)
  -- z: the column most (anti-)parallel to up
  local kz, sz = M.nearest_axis(r, ux, uy, uz)
  sz = sz < 0 and -1 or 1
  -- x: of the other two, the column most (anti-)parallel to ahead
  local kp, kq = 2, 3
  if kz == 2 then kp = 1 elseif kz == 3 then kp, kq = 1, 2 end
  local e1 = r[kp] * ax + r[3 + kp] * ay + r[6 + kp] * az
  local e2 = r[kq] * ax + r[3 + kq] * ay + r[6 + kq] * az
  local kx, sx = kp, e1
  if abs(e2) > abs(e1) then kx, sx = kq, e2 end
  sx = sx < 0 and -1 or 1
  local zx, zy, zz = sz * r[kz], sz * r[3 + kz], sz * r[6 + kz]
  local xx, xy, xz = sx * r[kx], sx * r[3 + kx], sx * r[6 + kx]
  out[1], out[4], out[7] = xx, xy, xz
  out[2], out[5], out[8] = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx
  out[3], out[6], out[9] = zx, zy, zz
  return out
end

-- The tag frame on each face of the standard cube, `[tag_x tag_y tag_z]` (columns) in the
-- block frame, flat row-major: tag z into the block; on the side faces tag y = -z (the tag
-- upright on an upright block), tag x = tag y × tag z; on the top tag x = +x, tag y = -y; on
-- the bottom tag x = +x, tag y = +y. The one place where tagpose puts tags on a cube's faces.
local FACE_FRAMES = {
  ["+x"] = { 0, 0, -1, 1, 0, 0, 0, -1, 0 },
  ["-x"] = { 0, 0, 1, -1, 0, 0, 0, -1, 0 },
  ["+y"] = { -1, 0, 0, 0, 0, -1, 0, -1, 0 },
  ["-y"] = { 1, 0, 0, 0, 0, 1, 0, -1, 0 },
  ["+z"] = { 1, 0, 0, 0, -1, 0, 0, 0, -1 },
  ["-z"] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 },
}

-- the default faces: ids 0 to 5 on +x, -x, +y, -y, +z, -z
local DEFAULT_FACES = { [0] = "+x", "-x", "+y", "-y", "+z", "-z" }

--- The layout of the standard cube: a centred tag on each face named (`tagpose.layout.cube`,
-- documented there), raising `bad argument #n to 'cube'` at its caller.
-- @tparam number|table tag_size side of the tags' black squares; or the sides by tag id
-- @tparam number block_size side of the cube
-- @tparam[opt] table faces tag id → face name or nested 3×3 rotation of the cube
-- @treturn table layout `{tags = {[id] = {size =, position =, quaternion =}}}`
function M.layout(tag_size, block_size, faces)
  local problem = args.check_sizes(tag_size, "tag_size")
  if problem then raise(1, "cube", problem) end
  for _, size in pairs(type(tag_size) == "table" and tag_size or { tag_size }) do
    if not (is_positive(block_size) and block_size > size) then
      raise(2, "cube", "number above tag_size expected for block_size, got "
        .. describe(block_size))
    end
  end
  faces = faces or DEFAULT_FACES
  if type(faces) ~= "table" then raise(3, "cube", "table expected, got " .. type(faces)) end
  local tags, half = {}, 0.5 * block_size
  for id, face in pairs(faces) do
    local k = type(face) ~= "string" and M.of_nested(face)
    local r = FACE_FRAMES[face] or M.ROTATIONS[k]
    if not (model.is_id(id) and r) then
      raise(3, "cube", "faces[" .. tostring(id) .. "]: face '+x', '-x', '+y', '-y', '+z' or "
        .. "'-z', or a 3x3 rotation of the cube, expected")
    end
    local size = size_of(tag_size, id)
    if size == nil then
      raise(1, "cube", "tag_size has no size for tag id " .. tostring(id) .. " and no default")
    end
    -- the face's outward normal: -R_f·e_z
    tags[id] = model.entry(r, 0 - half * r[3], 0 - half * r[6], 0 - half * r[9], size)
  end
  return { tags = tags }
end

return M
