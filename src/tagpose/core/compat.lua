--- The only place that knows which Lua it runs on.
--
-- tagpose runs unchanged on Lua 5.1, 5.2, 5.3, 5.4 and LuaJIT 2.1. Every lookup whose name or
-- meaning differs between them is made here, once, with the function of the newer Lua first.
-- @module tagpose.core.compat

local M = {}

-- luacheck: push compat
--- Two-argument arc tangent, `atan2(y, x)`, in radians (LuaJIT's `math.atan` ignores a second
-- argument, so `math.atan2` must come first).
M.atan2 = math.atan2 or math.atan

--- The values `t[i], ..., t[j]` (Lua 5.1's and LuaJIT's `unpack`).
M.unpack = table.unpack or unpack

local atan2 = M.atan2

--- One-argument arc tangent, as `atan2(y, 1)` on every VM: Lua 5.3 and 5.4's `math.atan(y)`
-- is that, 5.1's and LuaJIT's is C's `atan(y)`, which may differ from it in the last bit.
-- The same bits for the same input everywhere.
-- @tparam number y
-- @treturn number radians
function M.atan(y)
  return atan2(y, 1)
end

local setfenv, loadstring = setfenv, loadstring

--- Compile Lua source text as a chunk whose globals are the table `env` (text only, never
-- bytecode).
-- @tparam string text source
-- @tparam string name chunk name for messages
-- @tparam table env the chunk's environment
-- @treturn function the chunk
-- @return nil, string on a syntax error
function M.load_text(text, name, env)
  if setfenv then -- Lua 5.1, LuaJIT
    if text:byte(1) == 27 then return nil, name .. ": binary chunks are not loaded" end
    local chunk, err = loadstring(text, name)
    if chunk then setfenv(chunk, env) end
    return chunk, err
  end
  return load(text, name, "t", env)
end
-- luacheck: pop

local huge = math.huge

--- True on LuaJIT (for the few kernels whose fastest form differs between the VMs; the
-- results never do).
M.jit = rawget(_G, "jit") ~= nil

--- Leave a function to LuaJIT's interpreter (a no-op elsewhere): for driver code whose loops
-- branch and call so much that their traces would fill LuaJIT's machine-code area. The
-- functions it calls still compile their own loops.
-- @tparam function f
-- @treturn function f
function M.interpret(f)
  if M.jit then rawget(_G, "jit").off(f) end
  return f
end

--- Leave a whole module to LuaJIT's interpreter (a no-op elsewhere): called at a module's top
-- level, every function the module defines runs interpreted. For modules whose code branches
-- so much that LuaJIT's traces of it fill the machine-code area over and over (each time all
-- of them are thrown away and compiled again); the kernels they call compile as before.
function M.interpret_module()
  if M.jit then rawget(_G, "jit").off(debug.getinfo(2, "f").func, true) end
end

--- True when `v` is a number that is neither NaN nor ±infinity.
-- @tparam any v
-- @treturn boolean
function M.is_finite(v)
  return type(v) == "number" and v == v and v < huge and v > -huge
end

local find, byte = string.find, string.byte

--- The number a decimal numeral denotes, the same on every VM; `nil` for anything else.
-- The numeral is `[-+] digits [. [digits]] [(e|E) [-+] digits]` or the same with no digits
-- before the point (`.5`); no spaces, no hexadecimal, no `inf` or `nan` (Lua 5.1 and LuaJIT
-- read those through `strtod`, 5.3 and 5.4 do not). A whole numeral of 16 digits or more,
-- which 5.3's integers would hold exactly and doubles round, is the nearest double on every
-- VM. An exponent out of range gives ±infinity (or 0), as `tonumber` does. The scan is
-- linear in the length of `s`.
-- @tparam string s
-- @treturn number|nil
function M.decimal(s)
  -- tonumber reads every decimal numeral; what it reads beyond them (hexadecimal, inf and nan
  -- through strtod on 5.1 and LuaJIT, a string cut at a zero byte on 5.1) has other characters
  local v = tonumber(s)
  if v == nil or find(s, "[^%d%.eE+%-]") then return nil end
  if #s >= 16 and not find(s, "[%.eE]") then
    local _, e = find(s, "^[+-]?%d+")
    if e - (byte(s, 1) < 48 and 1 or 0) >= 16 then
      return tonumber(s .. "e0") -- a double on every VM, as 5.1 and LuaJIT read it
    end
  end
  return v
end

local char, floor = string.char, math.floor

--- The UTF-8 bytes of a code point, the same on every VM (Lua 5.1 and LuaJIT have no
-- `utf8.char`). The caller checks the code point: a whole number from 0 to 0x10FFFF.
-- @tparam int cp
-- @treturn string
function M.utf8_char(cp)
  if cp < 0x80 then return char(cp) end
  if cp < 0x800 then return char(0xC0 + floor(cp / 0x40), 0x80 + cp % 0x40) end
  if cp < 0x10000 then
    return char(0xE0 + floor(cp / 0x1000), 0x80 + floor(cp / 0x40) % 0x40, 0x80 + cp % 0x40)
  end
  return char(0xF0 + floor(cp / 0x40000), 0x80 + floor(cp / 0x1000) % 0x40,
    0x80 + floor(cp / 0x40) % 0x40, 0x80 + cp % 0x40)
end

return M
