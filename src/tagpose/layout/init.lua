--- Layouts: rigid sets of tags of any shape — a cube, a board, the tags around a robot — each
-- with its own id, size and pose on the body.
--
--     layout = {tags = {[id] = {size = s, position = {x =, y =, z =},
--                               quaternion = {w =, x =, y =, z =}}}}
--
-- places each tag's frame (docs/conventions.md: origin at the tag's centre, x right, y down,
-- z into the tag) in the body frame: `X_body = R(quaternion)·X_tag + position`. Lengths are
-- in the unit of the sizes, angles in radians, errors in pixels.
--
-- * `solve` gives the body's pose from one frame's detections (`tagpose.layout.solve`);
-- * `calibrate` gives the layout a recorded log says, from a nominal one
--   (`tagpose.layout.calibrate`);
-- * `read` and `write` keep layouts in files: Lua data files, apriltag_ros `tags.yaml` and CSV
--   tables (`tagpose.formats.layout`);
-- * `cube` builds the layout of a cube block with a centred tag on each face, the blocks'
--   standard cube (`tagpose.block` solves cubes given as layouts).
-- @module tagpose.layout

local args = require("tagpose.core.args")
local camera_model = require("tagpose.core.camera")
local cube = require("tagpose.rigid.cube")
local model = require("tagpose.rigid.model")

local is_positive, describe = args.is_positive, args.describe

local M = {}

-- The modules of solve, calibrate and the files, loaded when first used: `cube` alone
-- (`tagpose.rigid.cube.layout`, which `tagpose.block` uses) loads none of them.
local loaded = {}
local function lazy(name)
  local module = loaded[name]
  if not module then
    module = require(name)
    loaded[name] = module
  end
  return module
end

-- Raise a misuse at the caller of the entry point (`depth`: the helpers between them).
local function raise(n, fname, message, depth)
  args.raise(n, fname, message, 3 + (depth or 0))
end

-- Check that an options table has only the given keys (name, check, what it expects); returns
-- the options or raises at the caller of the entry point.
local function read_options(options, n, fname, spec)
  if options == nil then return {} end
  if type(options) ~= "table" then
    raise(n, fname, "options table expected, got " .. type(options), 1)
  end
  local keys = {}
  for key in pairs(spec) do keys[#keys + 1] = key end
  table.sort(keys)
  local unknown = args.unknown_keys(options, keys, "options")
  if unknown then raise(n, fname, unknown, 1) end
  for _, key in ipairs(keys) do
    local v, check = options[key], spec[key]
    if v ~= nil and not check[1](v) then
      raise(n, fname, "options." .. key .. ": " .. check[2] .. " expected, got " .. describe(v), 1)
    end
  end
  return options
end

-- `options.order`, as `tagpose.solve` takes it (`tagpose.core.args.read_order`)
local function is_order(v)
  return args.read_order(v) ~= nil
end
local ORDER = { is_order, "'apriltag' or 'opencv'" }

-- The options a facade hands on: the caller's, and `opencv` (the corners' order read).
local function settings(o, call)
  local out = {}
  for k, v in pairs(o) do out[k] = v end
  out.opencv = args.read_order(o.order)
  out.call = call
  return out
end

local SOLVE_OPTIONS = {
  sigma = { is_positive, "positive number" },
  max_iterations = { args.is_count, "positive integer" },
  order = ORDER,
}

--- The pose of a layout from one frame's detections: one joint least-squares fit over all the
-- corners of its tags seen, through the lens.
-- @tparam {table,...} detections array of `{id =, corners =}` (corners in detection order, as
--   for `tagpose.solve`); detections of ids not in the layout and malformed ones are skipped
--   and listed, and so are tags that cannot be solved alone when no other tag can (otherwise
--   their corners join the joint fit)
-- @tparam table camera as for `tagpose.solve`
-- @tparam table layout `{tags = {[id] = {size =, position =, quaternion =}}}`
-- @tparam[opt] table options `sigma` (corner noise, px, for `covariance` and `confidence`;
--   default: the fit's residuals pooled with `tagpose.uncertainty.DEFAULT_SIGMA`),
--   `max_iterations` (bound on the linearisations of one fit; default 20), `order` (the
--   corners' order: `"apriltag"`, the default, or `"opencv"`, as for `tagpose.solve`)
-- @treturn table body: `position = {x, y, z}`, `rotation` (nested 3×3), `quaternion`
--   (`w >= 0`), body → camera; `error` (RMS over the corners used, px); `iterations`;
--   `covariance` (6×6, order x, y, z, rx, ry, rz, camera frame); `confidence`; `alternative`
--   (the other branch where the view is ambiguous: one tag, or tags in one plane; nil
--   otherwise); `tags` (indices into `detections` of the detections used), `ids` (their ids),
--   `skipped` (`{index =, id =, reason =}` for every detection not used)
-- @return nil, string when no detection gives a pose (the message says why)
-- @raise `bad argument #n to 'solve' (...)` for a detections argument that is not a table (or
--   is one detection), a bad camera, a bad layout entry of a tag detected, or bad options
-- @usage
-- local body = tagpose.layout.solve({{id = 0, corners = c0}, {id = 3, corners = c3}}, camera,
--   layout)
-- print(body.position.x, body.position.y, body.position.z, body.error)
function M.solve(detections, camera, layout, options)
  if type(detections) ~= "table" then
    raise(1, "solve", "array of detections expected, got " .. type(detections))
  end
  local problem = camera_model.check(camera)
  if problem then raise(2, "solve", problem) end
  if type(layout) ~= "table" then
    raise(3, "solve", "layout table expected, got " .. type(layout))
  end
  local entries = layout.tags
  if type(entries) ~= "table" then
    raise(3, "solve", "layout.tags: table {[id] = tag} expected, got " .. type(entries))
  end
  if args.is_detection(detections) then raise(1, "solve", args.ONE_DETECTION) end
  local o = settings(read_options(options, 4, "solve", SOLVE_OPTIONS),
    "tagpose.layout.solve(detections, camera, layout, options)")
  -- the entries of the tags detected (the layout may hold many more)
  local tags = {}
  for i = 1, #detections do
    local d = detections[i]
    local id = type(d) == "table" and d.id or nil
    if id ~= nil and tags[id] == nil and entries[id] ~= nil then
      local t, why = model.read_tag(entries[id], id)
      if not t then raise(3, "solve", "layout." .. why) end
      tags[id] = t
    end
  end
  local body, why = lazy("tagpose.layout.solve").solve(detections, camera, tags, o)
  if not body then return nil, args.name_order(why, o.call) end
  for _, s in ipairs(body.skipped) do s.reason = args.name_order(s.reason, o.call) end
  return body
end

local CALIBRATE_OPTIONS = {
  sigma = { is_positive, "positive number" },
  max_iterations = { args.is_count, "positive integer" },
  reference = { model.is_id, "tag id of the layout" },
  robust = { is_positive, "positive number" },
  gauge = { function(v) return v == "planes" or v == "corners" end, "'planes' or 'corners'" },
  order = ORDER,
}

--- Calibrate a layout from a recorded log: the tags' poses on the body that the images say.
-- A bundle adjustment over every frame's body pose and every tag's pose on the body, the frame
-- poses eliminated per frame (see `tagpose.layout.calibrate`).
-- @tparam {table,...} frames array of frames, each an array of detections `{id =, corners =}`
-- @tparam table camera as for `tagpose.solve`
-- @tparam table layout the nominal layout (the start, and the body frame of the result)
-- @tparam[opt] table options `max_iterations` (bound on the bundle adjustment's
--   linearisations, default 100), `reference` (the tag held fixed while solving; default the
--   tag seen most), `robust` (the robust loss's scale, in standard deviations of the corner
--   noise; default 3), `sigma` (the corner noise, px, for the report's standard deviations;
--   default: estimated from the residuals), `order` (the corners' order, as for
--   `tagpose.solve`)
-- @treturn table the calibrated layout (same shape; tags that could not be placed keep their
--   nominal pose)
-- @treturn table the report (see `tagpose.layout.calibrate`)
-- @return nil, string when the log cannot calibrate the layout (the message says why)
-- @raise `bad argument #n to 'calibrate' (...)` for frames that are not an array of arrays, a
--   bad camera, a bad layout or bad options
function M.calibrate(frames, camera, layout, options)
  if type(frames) ~= "table" then
    raise(1, "calibrate", "array of frames expected, got " .. type(frames))
  end
  if args.is_detection(frames) then
    raise(1, "calibrate", "array of frames expected, got one detection {id =, corners =} "
      .. "(pass {{detection}})")
  end
  for i = 1, #frames do
    if type(frames[i]) ~= "table" then
      raise(1, "calibrate", "frames[" .. i .. "]: array of detections expected, got "
        .. type(frames[i]))
    end
    if args.is_detection(frames[i]) then
      raise(1, "calibrate", "frames[" .. i .. "]: " .. args.ONE_DETECTION
        .. " (frames: an array of frames, each an array of detections)")
    end
  end
  local problem = camera_model.check(camera)
  if problem then raise(2, "calibrate", problem) end
  local tags, why = model.read(layout)
  if not tags then raise(3, "calibrate", why) end
  local o = settings(read_options(options, 4, "calibrate", CALIBRATE_OPTIONS),
    "tagpose.layout.calibrate(frames, camera, layout, options)")
  if o.reference ~= nil and not tags[o.reference] then
    raise(4, "calibrate", "options.reference: tag " .. tostring(o.reference)
      .. " is not in the layout")
  end
  local out, rep = lazy("tagpose.layout.calibrate").calibrate(frames, camera, tags, o,
    layout.name)
  if not out then return nil, args.name_order(rep, o.call) end
  return out, rep
end

local READ_OPTIONS = {
  bundle = { function(v) return type(v) == "string" end, "string" },
  size = { is_positive, "positive number" },
}

--- Read a layout file: a Lua data file (`.lua`; read as data, never run), an apriltag_ros
-- `tags.yaml` (`.yaml`, `.yml`; its tags converted to tagpose's tag frame), a CSV table
-- `id,size,x,y,z,qw,qx,qy,qz` (`.csv`) or a WPILib field map (`.json`; its tags converted to
-- tagpose's tag frame, metres).
-- @tparam string path
-- @tparam[opt] string|table options `{bundle =, size =}`: `bundle` the name of the bundle to
--   read from a `tags.yaml` of several (or that name alone, as a string); `size` the side of
--   the tags' black squares, which a WPILib field map needs (it has none), in metres as the map
--   (one larger than twice the map is refused: millimetres?)
-- @treturn table layout
-- @return nil, string when the file cannot be read or is not a layout (with its line)
-- @raise `bad argument #n to 'read'` when path is not a string or an option is wrong
-- @usage
-- local field = assert(tagpose.layout.read("2024-crescendo.json", { size = 0.1651 }))
function M.read(path, options)
  if type(path) ~= "string" then raise(1, "read", "string expected, got " .. type(path)) end
  if type(options) ~= "string" then read_options(options, 2, "read", READ_OPTIONS) end
  return lazy("tagpose.formats.layout").read(path, options)
end

--- Write a layout file, in the format its extension names (as `read`): whole or not at all (a
-- temporary file beside it, renamed onto it once written); a path that is not a regular file
-- once links are followed (a device such as /dev/null, a FIFO, a pipe) is written through, in
-- place, never replaced.
-- @tparam string path
-- @tparam table layout
-- @treturn true
-- @return nil, string when the file cannot be written
-- @raise `bad argument #n to 'write'` for a path that is not a string or a bad layout
function M.write(path, layout)
  if type(path) ~= "string" then raise(1, "write", "string expected, got " .. type(path)) end
  local tags, why = model.read(layout)
  if not tags then raise(2, "write", why) end
  return lazy("tagpose.formats.layout").write(path, tags, layout.name)
end

--- The text `write` would write to `path`, in the format its extension names, and nothing
-- written: for a caller that writes it itself (onto an output it opened before the work that
-- makes the layout, as `tagpose-calibrate` does), or checks a path's format first.
-- @tparam string path its extension names the format, as in `write`
-- @tparam table layout
-- @treturn string the file's text
-- @return nil, string when the extension is not a layout format's, or the layout's name cannot
--   be written in it
-- @raise `bad argument #n to 'encode'` for a path that is not a string or a bad layout
-- @usage
-- local text = assert(tagpose.layout.encode("cube.yaml", tagpose.layout.cube(0.024, 0.03)))
function M.encode(path, layout)
  if type(path) ~= "string" then raise(1, "encode", "string expected, got " .. type(path)) end
  local tags, why = model.read(layout)
  if not tags then raise(2, "encode", why) end
  return lazy("tagpose.formats.layout").encode(path, tags, layout.name)
end

--- The layout of a cube block with a centred tag on each face named: the standard cube, whose
-- faces carry the tags as the lab's blocks do (tag z into the block; on the side faces the
-- tag upright on an upright block; on the top tag x = +x, tag y = -y; on the bottom tag
-- x = +x, tag y = +y). Every face's tag frame `R_f` is one of the cube's rotations
-- (`tagpose.rigid.cube`), and `X_block = R_f·X_tag + (block_size/2)·n_f`, `n_f` the face's
-- outward normal. With `symmetric = true` set on the result, it is the block of
-- `tagpose.block.solve` whose faces cannot be told apart (its default).
-- @tparam number|table tag_size side of the tags' black squares; or the sides by tag id,
--   `{[id] = size, default = size}`
-- @tparam number block_size side of the cube (> every tag's side)
-- @tparam[opt] table faces tag id → face (`"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`, or the
--   nested 3×3 rotation of the tag frame in the block frame, one of the cube's: a tag turned on
--   its face); default ids 0 to 5 on `+x`, `-x`, `+y`, `-y`, `+z`, `-z`
-- @treturn table layout `{tags = {[id] = {size =, position =, quaternion =}}}`
-- @raise `bad argument #n to 'cube'` for bad sizes or faces, or a tag of the faces without a
--   size
-- @function cube
-- @usage
-- local blocks = tagpose.layout.cube(0.024, 0.055, { [7] = "+z", [8] = "-x" })
M.cube = cube.layout

return M
