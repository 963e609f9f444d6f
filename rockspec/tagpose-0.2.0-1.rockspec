rockspec_format = "3.0"
package = "tagpose"
version = "0.2.0-1"
source = {
  url = "git+https://github.com/tagpose/tagpose.git",
  tag = "v0.2.0",
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
    ["tagpose"] = "src/tagpose/init.lua",
    ["tagpose.args"] = "src/tagpose/args.lua",
    ["tagpose.block"] = "src/tagpose/block/init.lua",
    ["tagpose.block.fit"] = "src/tagpose/block/fit.lua",
    ["tagpose.block.frame"] = "src/tagpose/block/frame.lua",
    ["tagpose.block.group"] = "src/tagpose/block/group.lua",
    ["tagpose.block.identity"] = "src/tagpose/block/identity.lua",
    ["tagpose.block.options"] = "src/tagpose/block/options.lua",
    ["tagpose.block.scene"] = "src/tagpose/block/scene.lua",
    ["tagpose.block.uncertainty"] = "src/tagpose/block/uncertainty.lua",
    ["tagpose.calibration"] = "src/tagpose/calibration/init.lua",
    ["tagpose.calibration.common"] = "src/tagpose/calibration/common.lua",
    ["tagpose.calibration.entries"] = "src/tagpose/calibration/entries.lua",
    ["tagpose.calibration.lua_file"] = "src/tagpose/calibration/lua_file.lua",
    ["tagpose.calibration.opencv"] = "src/tagpose/calibration/opencv.lua",
    ["tagpose.calibration.ros"] = "src/tagpose/calibration/ros.lua",
    ["tagpose.camera"] = "src/tagpose/camera.lua",
    ["tagpose.compat"] = "src/tagpose/compat.lua",
    ["tagpose.cube"] = "src/tagpose/cube.lua",
    ["tagpose.ippe"] = "src/tagpose/ippe.lua",
    ["tagpose.layout"] = "src/tagpose/layout/init.lua",
    ["tagpose.layout.align"] = "src/tagpose/layout/align.lua",
    ["tagpose.layout.bundle"] = "src/tagpose/layout/bundle.lua",
    ["tagpose.layout.calibrate"] = "src/tagpose/layout/calibrate.lua",
    ["tagpose.layout.fit"] = "src/tagpose/layout/fit.lua",
    ["tagpose.layout.io"] = "src/tagpose/layout/io.lua",
    ["tagpose.layout.model"] = "src/tagpose/layout/model.lua",
    ["tagpose.layout.report"] = "src/tagpose/layout/report.lua",
    ["tagpose.layout.schur"] = "src/tagpose/layout/schur.lua",
    ["tagpose.layout.solve"] = "src/tagpose/layout/solve.lua",
    ["tagpose.lens"] = "src/tagpose/lens.lua",
    ["tagpose.lsq"] = "src/tagpose/lsq.lua",
    ["tagpose.linsolve"] = "src/tagpose/linsolve.lua",
    ["tagpose.luadata"] = "src/tagpose/luadata/init.lua",
    ["tagpose.luadata.lexer"] = "src/tagpose/luadata/lexer.lua",
    ["tagpose.pipeline"] = "src/tagpose/pipeline.lua",
    ["tagpose.poly"] = "src/tagpose/poly.lua",
    ["tagpose.pose"] = "src/tagpose/pose.lua",
    ["tagpose.refine"] = "src/tagpose/refine.lua",
    ["tagpose.rigid"] = "src/tagpose/rigid.lua",
    ["tagpose.rotation"] = "src/tagpose/rotation.lua",
    ["tagpose.solvequad"] = "src/tagpose/solvequad.lua",
    ["tagpose.square"] = "src/tagpose/square.lua",
    ["tagpose.track"] = "src/tagpose/track.lua",
    ["tagpose.tracker"] = "src/tagpose/tracker.lua",
    ["tagpose.uncertainty"] = "src/tagpose/uncertainty/init.lua",
    ["tagpose.uncertainty.matrix"] = "src/tagpose/uncertainty/matrix.lua",
    ["tagpose.uncertainty.model"] = "src/tagpose/uncertainty/model.lua",
    ["tagpose.yaml"] = "src/tagpose/yaml/init.lua",
    ["tagpose.yaml.block"] = "src/tagpose/yaml/block.lua",
    ["tagpose.yaml.flow"] = "src/tagpose/yaml/flow.lua",
    ["tagpose.yaml.scalar"] = "src/tagpose/yaml/scalar.lua",
    ["tagpose.yaml.scanner"] = "src/tagpose/yaml/scanner.lua",
  },
}
test = {
  type = "busted",
}
