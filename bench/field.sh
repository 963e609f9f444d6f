#!/usr/bin/env bash
# The field benchmark from a clone: draw robot views of the 2024 field map, solve them with
# tagpose (layout.solve, then transform.inverse) and with OpenCV (solvePnP SQPNP, then
# solvePnPRefineLM), and print both side by side.
#
#   bench/field.sh DIR SEED [bench/make_field.lua's options: --views N --sigma PX --camera ...]
#
# LUA picks the interpreter (default lua5.4). OpenCV runs under Debian's /usr/bin/python3
# (python3-opencv, python3-numpy): a measuring tool, never a dependency of tagpose.
set -eu
if [ $# -lt 2 ]; then
  sed -n '2,9p' "$0"
  exit 2
fi
dir=$1
shift
case $dir in /*) ;; *) dir=$PWD/$dir ;; esac
cd "$(dirname "$0")/.."
lua=${LUA:-lua5.4}
"$lua" bench/make_field.lua "$dir" "$@"
"$lua" bench/field_solve.lua "$dir"
/usr/bin/python3 bench/field_opencv.py "$dir"
