--- Smoothing a tracker's log: what the forward pass records of each detection, and the
-- backward pass that revises every choice with the evidence of the later frames of its track.
--
-- Per detection row the forward pass keeps four numbers in a flat array: the row of its
-- track's previous pose (0: none), the posterior of the frame's first candidate (-1: no pose),
-- and the filter's two smoothing numbers (`tagpose.track.step`: the probability of the previous
-- frame's first candidate given this frame's first, and given its second). The backward pass
-- runs over each track from its last row: a row's smoothed probability p gives its
-- predecessor's, `a·p + b·(1 − p)`.
-- @module tagpose.tracker.smooth

local M = {}

--- Record one detection.
-- @tparam {number,...} rec the flat record
-- @tparam int row the detection's row (1-based, in the order fed)
-- @tparam int prev_row the row of its track's previous pose (0: none)
-- @tparam number first the posterior of the frame's first candidate (-1: no pose)
-- @tparam number a P(previous first | this first)
-- @tparam number b P(previous first | this second)
function M.record(rec, row, prev_row, first, a, b)
  local o = 4 * (row - 1)
  rec[o + 1], rec[o + 2], rec[o + 3], rec[o + 4] = prev_row, first, a, b
end

--- The backward pass.
-- @tparam {number,...} rec the flat record
-- @tparam int rows the rows recorded
-- @tparam function confidence the calibration of a posterior (`tagpose.track.confidence`)
-- @treturn {int,...} per row: 1 when the smoothed choice is the first candidate's side (the
--   pose returned), 2 the alternative, 0 no pose
-- @treturn {number,...} per row: the confidence of the smoothed choice (0 for no pose)
function M.run(rec, rows, confidence)
  local choice, conf, ps = {}, {}, {}
  for row = rows, 1, -1 do
    local o = 4 * (row - 1)
    local prev_row, p1, a, b = rec[o + 1], rec[o + 2], rec[o + 3], rec[o + 4]
    if p1 == nil or p1 < 0 then
      choice[row], conf[row] = 0, 0
    else
      local p = ps[row]
      if p == nil then p = p1 end
      ps[row] = nil
      -- the causal pose is the first candidate when p1 >= 0.5
      if (p >= 0.5) == (p1 >= 0.5) then
        choice[row] = 1
      else
        choice[row] = 2
      end
      conf[row] = confidence(p >= 0.5 and p or 1 - p)
      if prev_row > 0 then ps[prev_row] = a * p + b * (1 - p) end
    end
  end
  return choice, conf
end

return M
