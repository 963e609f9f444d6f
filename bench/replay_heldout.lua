-- The tracker's figures on held-out-like draws, measured through the command itself:
-- bin/tagpose-replay --track and --smooth, each draw compared with its truth (--compare counts
-- the rows whose rotation is more than 30° from the truth: the wrong branch), pooled.
--
--   lua5.4 bench/replay_heldout.lua OUT_DIR [DRAWS [SEQUENCES [FRAMES]]]
--
-- Makes DRAWS (default 5) draws of bench/make_sequences.lua on the dev camera (seeds 5101,
-- 5102, ...) and DRAWS on random cameras (seeds 5201, ...), each of SEQUENCES (default 8)
-- sequences of FRAMES (default 250) frames of the seven dev kinds, as the dev set's own
-- sequences are made, and replays them and bench/dev/sequences with the Lua running this
-- script. Prints per set the rows, the wrong rows of --track and of --smooth, and the 95 %
-- coverage of the pose log's sx, sy, sz (|x - truth| <= 1.96 sx, over the rows on the right
-- branch); then the pooled figures of the draws, and of the draws and the dev set. Everything
-- it writes is in OUT_DIR.
-- Run from the repository's root.

package.path = "./src/?.lua;./src/?/init.lua;" .. package.path
local log = require("tagpose.tools.log")

local KINDS = "approach,far_hover,far_wobble,orbit,spin,drive_by,enter_turning"

local dir = arg[1]
local draws, sequences, frames = tonumber(arg[2] or 5), tonumber(arg[3] or 8),
  tonumber(arg[4] or 250)
if not (dir and draws and sequences and frames) then
  io.stderr:write("usage: lua bench/replay_heldout.lua OUT_DIR [DRAWS [SEQUENCES [FRAMES]]]\n")
  os.exit(2)
end

-- the interpreter running this script
local lua = "lua5.4"
do
  local i = 0
  while arg[i - 1] ~= nil do i = i - 1 end
  if i < 0 then lua = arg[i] end
end

local function quote(s)
  return "'" .. tostring(s):gsub("'", "'\\''") .. "'"
end

local function sh(command)
  local p = assert(io.popen(command .. " 2>&1", "r"))
  local text = p:read("*a")
  p:close()
  return text
end

-- the replay of a set in a mode: rows matched, rows apart, and the pose log's coverage (the
-- pose log written in OUT_DIR, never beside a data set of the repository)
local function replay(set, mode)
  local out = ("%s/%s-%s.csv"):format(dir, (set:match("[^/]+/[^/]+$"):gsub("/", "_")), mode)
  local text = sh(table.concat({ quote(lua), "bin/tagpose-replay", quote(set .. "/corners.csv"),
    "--" .. mode, "--compare", quote(set .. "/truth.csv"), "--out", quote(out) }, " "))
  local matched, apart = text:match(": (%d+) rows? matched; .-; (%d+) rows? %([%d.]+ %%%) more")
  assert(matched, text)
  local poses = assert(log.read_csv(out))
  local truth = assert(log.read_csv(set .. "/truth.csv"))
  assert(#poses == #truth, out)
  local inside, right = { 0, 0, 0 }, 0
  for i, p in ipairs(poses) do
    local t = truth[i]
    local dot = math.abs(p.qw * t.qw + p.qx * t.qx + p.qy * t.qy + p.qz * t.qz)
    if p.sx and 2 * math.deg(math.acos(math.min(1, dot))) <= 30 then
      right = right + 1
      for a, name in ipairs({ "x", "y", "z" }) do
        if math.abs(p[name] - t[name]) <= 1.96 * p["s" .. name] then
          inside[a] = inside[a] + 1
        end
      end
    end
  end
  return tonumber(matched), tonumber(apart), inside, right
end

local sets = {}
for k = 1, draws do
  for _, camera in ipairs({ "dev", "random" }) do
    local seed = (camera == "dev" and 5100 or 5200) + k
    local set = ("%s/K7-%s-%d"):format(dir, camera, seed)
    sh(table.concat({ quote(lua), "bench/make_sequences.lua", quote(set), sequences, seed,
      "--kinds", KINDS, "--camera", camera, "--frames", frames }, " "))
    sets[#sets + 1] = set
  end
end
sets[#sets + 1] = "bench/dev/sequences"

print(("%-28s %6s %14s %14s   %s"):format("set", "rows", "--track wrong", "--smooth wrong",
  "--track: sx sy sz inside 1.96 sd"))
local pooled = { rows = 0, track = 0, smooth = 0, inside = { 0, 0, 0 }, right = 0 }
local function percent(n, d) return ("%d (%.2f %%)"):format(n, 100 * n / d) end
for i, set in ipairs(sets) do
  local rows, track, inside, right = replay(set, "track")
  local _, smooth = replay(set, "smooth")
  print(("%-28s %6d %14s %14s   %.1f %.1f %.1f %%"):format(set:match("[^/]+/[^/]+$"), rows,
    percent(track, rows), percent(smooth, rows), 100 * inside[1] / right,
    100 * inside[2] / right, 100 * inside[3] / right))
  pooled.rows, pooled.track = pooled.rows + rows, pooled.track + track
  pooled.smooth, pooled.right = pooled.smooth + smooth, pooled.right + right
  for a = 1, 3 do pooled.inside[a] = pooled.inside[a] + inside[a] end
  if i == #sets - 1 or i == #sets then
    print(("%-28s %6d %14s %14s   %.1f %.1f %.1f %%"):format(i == #sets
      and "pooled, draws and dev set" or "pooled, draws", pooled.rows,
      percent(pooled.track, pooled.rows), percent(pooled.smooth, pooled.rows),
      100 * pooled.inside[1] / pooled.right, 100 * pooled.inside[2] / pooled.right,
      100 * pooled.inside[3] / pooled.right))
  end
end
