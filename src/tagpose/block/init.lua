--- Blocks: the pose of cubes from the tags on their faces.
--
-- A block is a cube of side `block_size` carrying tags on its faces: a layout
-- (`tagpose.layout`) of one cube, each tag's frame placed in the block frame, whose origin is
-- the cube's centre and whose axes are along the face normals; every block in view is a copy
-- of it. By default it is the standard cube (`tagpose.layout.cube`): a centred tag of any id on
-- every face, its z axis into the block; the faces cannot be told apart, so a block's rotation
-- is defined up to the cube's 24 symmetries and a canonical one is returned. With
-- `options.layout` (a cube whose ids tell its tags apart: one calibrated from its log by
-- `tagpose.layout.calibrate`, say) or `options.faces` (tag id → face: the layout
-- `tagpose.layout.cube(tag_size, block_size, faces)`) the block frame is the layout's.
--
-- The stages, per frame, each a module of its own:
--
-- 1. `tagpose.block.options` and `tagpose.block.body`: the options, and the block they and the
--    sizes describe, read once;
-- 2. `tagpose.block.frame`: every detection solved alone by the single-tag pipeline
--    (`tagpose.core.pipeline`): one or two candidate poses (the planar ambiguity), each implying a
--    block centre and rotation; the frame's corner noise;
-- 3. `tagpose.block.search`, on `tagpose.block.group` and `tagpose.block.fit`: from every
--    candidate as a seed, the free detections that agree with it form a hypothesis, fitted
--    jointly over all its corners and kept together only while the fit is consistent with the
--    members' own fits (an F-test); the best hypothesis (most members, then the lowest error)
--    becomes a block, its tags leave the pool, and the rest are grouped again; a block seen
--    with one face keeps both candidates;
-- 4. `tagpose.block.scene`: with `up = "auto"` or `floor = "auto"`, what the blocks seen with
--    two or more faces show of up and the floor, for those seen with one;
-- 5. `tagpose.block.result`, on `tagpose.block.identity` and `tagpose.block.uncertainty`: the
--    blocks kept, their ids and frames across frames (`options.previous`), or the canonical
--    frame, and their uncertainty.
--
-- Lengths are in the unit of the tags' sizes, angles in radians, errors in pixels.
-- @module tagpose.block

local compat = require("tagpose.core.compat")
local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local read_options = require("tagpose.block.options").read
local body_model = require("tagpose.block.body")
local frame = require("tagpose.block.frame")
local search = require("tagpose.block.search")
local result = require("tagpose.block.result")

local M = {}

compat.interpret_module()

-- the call the corner-order hint names
local CALL = "tagpose.block.solve(detections, camera, tag_size, block_size, options)"

local function arg_error(n, message)
  args.raise(n, "solve", message, 3)
end

--- Solve the poses of the blocks whose tags one frame shows.
-- @tparam {table,...} detections array of `{id = n, corners = {...}}`, `corners` as
--   `tagpose.solve` takes them (four points `{u, v}` or `{x =, y =}` in detection order, pixels)
-- @tparam table camera `{fx =, fy =, cx =, cy =}` in pixels, optionally `distortion` and
--   `model` (see `tagpose.camera`)
-- @tparam number|table|nil tag_size side of the tags' black squares (> 0); lengths come out in
--   its unit. Or the sides by tag id, `{[id] = size, default = size}` (`default` optional: a tag
--   with no size is skipped, with its reason). With `options.layout`: nil (the layout's sizes),
--   or sizes that agree with the layout's
-- @tparam number|nil block_size side of the cube (> `tag_size`). With `options.layout`: nil
--   (twice the median distance of its tags from its centre along their faces' normals), or the
--   side of the cube on whose faces its tags lie
-- @tparam[opt] table options
--
--   - `up`: a vector `{x =, y =, z =}` (or `{x, y, z}`) in the camera frame pointing up
--     (against gravity), when known: a block resting on a face has a face axis along it, which
--     decides between the two poses of a block seen with one face and steadies every fit; it
--     also sets the canonical z. Default: none (and `(0, -1, 0)` for the canonical choice).
--     `"auto"`: when the frame has blocks seen with two or more faces, up is their face axis
--     nearest the camera's -y, used for the blocks seen with one face (this assumes that all
--     the blocks in view rest on a face, on the floor or on each other, and that the camera is
--     rolled and pitched by less than 45 degrees);
--   - `up_tolerance`: standard deviation of a block's tilt from `up`, radians (default 2°);
--   - `floor` (needs `up`): the height of the camera's centre above the floor the blocks rest
--     on, when known: a block resting on the floor or on other blocks has its centre at
--     `block_size/2 + k·block_size` above it, which fixes the depth a single tag measures
--     poorly. It helps only when known to about a millimetre: a height error moves a centre
--     along the line of sight by the error over the sine of the ray's angle below horizontal.
--     A block further than 0.3 block from every level is left free;
--     `"auto"` (with `up`, a vector or `"auto"`): when the frame has blocks seen with two or
--     more faces, the floor is where they rest (each at the level nearest its height above the
--     lowest), used for the blocks seen with one face and, for each of those blocks, the floor
--     the others show (this assumes that all the blocks in view rest on the floor or on each
--     other);
--   - `floor_tolerance`: standard deviation of a resting centre's height from its level, in
--     length units (default `block_size / 50`; `block_size / 100` with `floor = "auto"`);
--   - `previous`: the blocks returned for the previous frame: a block found again keeps its
--     `id` and the symmetric frame nearest its previous rotation, and a one-face block keeps
--     the candidate that continues a decided orientation;
--   - `layout`: the cube, when it is not the standard one: a layout `{tags = {[id] = {size =,
--     position =, quaternion =}}}` (`tagpose.layout`) of one cube, every block in view a copy
--     of it, its tags on the cube's faces; its ids tell its tags apart (the block frame is the
--     layout's, detections with other ids are skipped), unless it has `symmetric = true`: then
--     a tag of any id may be any of its tags, on any face and in any turn (the layout's tags
--     turned by the cube's 24 rotations; they must be of one size and where the rotations put
--     one another). Default: the standard cube, `tagpose.layout.cube(tag_size, block_size)`
--     with `symmetric = true`, each id's size from `tag_size`. A layout calibrated from a log
--     (`tagpose.layout.calibrate`, `tagpose-calibrate`) goes here;
--   - `faces`: a table tag id → face (`"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`, or the
--     nested 3×3 tag → block rotation, one of the cube's) when the faces can be told apart:
--     the layout `tagpose.layout.cube(tag_size, block_size, faces)` (not with `layout`);
--   - `max_iterations`: bound on the linearisations of one joint fit (default 20);
--   - `sigma`: the corner noise in pixels, for `covariance` and `confidence` (default: the
--     frame's block residuals pooled with `tagpose.uncertainty.DEFAULT_SIGMA`);
--   - `order`: the corners' order, `"apriltag"` (the default: the detection order) or
--     `"opencv"` (OpenCV's and ArUco's detectors: top-left, top-right, bottom-right,
--     bottom-left of the printed tag), as for `tagpose.solve`.
-- @treturn {table,...} blocks, nearest first (sorted by `id` when tracking), each
--   `{id =, position = {x, y, z}, rotation = {{...}, {...}, {...}}, quaternion = {w, x, y, z},
--   raw_rotation = {{...}, ...}, error = px, tags = {i, ...}, faces = k, tag_faces = {"+x",
--   ...}, orientation = "faces"|"up"|"track"|"error", covariance = {{...} x 6},
--   confidence = p, alternative = {position, rotation, quaternion, error, covariance,
--   confidence} or nil}`: `covariance[i][j]` in the order (x, y, z, rx, ry, rz) of the block
--   centre and a small rotation vector, both in the camera frame, as for a tag
--   (`tagpose.block.uncertainty`); `confidence` the probability that the block's orientation
--   is the true one of the two a one-face block has (1 with two or more faces; below 0.5 when
--   the better-fitting one is the less likely); the array's field `skipped` lists the
--   detections not used, `{index = i, reason = string}`, `next_id` the id a new block would
--   take, and `noise` the corner noise evidence `{sse =, dof =}` (px², degrees of freedom)
--   carried to the next frame, `up` (`{x =, y =, z =}`) and `floor` the up and floor used
--   (given or found with `"auto"`; nil when none)
-- @return nil, string when no detection gives a tag pose (the message says why)
-- @raise `bad argument #n to 'solve' (...)` when an argument has the wrong type or range
--   (`detections` not a table, the camera, the sizes, the options, sizes that contradict
--   `options.layout`, a layout that is not of one cube; a malformed detection inside the array
--   is skipped instead, with its reason)
-- @usage
-- local blocks = tagpose.block.solve({{id = 0, corners = c1}, {id = 0, corners = c2}},
--   camera, 0.024, 0.055, {up = {x = 0, y = -0.9, z = -0.4}})
-- for _, b in ipairs(blocks) do print(b.id, b.position.x, b.position.y, b.position.z) end
-- -- copies of a cube calibrated from its log
-- local cube = assert(tagpose.layout.read("calibrated.yaml"))
-- blocks = tagpose.block.solve(detections, camera, nil, nil, {layout = cube})
function M.solve(detections, camera, tag_size, block_size, options)
  if type(detections) ~= "table" then
    arg_error(1, "array of detections expected, got " .. type(detections))
  end
  if args.is_detection(detections) then arg_error(1, args.ONE_DETECTION) end
  local problem = camera_model.check(camera)
  if problem then arg_error(2, problem) end
  -- (the sizes are checked before the options unless a layout gives them)
  local settings, misuse = read_options(options)
  if not settings and type(options) == "table" and options.layout ~= nil then
    arg_error(5, misuse)
  end
  local body, n
  body, n, problem = body_model.new(tag_size, block_size, settings)
  if not body then arg_error(n, problem) end
  if not settings then arg_error(5, misuse) end
  local fr = frame.new(settings, detections, camera, body)
  for _, s in ipairs(fr.skipped) do s.reason = args.name_order(s.reason, CALL) end
  if #fr.dets == 0 and fr.first_reason then
    return nil, args.name_order("block: no detection gives a tag pose (" .. fr.first_reason
      .. ")", CALL)
  end
  return result.results(fr, result.keep(fr, search.find(fr)))
end

-- (left to LuaJIT's interpreter, as `tagpose.block.search`'s driver loops: `compat.interpret`)
compat.interpret(M.solve)

return M
