-- The folders are the layers (docs/method.md, "Modules"): data flows one way, down. A module
-- may require a module of its own layer or of a lower one, never of a higher one, and the
-- require graph has no cycle. The graph is read from the sources: every `require("tagpose…")`,
-- at the top of a module or lazily inside a function, and every string that names a module of
-- src/ (the facade's fields loaded when first used, `tagpose.layout`'s `lazy(name)`).
local run = require("support.run")

-- The layers, lowest first: a module belongs to the layer of the longest prefix that names it.
local LAYERS = {
  -- what every solve loads, and the pose algebra beside it
  { "tagpose.core", "tagpose.transform" },
  -- what a solve loads when a result's field is first read, or with a prior
  { "tagpose.track", "tagpose.uncertainty" },
  -- the end of every solve of one tag: the pose table and its fields made on read, the
  -- tracking filter's choice (the facade's solve and the tracker both end here)
  { "tagpose.result" },
  -- rigid sets of tags: the rigid-body model that blocks, the localizer and the layout files
  -- build on
  { "tagpose.rigid" },
  -- the file formats: loaded by a reader, never by a solve; on the model, under the layouts'
  -- read and write and the facade's calibration
  { "tagpose.formats" },
  -- many tags frame by frame, blocks, the robot on a map, rigid sets of tags solved and
  -- calibrated
  { "tagpose.tracker", "tagpose.block", "tagpose.localizer", "tagpose.layout" },
  -- the facade: the public API (`require("tagpose")`)
  { "tagpose" },
  -- the workstation's tools (the tagpose-tools rock): a client of the library
  { "tagpose.tools" },
}

-- The edges that go up today, each with its reason: every one is lazy (inside a function, or a
-- name loaded when first used), so no require at load time goes up or closes a cycle. The spec
-- fails when one of them is gone, so that it is taken off this list.
local EXCEPTIONS = {
  -- The localizer solves each detection through the public solve, its checks and its corner
  -- order: a cycle tagpose -> tagpose.localizer -> tagpose.localizer.engine -> tagpose, closed
  -- only at run time (each side requires the other inside a function).
  ["tagpose.localizer.engine -> tagpose"] = "each detection solved by tagpose.solve",
}

-- What the tools may require besides the facade and their own modules: the facilities the tools
-- share with the library that are not public fields (a module name, and why). Each is the one
-- place of its kind, which a copy under tools/ would make two; the tools rock depends on
-- exactly its own version of the library (spec/rockspec_spec.lua), so they cannot drift apart.
local TOOL_EXCEPTIONS = {
  -- the one place that knows which Lua it runs on (decimal numerals read alike on every VM)
  ["tagpose.core.compat"] = "the one compat module: numbers read and printed alike on every VM",
  -- the `bad argument` wording of every entry point, the plot's included
  ["tagpose.core.args"] = "the one wording of a misuse (describe, raise)",
  -- the one output writer: whole or not at all, devices written through; layout.write and the
  -- camera writers write with it too
  ["tagpose.formats.output"] = "the one output writer the library's writers use too",
  -- the safe reader of Lua data (nothing in it runs), for tagpose-localize's cameras file
  ["tagpose.formats.luadata"] = "the one reader of Lua data files",
}


local function module_name(path)
  return (path:gsub("^src/", ""):gsub("%.lua$", ""):gsub("/init$", ""):gsub("/", "."))
end

-- The source without its comments (a `--` inside a string is kept).
local function code_of(text)
  text = text:gsub("%-%-%[(=*)%[.-%]%1%]", "")
  local lines = {}
  for line in (text .. "\n"):gmatch("(.-)\n") do
    local masked = line:gsub("\"[^\"]*\"", function(s) return (s:gsub("%-", "\1")) end)
    masked = masked:gsub("'[^']*'", function(s) return (s:gsub("%-", "\1")) end)
    local c = masked:find("%-%-")
    lines[#lines + 1] = c and line:sub(1, c - 1) or line
  end
  return lines
end

-- modules by name, and the edges: `edges[from][to] = true` when `from` names `to`, lazy unless
-- a line at the top level (no indent) requires it
local function read_graph()
  local files = run.files("src", "%.lua$")
  table.sort(files)
  local modules = {}
  for _, path in ipairs(files) do modules[module_name(path)] = path end
  local edges, at_load = {}, {}
  for _, path in ipairs(files) do
    local from = module_name(path)
    edges[from], at_load[from] = {}, {}
    local f = assert(io.open(path, "rb"))
    local text = f:read("*a")
    f:close()
    for _, line in ipairs(code_of(text)) do
      for to in line:gmatch("[\"']([%w_.]+)[\"']") do
        if modules[to] and to ~= from then
          edges[from][to] = true
          local top = line:match("^[%a_][%w_., ]*=%s*require%s*%(?%s*[\"']")
          if top or line:match("^require") then
            at_load[from][to] = true
          end
        end
      end
    end
  end
  return modules, edges, at_load
end

local function layer_of(name)
  local best, best_len
  for i, layer in ipairs(LAYERS) do
    for _, prefix in ipairs(layer) do
      if (name == prefix or name:sub(1, #prefix + 1) == prefix .. ".")
        and (not best_len or #prefix > best_len) then
        best, best_len = i, #prefix
      end
    end
  end
  return best
end

local function sorted_keys(t)
  local keys = {}
  for k in pairs(t) do keys[#keys + 1] = k end
  table.sort(keys)
  return keys
end

-- a cycle of the graph (as a list of names), or nil
local function find_cycle(edges, skip)
  local state, stack = {}, {}
  local function visit(v)
    state[v] = "open"
    stack[#stack + 1] = v
    for _, w in ipairs(sorted_keys(edges[v] or {})) do
      if not (skip and skip[v .. " -> " .. w]) then
        if state[w] == "open" then
          local cycle = {}
          for i = #stack, 1, -1 do
            table.insert(cycle, 1, stack[i])
            if stack[i] == w then break end
          end
          cycle[#cycle + 1] = w
          return cycle
        elseif not state[w] then
          local c = visit(w)
          if c then return c end
        end
      end
    end
    stack[#stack] = nil
    state[v] = "done"
  end
  for _, v in ipairs(sorted_keys(edges)) do
    if not state[v] then
      local c = visit(v)
      if c then return c end
    end
  end
end

describe("the layers of src/", function()
  local modules, edges, at_load = read_graph()

  it("place every module in a layer", function()
    for _, name in ipairs(sorted_keys(modules)) do
      assert(layer_of(name), name .. " is in no layer of spec/layers_spec.lua")
    end
  end)

  it("read the lazy requires too", function()
    assert.is_true(edges["tagpose.result.pose"]["tagpose.track"])
    assert.is_nil(at_load["tagpose.result.pose"]["tagpose.track"])
    assert.is_true(at_load["tagpose.result.pose"]["tagpose.core.rotation"])
    assert.is_true(edges["tagpose"]["tagpose.localizer"])
  end)

  it("are required downwards only, but for the listed exceptions", function()
    local up = {}
    for _, from in ipairs(sorted_keys(edges)) do
      for _, to in ipairs(sorted_keys(edges[from])) do
        if layer_of(to) > layer_of(from) then
          local edge = from .. " -> " .. to
          up[edge] = true
          assert(EXCEPTIONS[edge], edge .. ": requires a module of a higher layer")
          assert(not at_load[from][to], edge .. ": an exception required at load time")
        end
      end
    end
    for _, edge in ipairs(sorted_keys(EXCEPTIONS)) do
      assert(up[edge], edge .. " is gone: take it off the exceptions of spec/layers_spec.lua")
    end
  end)

  it("have no cycle at load time", function()
    local cycle = find_cycle(at_load)
    assert(not cycle, "a cycle: " .. table.concat(cycle or {}, " -> "))
  end)

  it("have no cycle but through the listed exceptions", function()
    local cycle = find_cycle(edges, EXCEPTIONS)
    assert(not cycle, "a cycle: " .. table.concat(cycle or {}, " -> "))
  end)

  -- what they share is below them: a block is fitted with the rigid-body model, not through the
  -- layout subsystem's facade
  it("keep the subsystems of a layer apart: tracker, block, localizer and layout", function()
    local subsystems = LAYERS[layer_of("tagpose.block")]
    local function subsystem(name)
      for _, prefix in ipairs(subsystems) do
        if name == prefix or name:sub(1, #prefix + 1) == prefix .. "." then return prefix end
      end
    end
    for _, from in ipairs(sorted_keys(edges)) do
      for _, to in ipairs(sorted_keys(edges[from])) do
        local a, b = subsystem(from), subsystem(to)
        if a and b and a ~= b then
          error(from .. " -> " .. to .. ": " .. a .. " requires " .. b
            .. ", a subsystem of its own layer: move what they share to a lower layer")
        end
      end
    end
  end)

  it("leave the tools a client of the facade, but for the listed exceptions", function()
    local used = {}
    for _, from in ipairs(sorted_keys(edges)) do
      if layer_of(from) == #LAYERS then
        for _, to in ipairs(sorted_keys(edges[from])) do
          if to ~= "tagpose" and layer_of(to) ~= #LAYERS then
            used[to] = true
            assert(TOOL_EXCEPTIONS[to], from .. " requires " .. to
              .. ", which is not public: use a field of require('tagpose')")
          end
        end
      end
    end
    for _, name in ipairs(sorted_keys(TOOL_EXCEPTIONS)) do
      assert(used[name], name .. " is no longer required by the tools: take it off the list")
    end
  end)
end)
