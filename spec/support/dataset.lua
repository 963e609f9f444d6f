-- Read a data set in the format of bench/dev (corners.csv, truth.csv, camera.lua).

local D = {}

local function read_csv(path)
  local f = assert(io.open(path, "r"))
  local header = f:read("*l")
  local names = {}
  for name in header:gmatch("[^,]+") do names[#names + 1] = name end
  local rows = {}
  for line in f:lines() do
    if line ~= "" then
      local row, k = {}, 0
      for v in (line .. ","):gmatch("([^,]*),") do
        k = k + 1
        row[names[k]] = tonumber(v) or v
      end
      rows[#rows + 1] = row
    end
  end
  f:close()
  return rows
end

D.read_csv = read_csv

function D.load(dir)
  local camera = dofile(dir .. "/camera.lua")
  local corners = read_csv(dir .. "/corners.csv")
  local truth = read_csv(dir .. "/truth.csv")
  assert(#corners == #truth, "corners and truth differ in length")
  return camera, corners, truth
end

function D.corners(row)
  return { { row.u1, row.v1 }, { row.u2, row.v2 }, { row.u3, row.v3 }, { row.u4, row.v4 } }
end

return D
