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
    ["tagpose"] = "src/tagpose/init.lua",
    ["tagpose.args"] = "src/tagpose/args.lua",
    ["tagpose.block"] = "src/tagpose/block.lua",
    ["tagpose.camera"] = "src/tagpose/camera.lua",
    ["tagpose.compat"] = "src/tagpose/compat.lua",
    ["tagpose.cube"] = "src/tagpose/cube.lua",
    ["tagpose.ippe"] = "src/tagpose/ippe.lua",
    ["tagpose.linsolve"] = "src/tagpose/linsolve.lua",
    ["tagpose.pose"] = "src/tagpose/pose.lua",
    ["tagpose.refine"] = "src/tagpose/refine.lua",
    ["tagpose.rigid"] = "src/tagpose/rigid.lua",
    ["tagpose.rotation"] = "src/tagpose/rotation.lua",
    ["tagpose.solvequad"] = "src/tagpose/solvequad.lua",
    ["tagpose.square"] = "src/tagpose/square.lua",
    ["tagpose.track"] = "src/tagpose/track.lua",
    ["tagpose.tracker"] = "src/tagpose/tracker.lua",
  },
}
test = {
  type = "busted",
}
