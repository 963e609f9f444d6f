-- #docs: every command README.md and docs/*.md show, run.
--
-- A page shows commands in code blocks (fenced, or indented four spaces) and in `inline code`.
-- Each block of commands runs as a shell script, in a scratch folder that sees the repository's
-- folders (so `examples/...` and `bench/...` resolve and what a command writes lands there, and
-- `/tmp/` is the scratch folder's own). A command whose full run takes minutes runs on less —
-- the same script, with the smaller sizes SMALLER gives (fewer sequences, rows, frames, seeds) —
-- and a command that needs a tool tagpose does not (OpenCV with g++ or Python, valgrind) is
-- checked as far as can be without it (the script parses). An inline command with placeholders
-- (`DATASET_DIR`, `N`, `[--track]`) is a synopsis: its script must exist. The luarocks and
-- ldoc commands, and ./test.sh, are what ./test.sh itself runs. A page's command that no rule
-- here knows fails the spec: add it to a rule.
--
-- Run by ./test.sh once (`busted --tags=docs`): the commands name their Lua (lua5.4, luajit).
local run = require("support.run")

local PAGES = { "README.md" }
for name in io.popen("ls docs/*.md"):lines() do PAGES[#PAGES + 1] = name end

local COMMAND = { "lua5%.%d ", "luajit ", "lua ", "bin/", "bench/", "%./", "/usr/bin/python3 ",
  "/usr/bin/time ",
  "luarocks ", "lua_modules/", "valgrind ", "ldoc ", "rsvg%-convert ", "eval " }

local function is_command(line)
  for _, p in ipairs(COMMAND) do
    if line:match("^" .. p) then return true end
  end
  return false
end

-- the shell lines of a code block: commands (continuations joined), loops, assignments
local SHELL = { "^for ", "^do$", "^done", "^[%a_][%w_]*=", "^#", "^cd ", "^%[ ", "^if ",
  "^then", "^else", "^fi" }
local function shell_line(line, open)
  if is_command(line) or line:match("^[%u_][%u%d_]*=") then return true end
  if not open then return false end -- a block starts with a command (a Lua `for` does not)
  for _, p in ipairs(SHELL) do
    if line:match(p) then return true end
  end
  return false
end

-- The blocks of commands and the inline commands of a page: {page, line, text, inline,
-- shown}: `shown` the output line a page shows after a `$ command` (the command then need
-- not succeed: it shows a refusal).
local function commands(page)
  local out, block, first, shown = {}, nil, nil, nil
  local n, fenced, after_dollar, shell = 0, false, false, false
  local function close()
    if block and #block > 0 then
      out[#out + 1] = { page = page, line = first, text = table.concat(block, "\n"),
        shown = shown }
    end
    block, shown, after_dollar = nil, nil, false
  end
  local text = run.read(page) .. "\n"
  for line in text:gmatch("(.-)\n") do
    n = n + 1
    if line:match("^%s*```") then
      close()
      fenced = not fenced
      -- a block marked as shell is shell from its first line (a loop may open it)
      shell = fenced and (line:match("^%s*```sh%s*$") or line:match("^%s*```bash%s*$")) ~= nil
    else
      local code = fenced and line or line:match("^    (.*)$")
      if code then
        local dollar = code:match("^%s*%$ (.*)$")
        if after_dollar and not dollar and block then shown = shown or code:gsub("^%s+", "") end
        after_dollar = dollar ~= nil or (after_dollar and not dollar)
        code = dollar or code:gsub("^%s+", "")
        local continued = block and block[#block] and block[#block]:match("\\$")
        if continued then
          block[#block] = block[#block]:gsub("\\$", "") .. " " .. code
        elseif code ~= "" and shell_line(code, block ~= nil or shell) and not after_dollar then
          if not block then block, first = {}, n end
          block[#block + 1] = code
        elseif dollar then
          if not block then block, first = {}, n end
          block[#block + 1] = code
        end
      else
        close()
        for span in line:gmatch("`([^`]+)`") do
          if is_command(span) and span:find(" ") then
            out[#out + 1] = { page = page, line = n, text = span, inline = true }
          end
        end
      end
    end
  end
  close()
  return out
end

-- A synopsis: placeholders in capitals, options in brackets, a script named without its
-- interpreter, or a command named without its arguments.
local function synopsis(cmd)
  return cmd:find("%[") ~= nil or cmd:match("%f[%w_]%u[%u_]*%f[^%w_]") ~= nil
    or cmd:match("^bench/[%w_]+%.lua") ~= nil or cmd:match("^%S+ bin/[%w%-]+$") ~= nil
end

-- Commands that need a tool tagpose does not: how far they are checked without it.
local function outside(cmd)
  if cmd:match("^/usr/bin/python3 ") then
    local script = cmd:match("^/usr/bin/python3 (%S+)")
    return "python3 -m py_compile " .. run.quote(script) .. " >/dev/null"
  elseif cmd:match("^bench/[%w_]+%.sh") then
    return "bash -n " .. run.quote(cmd:match("^(%S+)"))
  elseif cmd:match("^valgrind ") or cmd:match("^luarocks ") or cmd:match("^eval ")
    or cmd:match("^lua_modules/") or cmd:match("^ldoc ") or cmd:match("^%./test%.sh") then
    return "true" -- ./test.sh runs these itself (the rock installed, then its command run)
  end
  return nil
end

-- The same command on less: the sizes a full run measures with, made small.
local function smaller(cmd)
  cmd = cmd:gsub("(bench/make_sequences%.lua %S+) (%d+)", function(head)
    return head .. " 2 --frames 40"
  end)
  cmd = cmd:gsub("(bench/make_tags%.lua %S+ %S+ %S+) %d+", "%1 60")
  cmd = cmd:gsub("(bench/make_tags%.lua %S+ %S+ %d+)$", "%1 60")
  cmd = cmd:gsub("(bench/make_tags%.lua %S+ %S+ %d+) &&", "%1 60 &&")
  cmd = cmd:gsub("(bench/make_blocks%.lua %S+) %d+", "%1 12")
  cmd = cmd:gsub("(bench/make_long_log%.lua %S+) %d+", "%1 3000")
  cmd = cmd:gsub("(bench/make_layout%.lua %S+ %d+)", "%1 --frames 20")
  cmd = cmd:gsub("(bench/real_noise%.lua) %-%-seeds %d+", "%1 --seeds 1 --sigma 2"
    .. " bench/realdata/builderbot-exp-11")
  cmd = cmd:gsub("(bench/bounds%.lua) all (%S+)", "%1 board 3 4")
  cmd = cmd:gsub("(bench/replay_heldout%.lua %S+)$", "%1 1 2 40")
  -- (the peak memory GNU time measures is the figure's: the command is the same without it)
  cmd = cmd:gsub("^/usr/bin/time %-v ", "")
  return cmd
end

-- Synopses that are also run, with their placeholders filled.
local FILLED = {
  ["lua5.4 bench/bounds.lua board N"] = "lua5.4 bench/bounds.lua board 3 4",
}

-- What git says of the repository's tracked files (a command must change none of them: the
-- scratch folder sees the repository's own folders), or nil without git.
local function tracked_state()
  local out, status = run.run("git status --porcelain --untracked-files=no 2>/dev/null")
  if status ~= 0 then return nil end
  return out
end

-- A scratch folder with the repository's folders in it; returns its path.
local function scratch()
  local dir = os.tmpname()
  os.remove(dir)
  assert(run.run("mkdir -p " .. run.quote(dir .. "/tmp")) ~= nil)
  local here = run.run("pwd"):gsub("%s+$", "")
  for _, d in ipairs({ "bin", "src", "examples", "bench", "spec", "docs", "rockspec" }) do
    run.run("ln -s " .. run.quote(here .. "/" .. d) .. " " .. run.quote(dir .. "/" .. d))
  end
  return dir
end

-- The script a block runs (each command made smaller or checked, /tmp/ the scratch's).
local function script_of(entry, dir)
  local lines = {}
  for line in (entry.text .. "\n"):gmatch("(.-)\n") do
    local check = is_command(line) and outside(line)
    if check then
      line = check
    elseif is_command(line) then
      line = smaller(line)
    end
    lines[#lines + 1] = (line:gsub("/tmp/", dir .. "/tmp/"))
  end
  -- (Python's bytecode cache would be written into bench/, which the scratch only links to)
  return "set -e\nexport PYTHONDONTWRITEBYTECODE=1\ncd " .. run.quote(dir) .. "\n"
    .. table.concat(lines, "\n") .. "\n"
end

describe("#docs every command the README and docs/ show", function()
  for _, page in ipairs(PAGES) do
    -- a page's commands run in order, in one scratch folder (a later one may use what an
    -- earlier one wrote)
    describe(page, function()
      local dir
      setup(function() dir = scratch() end)
      teardown(function() run.run("rm -rf " .. run.quote(dir)) end)
      for _, entry in ipairs(commands(page)) do
        local where = page .. ":" .. entry.line
        it("line " .. entry.line .. ": " .. entry.text:gsub("\n.*", " ..."), function()
          local filled = FILLED[entry.text]
          if filled then entry = { text = filled } end
          if entry.inline and synopsis(entry.text) then
            -- a synopsis: its script exists
            local path = entry.text:match("^%S+ (%S+%.lua)") or entry.text:match("^(%S+)")
              :gsub("^lua5%.%d$", "")
            path = entry.text:match("bin/[%w%-]+") or path
            assert.is_truthy(io.open(path), where .. ": no " .. path)
            return
          end
          local script = run.write(dir .. "/commands.sh", script_of(entry, dir))
          local before = tracked_state()
          local out, status = run.run("bash " .. run.quote(script) .. " 2>&1")
          assert.equal(before, tracked_state(), where .. " changed the repository's files")
          if entry.shown then
            -- a refusal the page shows: its first line, as shown
            assert.equal(entry.shown, out:match("^[^\n]*"), where)
          else
            assert.equal(0, status, where .. " failed:\n" .. run.read(script) .. "\n" .. out)
          end
        end)
      end
    end)
  end
end)
