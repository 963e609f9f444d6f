-- The broken links of a generated HTML reference (LDoc's): every href of every .html file under
-- DIR that is not an outside address (http:, https:, mailto:, ...) must name a file under DIR
-- that exists, and its #anchor, when it has one, an id or name in that file. Prints one line per
-- broken link, "page: href (reason)", and a count; exits 1 when there is one.
--
--   ldoc -d /tmp/ldoc . && lua5.4 bench/check_links.lua /tmp/ldoc
local lfs = require("lfs")

local M = {}

local function html_files(dir, into)
  for name in lfs.dir(dir) do
    local path = dir .. "/" .. name
    if name ~= "." and name ~= ".." then
      if lfs.attributes(path, "mode") == "directory" then
        html_files(path, into)
      elseif name:match("%.html$") then
        into[#into + 1] = path
      end
    end
  end
  return into
end

local function read(path)
  local f = io.open(path, "rb")
  if not f then return nil end
  local text = f:read("*a")
  f:close()
  return text
end

-- "a/./b/../c" -> "a/c"
local function normalise(path)
  local parts = {}
  for part in path:gmatch("[^/]+") do
    if part == ".." and #parts > 0 and parts[#parts] ~= ".." then
      parts[#parts] = nil
    elseif part ~= "." then
      parts[#parts + 1] = part
    end
  end
  return (path:sub(1, 1) == "/" and "/" or "") .. table.concat(parts, "/")
end

-- &amp; and the numeric references an href may hold, and %XX
local function unescape(s)
  s = s:gsub("&#(%d+);", function(n) return string.char(tonumber(n)) end)
    :gsub("&amp;", "&"):gsub("&quot;", '"'):gsub("&lt;", "<"):gsub("&gt;", ">")
  return (s:gsub("%%(%x%x)", function(h) return string.char(tonumber(h, 16)) end))
end

local anchors_of = {}
local function anchors(path)
  local set = anchors_of[path]
  if not set then
    set = {}
    local text = read(path) or ""
    for _, attr in ipairs({ "id", "name" }) do
      for value in text:gmatch("%s" .. attr .. "%s*=%s*\"([^\"]*)\"") do
        set[unescape(value)] = true
      end
      for value in text:gmatch("%s" .. attr .. "%s*=%s*'([^']*)'") do
        set[unescape(value)] = true
      end
    end
    anchors_of[path] = set
  end
  return set
end

--- The broken links of the reference under dir.
-- @treturn {string,...} "page: href (reason)", sorted
-- @treturn int the number of links checked
function M.check(dir)
  local broken, checked = {}, 0
  for _, page in ipairs(html_files(dir, {})) do
    local text = assert(read(page))
    local base = page:match("^(.*)/") or "."
    for href in text:gmatch("<a%s[^>]-href%s*=%s*\"([^\"]*)\"") do
      local raw = href
      href = unescape(href)
      if not href:match("^%a[%w+.-]*:") then
        checked = checked + 1
        local file, anchor = href:match("^([^#]*)#?(.*)$")
        local target = file == "" and page or normalise(base .. "/" .. file)
        local rel = page:sub(#dir + 2)
        if lfs.attributes(target, "mode") == "directory" then target = target .. "/index.html" end
        if not lfs.attributes(target, "mode") then
          broken[#broken + 1] = rel .. ": " .. raw .. " (no file " .. target:sub(#dir + 2) .. ")"
        elseif anchor ~= "" and not anchors(target)[anchor] then
          broken[#broken + 1] = rel .. ": " .. raw .. " (no anchor #" .. anchor .. ")"
        end
      end
    end
  end
  table.sort(broken)
  return broken, checked
end

if arg and arg[0] and arg[0]:match("check_links%.lua$") then
  local dir = arg[1]
  if not dir or not lfs.attributes(dir, "mode") then
    io.stderr:write("usage: lua bench/check_links.lua DIR (an HTML reference, LDoc's)\n")
    os.exit(2)
  end
  dir = dir:gsub("/+$", "")
  local broken, checked = M.check(dir)
  for _, line in ipairs(broken) do print(line) end
  print(#broken .. " broken links of " .. checked .. " checked")
  os.exit(#broken == 0 and 0 or 1)
end

return M
