-- How long tagpose.calibration takes to read an OpenCV file of many keys it does not read (each
-- is checked for looking like a misspelling of one it reads), in YAML, XML and JSON.
--
--   lua5.4 bench/calibration_keys.lua [N] [PATTERN]
--
-- N keys (default 40000) named by PATTERN (a string.format pattern of the key's number;
-- default "ignored_key_%05d"; "camera_ma%04d" gives keys of a read key's length and prefix,
-- the slowest to tell apart). Prints the seconds of os.clock per format.
package.path = "./src/?.lua;./src/?/init.lua;" .. package.path

local calibration = require("tagpose.formats.calibration")

local n = tonumber(arg[1]) or 40000
local pattern = arg[2] or "ignored_key_%05d"

local K = { 600, 0, 320, 0, 610, 240, 0, 0, 1 }
local D = { -0.2, 0.05, 0, 0, 0 }

local function yaml_text()
  local t = { "%YAML:1.0", "---", "camera_matrix: !!opencv-matrix", "   rows: 3", "   cols: 3",
    "   dt: d", "   data: [ " .. table.concat(K, ", ") .. " ]",
    "distortion_coefficients: !!opencv-matrix", "   rows: 5", "   cols: 1", "   dt: d",
    "   data: [ " .. table.concat(D, ", ") .. " ]" }
  for i = 1, n do t[#t + 1] = pattern:format(i) .. ": " .. i end
  return table.concat(t, "\n") .. "\n"
end

local function xml_text()
  local function matrix(name, rows, cols, data)
    return ("<%s type_id=\"opencv-matrix\"><rows>%d</rows><cols>%d</cols><dt>d</dt><data>%s"
      .. "</data></%s>"):format(name, rows, cols, table.concat(data, " "), name)
  end
  local t = { '<?xml version="1.0"?>', "<opencv_storage>", matrix("camera_matrix", 3, 3, K),
    matrix("distortion_coefficients", 5, 1, D) }
  for i = 1, n do
    local key = pattern:format(i)
    t[#t + 1] = "<" .. key .. ">" .. i .. "</" .. key .. ">"
  end
  t[#t + 1] = "</opencv_storage>"
  return table.concat(t, "\n") .. "\n"
end

local function json_text()
  local function matrix(rows, cols, data)
    return ('{ "type_id": "opencv-matrix", "rows": %d, "cols": %d, "dt": "d", "data": [ %s ] }')
      :format(rows, cols, table.concat(data, ", "))
  end
  local t = { '{', '  "camera_matrix": ' .. matrix(3, 3, K) .. ",",
    '  "distortion_coefficients": ' .. matrix(5, 1, D) }
  for i = 1, n do t[#t] = t[#t] .. ","; t[#t + 1] = '  "' .. pattern:format(i) .. '": ' .. i end
  t[#t + 1] = "}"
  return table.concat(t, "\n") .. "\n"
end

for _, case in ipairs({ { "yml", yaml_text }, { "xml", xml_text }, { "json", json_text } }) do
  local text = case[2]()
  local t0 = os.clock()
  local camera, info = calibration.decode(text, "many." .. case[1])
  local dt = os.clock() - t0
  assert(camera, info)
  assert(#info.ignored == n, "all keys listed")
  print(("%s  %d keys (%s), %d bytes: %.3f s"):format(case[1], n, pattern:format(1), #text, dt))
end
