-- The repository stands alone: every file of the repository that its own text names (a path
-- under bench/, bin/, docs/, examples/, rockspec/, spec/ or src/, in a comment, a page or a
-- configuration) is in it. Left out on purpose: CHANGELOG.md (its history names files since
-- removed), the released rockspecs (they name the files of their release's commit) and
-- bench/dev/PEERS.md and bench/realdata/README.md (the data sets' own pages, which say that the
-- scripts they name belong to the data sets' origins).
local lfs = require("lfs")

local ROOTS = { "bench", "bin", "docs", "examples", "rockspec", "spec", "src" }
local TOP = { ".busted", ".luacheckrc", "config.ld", "README.md", "test.sh" }
local SKIP = { ["CHANGELOG.md"] = true, ["bench/dev/PEERS.md"] = true,
  ["bench/realdata/README.md"] = true, ["spec/standalone_spec.lua"] = true }
local TEXT = { lua = true, md = true, sh = true, py = true, ld = true, rockspec = true, cpp = true }
-- named by pages of work not yet in the repository (issue 27's drive logs): pending until it is
local function awaited(path)
  return path == "bench/drive.sh" or path == "bench/score_drive.lua"
    or path:match("^bench/dev/drive_hard/") ~= nil or path:match("^bench/dev/drive/") ~= nil
end

local function exists(path)
  return lfs.attributes(path, "mode") ~= nil
end

-- every text file under dir (the data sets' CSV and JSON are not read)
local function walk(dir, into)
  for name in lfs.dir(dir) do
    local path = dir .. "/" .. name
    if name ~= "." and name ~= ".." then
      local mode = lfs.attributes(path, "mode")
      if mode == "directory" then
        walk(path, into)
      elseif TEXT[name:match("%.(%w+)$") or ""] or dir == "bin" then
        into[#into + 1] = path
      end
    end
  end
end

local files = {}
for _, root in ipairs(ROOTS) do walk(root, files) end
for _, name in ipairs(TOP) do
  if exists(name) then files[#files + 1] = name end
end
table.sort(files)

-- the repository paths a line names: a word of path characters that, less a leading ./ or ../,
-- starts with a root folder and ends in an extension
local function named_paths(line)
  local found = {}
  for word in line:gmatch("[%w_./-]+") do
    word = word:gsub("^%.%.?/", ""):gsub("%.+$", "")
    local root = word:match("^([%w_]+)/")
    if root and word:match("%.%w+$") then
      for _, r in ipairs(ROOTS) do
        if root == r then found[#found + 1] = word end
      end
    end
  end
  return found
end

describe("the repository stands alone", function()
  it("names no file of its own that it does not hold", function()
    local missing, later = {}, {}
    for _, file in ipairs(files) do
      if not SKIP[file] and not file:match("^rockspec/.*%-%d[^/]*%.rockspec$") then
        local n = 0
        for line in io.lines(file) do
          n = n + 1
          for _, path in ipairs(named_paths(line)) do
            if not exists(path) then
              local into = awaited(path) and later or missing
              into[#into + 1] = file .. ":" .. n .. ": " .. path
            end
          end
        end
      end
    end
    assert.are.same({}, missing)
    if #later > 0 then pending("awaited: " .. table.concat(later, ", ")) end
  end)
end)
