-- tagpose-replay's --compare matches the solved rows of a frame with the compared log's rows of
-- the same tag nearest first. The matching is checked against its definition (every pair, in
-- order of distance, ties by index, each position at most once), written out here, and on a
-- frame of 1000 detections of one id at known positions, whose compared rows must each be
-- matched with the detection they were made from.
local nearest = require("tagpose.tools.replay.nearest")
local compare = require("tagpose.tools.replay.compare")

local sqrt = math.sqrt

-- Park-Miller: the same sequence on every VM
local function generator(seed)
  local s = seed
  return function(n)
    s = (16807 * s) % 2147483647
    return n and s % n or s / 2147483647
  end
end

-- the definition: all pairs by (distance, index in a, index in b), each index taken once
local function greedy(a, b)
  local all = {}
  for i, p in ipairs(a) do
    for j, q in ipairs(b) do
      local dx, dy, dz = p.x - q.x, p.y - q.y, p.z - q.z
      all[#all + 1] = { d = sqrt(dx * dx + dy * dy + dz * dz), i = i, j = j }
    end
  end
  table.sort(all, function(u, v)
    if u.d ~= v.d then return u.d < v.d end
    if u.i ~= v.i then return u.i < v.i end
    return u.j < v.j
  end)
  local used_a, used_b, pairs_ = {}, {}, {}
  for _, e in ipairs(all) do
    if not used_a[e.i] and not used_b[e.j] then
      used_a[e.i], used_b[e.j] = true, true
      pairs_[e.i] = { j = e.j, d = e.d }
    end
  end
  return pairs_
end

local function as_table(ka, kb, ds)
  local t = {}
  for p = 1, #ka do
    assert.is_nil(t[ka[p]], "index " .. ka[p] .. " matched twice")
    t[ka[p]] = { j = kb[p], d = ds[p] }
  end
  return t
end

describe("tagpose.tools.replay.nearest", function()
  describe("match()", function()
    it("gives the pairs of the nearest-first matching, ties and repeated positions too",
      function()
        -- positions on a small integer lattice: many equal distances and repeated positions
        for seed = 1, 100 do
          local rand = generator(seed)
          -- (the first half few enough to be matched by listing every pair: SMALL)
          local na, nb, side = rand(25), rand(25), 1 + rand(4)
          if seed % 2 == 0 then na, nb, side = 1 + rand(4), 1 + rand(4), 1 + rand(2) end
          local a, b = {}, {}
          for i = 1, na do a[i] = { x = rand(side), y = rand(side), z = rand(2) } end
          for j = 1, nb do b[j] = { x = rand(side), y = rand(side), z = rand(2) } end
          local got = as_table(nearest.match(a, b))
          local want = greedy(a, b)
          for i = 1, na do
            assert.same(want[i], got[i], ("seed %d, index %d of %d x %d"):format(seed, i, na, nb))
          end
        end
      end)

    it("gives the nearest-first matching of spread positions", function()
      for seed = 1, 2 do
        local rand = generator(1000 + seed)
        local a, b = {}, {}
        for i = 1, 60 do a[i] = { x = rand() - 0.5, y = rand(), z = 1 + rand() } end
        for j = 1, 50 do b[j] = { x = rand() - 0.5, y = rand(), z = 1 + rand() } end
        assert.same(greedy(a, b), as_table(nearest.match(a, b)), "seed " .. seed)
      end
    end)

    it("matches nothing when either set is empty", function()
      assert.same({}, (nearest.match({}, { { x = 0, y = 0, z = 0 } })))
      assert.same({}, (nearest.match({ { x = 0, y = 0, z = 0 } }, {})))
    end)
  end)
end)

describe("tagpose.tools.replay.compare", function()
  it("matches each of 1000 rows of one id with the detection it was made from", function()
    -- 1000 tags of id 0 on a 40 x 25 grid, 6 cm apart, 2 m away, each turned its own way; the
    -- compared log has each 1 mm off (less than half the spacing), in another order
    local N, path = 1000, os.tmpname()
    local rand = generator(26)
    local solved, order = {}, {}
    for k = 1, N do
      local c, r = (k - 1) % 40, math.floor((k - 1) / 40)
      local a = 0.3 * (rand() - 0.5)
      solved[k] = { tag = 0, slot = k, pose = {
        position = { x = 0.06 * (c - 19.5), y = 0.06 * (r - 12), z = 2 },
        quaternion = { w = math.cos(a / 2), x = 0, y = math.sin(a / 2), z = 0 } } }
      order[k] = k
    end
    for k = N, 2, -1 do -- a shuffle
      local j = 1 + rand(k)
      order[k], order[j] = order[j], order[k]
    end
    local f = assert(io.open(path, "w"))
    f:write("frame,tag,x,y,z,qw,qx,qy,qz\n")
    for line = 1, N do
      local s = solved[order[line]].pose
      local p, q = s.position, s.quaternion
      local u, v = rand() - 0.5, rand() - 0.5
      local w = sqrt(u * u + v * v)
      f:write(("0,0,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n"):format(p.x + 1e-3 * u / w,
        p.y + 1e-3 * v / w, p.z, q.w, q.x, q.y, q.z))
    end
    f:close()
    local c = assert(compare.open(path))
    c:match(0, solved)
    local rows = c:take(0)
    os.remove(path)
    assert.equal(N, #rows)
    assert.equal(N, c.matched)
    assert.equal(0, c.apart)
    for line, e in ipairs(rows) do
      -- (the data rows start on line 2)
      assert.equal(line + 1, e.line)
      assert.equal(solved[order[line]], e.partner, "row on line " .. e.line)
    end
  end)
end)
