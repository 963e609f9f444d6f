rockspec_format = "3.0"
package = "tagpose"
version = "scm-1"
source = {
  url = "git+https://github.com/tagpose/tagpose.git",
}
description = {
  summary = "AprilTag pose (position and rotation) from four image corners, in pure Lua",
  detailed = [[
    tagpose gives a robot controller the 3D position and rotation of every AprilTag it sees,
    from the tag's four image corners and the camera's intrinsics. It implements the method of
    Zhu, Allwright and Dorigo, "A Solution for April-tag Positioning" (2017), in pure Lua with
    no dependencies, on Lua 5.1-5.4 and LuaJIT.
  ]],
  license = "MIT",
  labels = { "apriltag", "pose", "robotics", "vision" },
}
dependencies = {
  "lua >= 5.1",
}
test_dependencies = {
  "busted",
}
build = {
  type = "builtin",
  modules = {
    ["tagpose.block.body"] = "src/tagpose/block/body.lua",
    ["tagpose.block.fit"] = "src/tagpose/block/fit.lua",
    ["tagpose.block.frame"] = "src/tagpose/block/frame.lua",
    ["tagpose.block.group"] = "src/tagpose/block/group.lua",
    ["tagpose.block.identity"] = "src/tagpose/block/identity.lua",
    ["tagpose.block"] = "src/tagpose/block/init.lua",
    ["tagpose.block.options"] = "src/tagpose/block/options.lua",
    ["tagpose.block.result"] = "src/tagpose/block/result.lua",
    ["tagpose.block.scene"] = "src/tagpose/block/scene.lua",
    ["tagpose.block.search"] = "src/tagpose/block/search.lua",
    ["tagpose.block.uncertainty"] = "src/tagpose/block/uncertainty.lua",
    ["tagpose.core.args"] = "src/tagpose/core/args.lua",
    ["tagpose.core.camera"] = "src/tagpose/core/camera.lua",
    ["tagpose.core.compat"] = "src/tagpose/core/compat.lua",
    ["tagpose.core.ippe"] = "src/tagpose/core/ippe.lua",
    ["tagpose.core.lens"] = "src/tagpose/core/lens.lua",
    ["tagpose.core.lsq"] = "src/tagpose/core/lsq.lua",
    ["tagpose.core.pipeline"] = "src/tagpose/core/pipeline.lua",
    ["tagpose.core.poly"] = "src/tagpose/core/poly.lua",
    ["tagpose.core.pose"] = "src/tagpose/core/pose.lua",
    ["tagpose.core.refine"] = "src/tagpose/core/refine.lua",
    ["tagpose.core.result"] = "src/tagpose/core/result.lua",
    ["tagpose.core.rotation"] = "src/tagpose/core/rotation.lua",
    ["tagpose.core.solvequad"] = "src/tagpose/core/solvequad.lua",
    ["tagpose.core.square"] = "src/tagpose/core/square.lua",
    ["tagpose.formats.calibration.common"] = "src/tagpose/formats/calibration/common.lua",
    ["tagpose.formats.calibration.entries"] = "src/tagpose/formats/calibration/entries.lua",
    ["tagpose.formats.calibration"] = "src/tagpose/formats/calibration/init.lua",
    ["tagpose.formats.calibration.kalibr"] = "src/tagpose/formats/calibration/kalibr.lua",
    ["tagpose.formats.calibration.lua_file"] = "src/tagpose/formats/calibration/lua_file.lua",
    ["tagpose.formats.calibration.opencv"] = "src/tagpose/formats/calibration/opencv.lua",
    ["tagpose.formats.calibration.ros"] = "src/tagpose/formats/calibration/ros.lua",
    ["tagpose.formats.calibration.storage"] = "src/tagpose/formats/calibration/storage.lua",
    ["tagpose.formats.failure"] = "src/tagpose/formats/failure.lua",
    ["tagpose.formats.json"] = "src/tagpose/formats/json.lua",
    ["tagpose.formats.layout"] = "src/tagpose/formats/layout.lua",
    ["tagpose.formats.layout_encode"] = "src/tagpose/formats/layout_encode.lua",
    ["tagpose.formats.luadata"] = "src/tagpose/formats/luadata/init.lua",
    ["tagpose.formats.luadata.lexer"] = "src/tagpose/formats/luadata/lexer.lua",
    ["tagpose.formats.output"] = "src/tagpose/formats/output.lua",
    ["tagpose.formats.wpilib"] = "src/tagpose/formats/wpilib.lua",
    ["tagpose.formats.xml"] = "src/tagpose/formats/xml.lua",
    ["tagpose.formats.yaml.block"] = "src/tagpose/formats/yaml/block.lua",
    ["tagpose.formats.yaml.flow"] = "src/tagpose/formats/yaml/flow.lua",
    ["tagpose.formats.yaml"] = "src/tagpose/formats/yaml/init.lua",
    ["tagpose.formats.yaml.scalar"] = "src/tagpose/formats/yaml/scalar.lua",
    ["tagpose.formats.yaml.scanner"] = "src/tagpose/formats/yaml/scanner.lua",
    ["tagpose"] = "src/tagpose/init.lua",
    ["tagpose.layout.align"] = "src/tagpose/layout/align.lua",
    ["tagpose.layout.bundle"] = "src/tagpose/layout/bundle.lua",
    ["tagpose.layout.calibrate"] = "src/tagpose/layout/calibrate.lua",
    ["tagpose.layout.cube"] = "src/tagpose/layout/cube.lua",
    ["tagpose.layout.fit"] = "src/tagpose/layout/fit.lua",
    ["tagpose.layout"] = "src/tagpose/layout/init.lua",
    ["tagpose.layout.linsolve"] = "src/tagpose/layout/linsolve.lua",
    ["tagpose.layout.minima"] = "src/tagpose/layout/minima.lua",
    ["tagpose.layout.model"] = "src/tagpose/layout/model.lua",
    ["tagpose.layout.report"] = "src/tagpose/layout/report.lua",
    ["tagpose.layout.rigid"] = "src/tagpose/layout/rigid.lua",
    ["tagpose.layout.schur"] = "src/tagpose/layout/schur.lua",
    ["tagpose.layout.solve"] = "src/tagpose/layout/solve.lua",
    ["tagpose.track.filter"] = "src/tagpose/track/filter.lua",
    ["tagpose.track"] = "src/tagpose/track/init.lua",
    ["tagpose.tracker.associate"] = "src/tagpose/tracker/associate.lua",
    ["tagpose.tracker"] = "src/tagpose/tracker/init.lua",
    ["tagpose.tracker.smooth"] = "src/tagpose/tracker/smooth.lua",
    ["tagpose.tracker.tracks"] = "src/tagpose/tracker/tracks.lua",
    ["tagpose.transform"] = "src/tagpose/transform.lua",
    ["tagpose.uncertainty"] = "src/tagpose/uncertainty/init.lua",
    ["tagpose.uncertainty.matrix"] = "src/tagpose/uncertainty/matrix.lua",
    ["tagpose.uncertainty.model"] = "src/tagpose/uncertainty/model.lua",
    ["tagpose.uncertainty.read"] = "src/tagpose/uncertainty/read.lua",
  },
}
test = {
  type = "busted",
}
