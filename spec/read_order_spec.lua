-- Order must not matter: a number made on read (a pose's confidence, covariance and alternative,
-- the alternative's own, a tracked pose's, a block's and a layout body's) is the same whatever
-- was solved or read before it. Each is compared, bit for bit, with the same field of a fresh
-- solve read alone, after reading in three orders: fields first to last pose by pose, all solves
-- then the fields in reverse from the last pose, and the fields of neighbouring poses
-- interleaved.
local tagpose = require("tagpose")
local geometry = require("support.geometry")
local layouts = require("support.layouts")

local camera = { fx = 800, fy = 800, cx = 320, cy = 240 }
local SIZE = 0.05

-- Corner sets of random views: small, far and nearly face-on tags with noise of 0.3 px (two
-- minima with a live chord term), and larger face-on ones, exact (one minimum, mostly).
local function views(seed, n)
  local rng = geometry.rng(seed)
  local out = {}
  while #out < n do
    local exact = #out % 3 == 0
    local tilt = exact and rng.uniform(0, 0.1) or rng.uniform(0, 0.35)
    local width = exact and rng.uniform(60, 300) or rng.uniform(16, 60)
    local sigma = exact and 0 or 0.3
    local r, t = geometry.random_pose(rng, camera, SIZE, { width = width, tilt = tilt })
    local px = geometry.project(camera, r, t, SIZE)
    if px then
      for _, c in ipairs(px) do
        c[1], c[2] = c[1] + sigma * rng.normal(), c[2] + sigma * rng.normal()
      end
      out[#out + 1] = px
    end
  end
  return out
end

local function same_table(a, b, where)
  if type(a) ~= "table" or type(b) ~= "table" then
    assert(a == b, where .. ": " .. tostring(a) .. " ~= " .. tostring(b))
    return
  end
  for i = 1, 6 do
    for j = 1, 6 do
      local x, y = a[i][j], b[i][j]
      assert(x == y, ("%s [%d][%d]: %.17g, read alone %.17g"):format(where, i, j, x, y))
    end
  end
end

-- The fields of one pose as a fresh solve read each alone (a new solve per field).
local function alone(corners, options)
  local function fresh() return assert(tagpose.solve(corners, camera, SIZE, options)) end
  local ref = { confidence = fresh().confidence, covariance = fresh().covariance }
  local p = fresh()
  ref.has_alt = p.alternative ~= nil
  if ref.has_alt then
    ref.alt_confidence = fresh().alternative.confidence
    ref.alt_covariance = fresh().alternative.covariance
  end
  return ref
end

local function check(p, ref, where)
  assert(p.confidence == ref.confidence, where .. " confidence")
  same_table(p.covariance, ref.covariance, where .. " covariance")
  assert((p.alternative ~= nil) == ref.has_alt, where .. " alternative")
  if ref.has_alt then
    assert(p.alternative.confidence == ref.alt_confidence, where .. " alternative confidence")
    same_table(p.alternative.covariance, ref.alt_covariance, where .. " alternative covariance")
  end
end

-- Read the fields of poses[i] in one of several orders (the check reads what is left).
local READS = {
  function(p) local _ = p.covariance end,
  function(p) local _ = p.confidence end,
  function(p) local a = p.alternative; if a then local _ = a.covariance end end,
  function(p) local a = p.alternative; if a then local _ = a.confidence end end,
}

local function solve_all(sets, options, into)
  local out = {}
  for i, c in ipairs(sets) do
    out[i] = assert(tagpose.solve(c, camera, SIZE, into and { into = into[i], sigma =
      options and options.sigma } or options))
  end
  return out
end

describe("a value made on read", function()
  local sets = views(2511, 90)
  local refs = {}
  for i, c in ipairs(sets) do refs[i] = alone(c) end

  it("has single and double minima in the set (so that both paths are read)", function()
    local one, two = 0, 0
    for _, r in ipairs(refs) do
      if r.has_alt then two = two + 1 else one = one + 1 end
    end
    assert.is_true(one >= 10 and two >= 30, one .. " single, " .. two .. " double")
  end)

  it("is the pose's own, read pose by pose in the order of the fields", function()
    for i, c in ipairs(sets) do
      local p = assert(tagpose.solve(c, camera, SIZE))
      for _, read in ipairs(READS) do read(p) end
      check(p, refs[i], "row " .. i)
    end
  end)

  it("is the pose's own, all solved first, read from the last with the fields reversed",
    function()
      local poses = solve_all(sets)
      for i = #poses, 1, -1 do
        for k = #READS, 1, -1 do READS[k](poses[i]) end
        check(poses[i], refs[i], "row " .. i)
      end
    end)

  it("is the pose's own, the fields of neighbours interleaved", function()
    local poses = solve_all(sets)
    for i = 1, #poses - 1 do
      local p, q = poses[i], poses[i + 1]
      -- the case of the report: p's confidence, q's confidence, then p's alternative's
      -- covariance; and a single minimum read after a double
      local _ = p.confidence
      _ = q.confidence
      local a = p.alternative
      if a then _ = a.covariance end
      _ = q.covariance
      check(p, refs[i], "row " .. i)
    end
    check(poses[#poses], refs[#poses], "last row")
  end)

  it("is refused once the pose was changed in place, whatever was read before", function()
    local changed = "a pose was changed in place after its solve"
    for i = 1, #sets - 1 do
      if refs[i].has_alt then
        -- nothing read; its confidence read; another pose read between
        local p = assert(tagpose.solve(sets[i], camera, SIZE))
        p.position.x = p.position.x + 1
        assert.has_error(function() return p.confidence end, nil)
        local ok, err = pcall(function() return p.covariance end)
        assert(not ok and err:find(changed, 1, true), "row " .. i .. ": " .. tostring(err))
        p = assert(tagpose.solve(sets[i], camera, SIZE))
        local _ = p.confidence
        p.position.x = p.position.x + 1
        ok, err = pcall(function() return p.covariance end)
        assert(not ok and err:find(changed, 1, true), "row " .. i .. ": " .. tostring(err))
        p = assert(tagpose.solve(sets[i], camera, SIZE))
        _ = p.confidence
        local q = assert(tagpose.solve(sets[i + 1], camera, SIZE))
        _ = q.covariance
        p.quaternion.w = -p.quaternion.w
        ok, err = pcall(function() return p.alternative.covariance end)
        assert(not ok and err:find(changed, 1, true), "row " .. i .. ": " .. tostring(err))
      end
    end
  end)

  it("is the pose's own when solved into reused tables (options.into) in any order", function()
    local into = {}
    for i = 1, #sets do into[i] = {} end
    -- fill each table once with another row's pose, read it, then solve the row into it
    for i = 1, #sets do
      local other = assert(tagpose.solve(sets[#sets + 1 - i], camera, SIZE, { into = into[i] }))
      for _, read in ipairs(READS) do read(other) end
    end
    local poses = solve_all(sets, nil, into)
    for i = #poses, 1, -1 do
      local _ = poses[i].confidence
      if i > 1 then _ = poses[i - 1].covariance end
      check(poses[i], refs[i], "row " .. i)
    end
  end)

  it("of a tracked pose is the same whatever else was read between updates", function()
    -- two runs of one tracker over the same frames (two tags, one often ambiguous), reading in
    -- other orders, and reading other poses in between: the same numbers
    local rng = geometry.rng(77)
    local frames = {}
    for f = 1, 40 do
      local dets = {}
      for id = 1, 2 do
        local c = sets[(id - 1) * 30 + 1 + (f % 7)]
        local d = {}
        for k = 1, 4 do
          d[k] = { c[k][1] + 0.2 * rng.normal() + f * 0.1, c[k][2] + 0.2 * rng.normal() }
        end
        dets[id] = { id = id, corners = d }
      end
      frames[f] = dets
    end
    local function run(order)
      local tr = tagpose.tracker.new(camera, SIZE)
      local got = {}
      for f, dets in ipairs(frames) do
        local seen = tr:update(dets, f / 30)
        local n = #seen
        for k = 1, n do
          local s = seen[order == 1 and k or n + 1 - k]
          if order == 3 then
            local _ = assert(tagpose.solve(sets[f], camera, SIZE)).confidence
          end
          for r = 1, #READS do READS[order == 2 and #READS + 1 - r or r](s) end
        end
        for k = 1, n do
          local s = seen[k]
          got[#got + 1] = { s.confidence, s.covariance, s.alternative and s.alternative.covariance
            or false }
        end
      end
      return got
    end
    local a, b, c = run(1), run(2), run(3)
    assert.are.equal(#a, #b)
    assert.are.equal(#a, #c)
    for i = 1, #a do
      for _, other in ipairs({ b, c }) do
        assert(a[i][1] == other[i][1], "confidence of pose " .. i)
        same_table(a[i][2], other[i][2], "covariance of pose " .. i)
        same_table(a[i][3], other[i][3], "alternative's covariance of pose " .. i)
      end
    end
  end)

  it("of a layout body and a block is the same whatever was solved and read before", function()
    local rng = geometry.rng(9)
    local cube = layouts.cube(rng, 0.024, 0.055, 0, 0, 0)
    local cam = { fx = 600, fy = 600, cx = 320, cy = 240, width = 640, height = 480 }
    local scenes = {}
    for _ = 1, 12 do
      local r = geometry.axis_angle(rng.normal(), rng.normal(), rng.normal(), rng.uniform(0, 3))
      local t = { rng.uniform(-0.05, 0.05), rng.uniform(-0.04, 0.04), rng.uniform(0.25, 0.9) }
      local dets = layouts.detections(cube, cam, r, t, rng, 0.4, 75)
      if #dets > 0 then scenes[#scenes + 1] = dets end
    end
    assert.is_true(#scenes >= 8)
    local function body(dets) return tagpose.layout.solve(dets, cam, cube) end
    local function block(dets)
      return tagpose.block.solve(dets, cam, 0.024, 0.055)[1]
    end
    for _, solve in ipairs({ body, block }) do
      local ref = {}
      for i, dets in ipairs(scenes) do ref[i] = solve(dets) end
      -- again in reverse, with single tags of the set solved and read between
      for i = #scenes, 1, -1 do
        local p = assert(tagpose.solve(sets[i], camera, SIZE))
        local _ = p.covariance
        local got = solve(scenes[i])
        assert.are.equal(ref[i] == nil, got == nil)
        if got then
          assert(got.confidence == ref[i].confidence, "confidence of scene " .. i)
          same_table(got.covariance, ref[i].covariance, "covariance of scene " .. i)
          assert.are.same(ref[i].position, got.position)
        end
      end
    end
  end)
end)
