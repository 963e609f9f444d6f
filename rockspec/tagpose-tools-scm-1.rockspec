rockspec_format = "3.0"
package = "tagpose-tools"
version = "scm-1"
source = {
  url = "git+https://github.com/tagpose/tagpose.git",
}
description = {
  summary = "Workstation tools for tagpose: logs, plots, tagpose-replay, tagpose-calibrate",
  detailed = [[
    The tools around the tagpose library that a robot does not need: reading and writing
    corner logs and pose logs, drawing poses over frames as SVG, and the tagpose-replay command
    that replays a recorded corner log. The robot installs the tagpose rock alone.
  ]],
  license = "MIT",
  labels = { "apriltag", "pose", "robotics", "vision" },
}
-- The tools are built with the library of the same commit and tested with it only: each
-- release of the tools depends on exactly the same version of the library (`tagpose == 0.4.0`
-- in tagpose-tools-0.4.0-1), as this one on the library's scm rock (spec/rockspec_spec.lua).
dependencies = {
  "lua >= 5.1",
  "tagpose == scm",
}
test_dependencies = {
  "busted",
}
build = {
  type = "builtin",
  modules = {
    ["tagpose.tools.calibrate"] = "src/tagpose/tools/calibrate.lua",
    ["tagpose.tools.command"] = "src/tagpose/tools/command.lua",
    ["tagpose.tools.csv"] = "src/tagpose/tools/csv.lua",
    ["tagpose.tools.files"] = "src/tagpose/tools/files.lua",
    ["tagpose.tools.localize"] = "src/tagpose/tools/localize.lua",
    ["tagpose.tools.localize_geometry"] = "src/tagpose/tools/localize_geometry.lua",
    ["tagpose.tools.localize_plot"] = "src/tagpose/tools/localize_plot.lua",
    ["tagpose.tools.log"] = "src/tagpose/tools/log.lua",
    ["tagpose.tools.plot.draw"] = "src/tagpose/tools/plot/draw.lua",
    ["tagpose.tools.plot.figure"] = "src/tagpose/tools/plot/figure.lua",
    ["tagpose.tools.plot"] = "src/tagpose/tools/plot/init.lua",
    ["tagpose.tools.plot.recorder"] = "src/tagpose/tools/plot/recorder.lua",
    ["tagpose.tools.plot.scale"] = "src/tagpose/tools/plot/scale.lua",
    ["tagpose.tools.plot.svg"] = "src/tagpose/tools/plot/svg.lua",
    ["tagpose.tools.replay.clock"] = "src/tagpose/tools/replay/clock.lua",
    ["tagpose.tools.replay.command"] = "src/tagpose/tools/replay/command.lua",
    ["tagpose.tools.replay.compare"] = "src/tagpose/tools/replay/compare.lua",
    ["tagpose.tools.replay.frames"] = "src/tagpose/tools/replay/frames.lua",
    ["tagpose.tools.replay"] = "src/tagpose/tools/replay/init.lua",
    ["tagpose.tools.replay.nearest"] = "src/tagpose/tools/replay/nearest.lua",
    ["tagpose.tools.replay.slots"] = "src/tagpose/tools/replay/slots.lua",
    ["tagpose.tools.replay.stats"] = "src/tagpose/tools/replay/stats.lua",
    ["tagpose.tools.replay.summary"] = "src/tagpose/tools/replay/summary.lua",
    ["tagpose.tools.tag_id"] = "src/tagpose/tools/tag_id.lua",
  },
  install = {
    bin = {
      ["tagpose-calibrate"] = "bin/tagpose-calibrate",
      ["tagpose-localize"] = "bin/tagpose-localize",
      ["tagpose-replay"] = "bin/tagpose-replay",
    },
  },
}
test = {
  type = "busted",
}
