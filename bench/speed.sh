#!/usr/bin/env bash
# What a robot pays, in one run beside OpenCV's C++: cv::solvePnPGeneric with
# SOLVEPNP_IPPE_SQUARE, both poses and their reprojection errors (bench/opencv_speed.cpp), and
# tagpose on Lua 5.4 and LuaJIT (examples/benchmark.lua) on the same data set, interleaved round
# by round so that the machine's load falls on all of them alike. Prints each round, then the
# medians of the rounds' ratios to OpenCV for
#   - a plain solve (fresh result tables), the same with options.into, and a solve whose
#     confidence and covariance are read;
#   - tracker:update of one tag a frame, as a ratio to a plain solve of the same rows
#     (SEQUENCES_DIR, default bench/dev/sequences);
#   - the same plain solve and read in a controller loop, with other interpreted work between
#     frames (examples/benchmark.lua --controller): a hot loop of solves is a best case;
# and the bytes a plain solve allocates and what `require "tagpose"` loads.
#
#   bench/speed.sh [DATASET_DIR] [ROUNDS] [SEQUENCES_DIR]  (default bench/dev/noise_0.5, 5 rounds)
#
# Needs g++ and Debian's libopencv-dev for the C++ side (apt-get install libopencv-dev).
set -eu
cd "$(dirname "$0")/.."
dir=${1:-bench/dev/noise_0.5}
rounds=${2:-5}
seqs=${3:-bench/dev/sequences}
bin=$(mktemp -d)/opencv_speed
g++ -O2 -o "$bin" bench/opencv_speed.cpp $(pkg-config --cflags --libs opencv4)

field() { printf '%s\n' "$1" | sed -n "s/.*| $2 \([0-9.]*\).*/\1/p"; }
ratio() { awk "BEGIN {printf \"%.3f\", $1 / $2}"; }
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR]=$1} END {print (NR%2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'; }

declare -A r
for k in 54 54i 54r j ji jr t54 tj c54 c54r cj cjr; do r[$k]=""; done
for i in $(seq "$rounds"); do
  c=$("$bin" "$dir" 15 | sed -n 's/.*: \([0-9.]*\) us\/pose.*/\1/p')
  a=$(lua5.4 examples/benchmark.lua "$dir" --passes 7)
  b=$(luajit examples/benchmark.lua "$dir" --passes 7)
  ta=$(lua5.4 examples/benchmark.lua "$seqs" --tracker --passes 5)
  tb=$(luajit examples/benchmark.lua "$seqs" --tracker --passes 5)
  ca=$(lua5.4 examples/benchmark.lua "$dir" --controller --passes 7)
  cb=$(luajit examples/benchmark.lua "$dir" --controller --passes 7)
  echo "round $i: opencv $c us;" \
    "lua5.4 solve $(field "$a" solve), into $(field "$a" into), read $(field "$a" read) us," \
    "tracker $(field "$ta" update) us (solve $(field "$ta" solve));" \
    "luajit solve $(field "$b" solve), into $(field "$b" into), read $(field "$b" read) us," \
    "tracker $(field "$tb" update) us (solve $(field "$tb" solve));" \
    "controller loop: lua5.4 solve $(field "$ca" solve), read $(field "$ca" read) us," \
    "luajit solve $(field "$cb" solve), read $(field "$cb" read) us"
  r[54]+=" $(ratio "$(field "$a" solve)" "$c")"
  r[54i]+=" $(ratio "$(field "$a" into)" "$c")"
  r[54r]+=" $(ratio "$(field "$a" read)" "$c")"
  r[j]+=" $(ratio "$(field "$b" solve)" "$c")"
  r[ji]+=" $(ratio "$(field "$b" into)" "$c")"
  r[jr]+=" $(ratio "$(field "$b" read)" "$c")"
  r[t54]+=" $(field "$ta" ratio)"
  r[tj]+=" $(field "$tb" ratio)"
  r[c54]+=" $(ratio "$(field "$ca" solve)" "$c")"
  r[c54r]+=" $(ratio "$(field "$ca" read)" "$c")"
  r[cj]+=" $(ratio "$(field "$cb" solve)" "$c")"
  r[cjr]+=" $(ratio "$(field "$cb" read)" "$c")"
done
echo "ratio to OpenCV's C++ (median of the rounds):"
echo "  plain solve:                    lua5.4 $(median ${r[54]})x, luajit $(median ${r[j]})x"
echo "  with options.into:              lua5.4 $(median ${r[54i]})x, luajit $(median ${r[ji]})x"
echo "  reading confidence, covariance: lua5.4 $(median ${r[54r]})x, luajit $(median ${r[jr]})x"
echo "in a controller loop (other work between frames), ratio to OpenCV's C++:"
echo "  plain solve:                    lua5.4 $(median ${r[c54]})x, luajit $(median ${r[cj]})x"
echo "  reading confidence, covariance: lua5.4 $(median ${r[c54r]})x, luajit $(median ${r[cjr]})x"
echo "tracker:update of one tag / plain solve: lua5.4 $(median ${r[t54]})x," \
  "luajit $(median ${r[tj]})x"
echo "bytes per plain solve: lua5.4 $(field "$a" bytes), luajit $(field "$b" bytes);" \
  "with options.into: lua5.4 $(field "$a" bytes_into), luajit $(field "$b" bytes_into)"
echo "require \"tagpose\": $(lua5.4 examples/benchmark.lua --require | cut -d'|' -f2-)"
