-- A golden dump of tagpose.block.solve over a block data set, to tell whether a change of the
-- code changed any result: every field of every block (position, rotations, quaternion, error,
-- tags and faces, orientation, covariance, confidence, the alternative and its uncertainty),
-- every skipped detection and the frame's fields, each number written with 17 significant
-- digits, for eight runs: the corners only, up = "auto", both "auto" options, up, up and the
-- floor (both as examples/blocks.lua takes them from the truth), tracking (each frame's blocks
-- passed to the next), options.sigma = 0.3, and options.faces (each tag given its own id by
-- its true face, from truth_tags.csv).
--
--   lua5.4 bench/block_golden.lua [--src DIR] DATASET_DIR OUT
--   lua5.4 bench/block_golden.lua --compare OUT_A OUT_B
--
-- --src loads tagpose from DIR (default ./src): the dump of another checkout's source, e.g.
--   git archive main src | tar -x -C /tmp/main && lua5.4 bench/block_golden.lua --src
--   /tmp/main/src bench/dev/blocks /tmp/main.txt
-- --compare prints, per run, how many lines are bit-identical and the largest difference of a
--   number between the two dumps (exit status 1 when a run differs).
--
-- The data set as examples/blocks.lua reads it (camera.lua with tag_size and block_size,
-- corners.csv, truth.csv, truth_tags.csv), with a CSV reader of its own, so that the dumps of
-- two checkouts depend on nothing but their tagpose.block.

local args = { ... }
if #args == 0 then args = arg end

local function usage()
  io.stderr:write("usage: lua bench/block_golden.lua [--src DIR] DATASET_DIR OUT\n"
    .. "       lua bench/block_golden.lua --compare OUT_A OUT_B\n")
  os.exit(2)
end

local function lines_of(path)
  local out = {}
  for line in assert(io.lines(path)) do out[#out + 1] = line end
  return out
end

-- the runs of a dump: name -> array of lines
local function runs_of(path)
  local runs, order = {}, {}
  for _, line in ipairs(lines_of(path)) do
    local name = line:match("^== (.+)$")
    if name then
      runs[name] = {}
      order[#order + 1] = name
    else
      local lines = runs[order[#order]]
      lines[#lines + 1] = line
    end
  end
  return runs, order
end

local function compare(a, b)
  local ra, order = runs_of(a)
  local rb = runs_of(b)
  local differs = false
  for _, name in ipairs(order) do
    local la, lb = ra[name], rb[name] or {}
    local same, worst = 0, 0
    for i = 1, math.max(#la, #lb) do
      if la[i] == lb[i] then
        same = same + 1
      else
        differs = true
        local na, nb = {}, {}
        for v in (la[i] or ""):gmatch("[-+%w%.]+") do na[#na + 1] = tonumber(v) or v end
        for v in (lb[i] or ""):gmatch("[-+%w%.]+") do nb[#nb + 1] = tonumber(v) or v end
        for k = 1, math.max(#na, #nb) do
          local x, y = na[k], nb[k]
          if type(x) == "number" and type(y) == "number" then
            local d = math.abs(x - y)
            if d > worst or d ~= d then worst = d end
          elseif x ~= y then
            worst = math.huge
          end
        end
      end
    end
    print(("%-12s %5d of %5d lines bit-identical, largest difference %.3g"):format(name, same,
      math.max(#la, #lb), worst))
  end
  os.exit(differs and 1 or 0)
end

if args[1] == "--compare" then
  if not (args[2] and args[3]) then usage() end
  compare(args[2], args[3])
end

local src = "./src"
if args[1] == "--src" then
  src = args[2] or usage()
  table.remove(args, 1)
  table.remove(args, 1)
end
local dir, out_path = args[1], args[2]
if not (dir and out_path) then usage() end
package.path = src .. "/?.lua;" .. src .. "/?/init.lua;" .. package.path
local tagpose = require("tagpose")

local function read_csv(path)
  local rows, names = {}, nil
  for line in assert(io.lines(path)) do
    local fields = {}
    for v in (line .. ","):gmatch("([^,]*),") do fields[#fields + 1] = v end
    if not names then
      names = fields
    else
      local row = {}
      for i, name in ipairs(names) do row[name] = tonumber(fields[i]) or fields[i] end
      rows[#rows + 1] = row
    end
  end
  return rows
end

local info = assert(loadfile(dir .. "/camera.lua"))()
local camera = { fx = info.fx, fy = info.fy, cx = info.cx, cy = info.cy }
local tag_size, block_size = info.tag_size, info.block_size

-- frames in order, each with its detections (ids as logged, and by true face)
local FACE_IDS = { ["+x"] = 1, ["-x"] = 2, ["+y"] = 3, ["-y"] = 4, ["+z"] = 5, ["-z"] = 6 }
local frames, by_frame = {}, {}
local corners, faces = read_csv(dir .. "/corners.csv"), read_csv(dir .. "/truth_tags.csv")
for i, row in ipairs(corners) do
  local f = by_frame[row.frame]
  if not f then
    f = { frame = row.frame, detections = {}, by_face = {} }
    by_frame[row.frame] = f
    frames[#frames + 1] = f
  end
  local c = { { row.u1, row.v1 }, { row.u2, row.v2 }, { row.u3, row.v3 }, { row.u4, row.v4 } }
  f.detections[#f.detections + 1] = { id = row.tag, corners = c }
  f.by_face[#f.by_face + 1] = { id = FACE_IDS[faces[i].face], corners = c }
end
table.sort(frames, function(a, b) return a.frame < b.frame end)

-- up and the floor from the truth, as examples/blocks.lua takes them
local function from_quaternion(w, x, y, z)
  return { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) }
end
for _, t in ipairs(read_csv(dir .. "/truth.csv")) do
  local f = by_frame[t.frame]
  if f then
    f.truth = f.truth or {}
    f.truth[#f.truth + 1] = { x = t.x, y = t.y, z = t.z,
      r = from_quaternion(t.qw, t.qx, t.qy, t.qz) }
  end
end
for _, f in ipairs(frames) do
  if f.truth then
    local ux, uy, uz = 0, 0, 0
    for _, t in ipairs(f.truth) do
      local r, best, bx, by, bz = t.r, -math.huge, 0, 0, 0
      for k = 1, 3 do
        for s = -1, 1, 2 do
          local x, y, z = s * r[k], s * r[3 + k], s * r[6 + k]
          if -y > best then best, bx, by, bz = -y, x, y, z end
        end
      end
      ux, uy, uz = ux + bx, uy + by, uz + bz
    end
    local n = math.sqrt(ux * ux + uy * uy + uz * uz)
    f.up = { x = ux / n, y = uy / n, z = uz / n }
    local low = math.huge
    for _, t in ipairs(f.truth) do
      low = math.min(low, f.up.x * t.x + f.up.y * t.y + f.up.z * t.z)
    end
    f.floor = 0.5 * block_size - low
  end
end

local function g(v)
  if type(v) ~= "number" then return tostring(v) end
  return ("%.17g"):format(v)
end

local out = assert(io.open(out_path, "w"))

-- one pose (a block or its alternative) on one line
local function pose_line(prefix, b)
  local p, q, r = b.position, b.quaternion, b.rotation
  local parts = { prefix, g(p.x), g(p.y), g(p.z), g(q.w), g(q.x), g(q.y), g(q.z), g(b.error),
    "R" }
  for i = 1, 3 do for j = 1, 3 do parts[#parts + 1] = g(r[i][j]) end end
  parts[#parts + 1] = "C"
  for i = 1, 6 do for j = 1, 6 do parts[#parts + 1] = g(b.covariance and b.covariance[i][j]) end end
  parts[#parts + 1] = "p " .. g(b.confidence)
  out:write(table.concat(parts, " "), "\n")
end

local function dump(name, options_of, detections_of, faces_option)
  out:write("== ", name, "\n")
  local previous, last = nil, nil
  for _, f in ipairs(frames) do
    local options = options_of(f, last == f.frame - 1 and previous or nil)
    if faces_option then options.faces = faces_option end
    local blocks, err = tagpose.block.solve(detections_of(f), camera, tag_size, block_size,
      options)
    if not blocks then
      out:write(g(f.frame), " nil ", tostring(err), "\n")
    else
      out:write(("%s %d blocks, next_id %s, noise %s %s, up %s, floor %s\n"):format(g(f.frame),
        #blocks, g(blocks.next_id), g(blocks.noise.sse), g(blocks.noise.dof),
        blocks.up and (g(blocks.up.x) .. " " .. g(blocks.up.y) .. " " .. g(blocks.up.z)) or "-",
        g(blocks.floor)))
      for _, b in ipairs(blocks) do
        pose_line(("block %s faces %d tags %s on %s by %s"):format(g(b.id), b.faces,
          table.concat(b.tags, ","), table.concat(b.tag_faces, ","), b.orientation), b)
        local raw = {}
        for i = 1, 3 do for j = 1, 3 do raw[#raw + 1] = g(b.raw_rotation[i][j]) end end
        out:write("raw ", table.concat(raw, " "), "\n")
        if b.alternative then pose_line("alternative", b.alternative) end
      end
      for _, s in ipairs(blocks.skipped) do
        out:write("skipped ", g(s.index), " ", s.reason, "\n")
      end
    end
    previous, last = blocks, f.frame
  end
end

local function plain(f) return f.detections end
local function by_face(f) return f.by_face end
local FACES = {}
for face, id in pairs(FACE_IDS) do FACES[id] = face end

dump("corners", function() return {} end, plain)
dump("auto", function() return { up = "auto" } end, plain)
dump("auto-floor", function() return { up = "auto", floor = "auto" } end, plain)
dump("up", function(f) return { up = f.up } end, plain)
dump("up-floor", function(f) return { up = f.up, floor = f.floor } end, plain)
dump("track", function(_, previous) return { previous = previous } end, plain)
dump("sigma", function() return { sigma = 0.3 } end, plain)
dump("faces", function() return {} end, by_face, FACES)
out:close()
