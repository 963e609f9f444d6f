-- Running the examples and outside tools from the specs: the same Lua as the running spec,
-- shell quoting, exit statuses on every VM (io.popen's close gives none on 5.1 and LuaJIT).

local R = {}

--- The interpreter running the specs (busted --lua=lua5.1 runs them under lua5.1).
function R.lua()
  local i = 0
  while arg and arg[i - 1] ~= nil do i = i - 1 end
  local name = arg and i < 0 and arg[i] or "lua5.4"
  return name
end

function R.quote(s)
  return "'" .. tostring(s):gsub("'", "'\\''") .. "'"
end

--- Run a shell command; returns its output (stdout, and stderr unless redirected) and exit
-- status.
function R.run(command)
  local p = assert(io.popen(command .. '; echo "exit=$?"', "r"))
  local text = p:read("*a")
  p:close()
  local body, status = text:match("^(.-)exit=(%d+)%s*$")
  return body, tonumber(status)
end

--- Run a Lua script with the running interpreter and arguments (quoted here).
function R.script(path, ...)
  local parts = { R.quote(R.lua()), R.quote(path) }
  for i = 1, select("#", ...) do parts[#parts + 1] = R.quote((select(i, ...))) end
  return R.run(table.concat(parts, " ") .. " 2>&1")
end

--- The paths of every file under `dir` whose name matches `pattern` (a Lua pattern), any depth,
-- sorted.
function R.files(dir, pattern)
  local lfs = require("lfs")
  local out = {}
  local function walk(d)
    for name in lfs.dir(d) do
      local path = d .. "/" .. name
      if name ~= "." and name ~= ".." then
        if lfs.attributes(path, "mode") == "directory" then
          walk(path)
        elseif name:match(pattern) then
          out[#out + 1] = path
        end
      end
    end
  end
  walk(dir)
  table.sort(out)
  return out
end

--- A new folder under the system's temporary folder, named by os.tmpname (the file it makes
-- removed), created with `sub` inside it when given (mkdir -p); returns the folder, not `sub`.
function R.tmpdir(sub)
  local dir = os.tmpname()
  os.remove(dir)
  os.execute("mkdir -p " .. R.quote(sub and dir .. "/" .. sub or dir))
  return dir
end

function R.write(path, text)
  local f = assert(io.open(path, "w"))
  f:write(text)
  f:close()
  return path
end

function R.read(path)
  local f = assert(io.open(path, "r"))
  local text = f:read("*a")
  f:close()
  return text
end

--- Check a document with xmllint; returns true, or false and xmllint's complaint.
function R.xmllint(text)
  local path = R.write(os.tmpname(), text)
  local out, status = R.run("xmllint --noout " .. R.quote(path) .. " 2>&1")
  os.remove(path)
  return status == 0, out
end

--- Occurrences of a plain string in a text.
function R.count(text, plain)
  local n, at = 0, 1
  while true do
    local i = text:find(plain, at, true)
    if not i then return n end
    n, at = n + 1, i + #plain
  end
end

-- the SVG text of one panel of a plot
function R.panel(svg, name)
  local i = assert(svg:find('<g class="panel" id="panel-' .. name .. '"', 1, true), name)
  local j = svg:find('<g class="panel"', i + 1, true) or #svg
  return svg:sub(i, j - 1)
end

return R
