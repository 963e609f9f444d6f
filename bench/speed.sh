#!/usr/bin/env bash
# The speed bar, in one run: OpenCV's C++ solvePnP (SOLVEPNP_IPPE_SQUARE, bench/opencv_speed.cpp)
# beside tagpose's refined solve on Lua 5.4 and LuaJIT (examples/benchmark.lua), on the same
# data set, interleaved round by round so that the machine's load falls on all three alike.
# Prints each round and the medians, and the ratios tagpose / OpenCV.
#
#   bench/speed.sh [DATASET_DIR] [ROUNDS]      (default bench/dev/noise_0.5, 5 rounds)
#
# Needs g++ and Debian's libopencv-dev for the C++ side (apt-get install libopencv-dev).
set -eu
cd "$(dirname "$0")/.."
dir=${1:-bench/dev/noise_0.5}
rounds=${2:-5}
bin=$(mktemp -d)/opencv_speed
g++ -O2 -o "$bin" bench/opencv_speed.cpp $(pkg-config --cflags --libs opencv4)
cv=() ; l54=() ; lj=() ; raw54=() ; rawj=() ; l54i=() ; lji=()
for r in $(seq "$rounds"); do
  c=$("$bin" "$dir" 15 | sed -n 's/.*: \([0-9.]*\) us\/pose.*/\1/p')
  out54=$(lua5.4 examples/benchmark.lua "$dir"); outj=$(luajit examples/benchmark.lua "$dir")
  a=$(echo "$out54" | sed -n 's/.*| \([0-9.]*\) µs\/pose.*/\1/p')
  j=$(echo "$outj" | sed -n 's/.*| \([0-9.]*\) µs\/pose.*/\1/p')
  ai=$(echo "$out54" | sed -n 's/.*(\([0-9.]*\) µs with into).*/\1/p')
  ji=$(echo "$outj" | sed -n 's/.*(\([0-9.]*\) µs with into).*/\1/p')
  echo "round $r: opencv $c us, lua5.4 $a us ($ai with into), luajit $j us ($ji with into)"
  cv+=("$c"); l54+=("$(awk "BEGIN {print $a / $c}")"); lj+=("$(awk "BEGIN {print $j / $c}")")
  l54i+=("$(awk "BEGIN {print $ai / $c}")"); lji+=("$(awk "BEGIN {print $ji / $c}")")
  raw54+=("$a"); rawj+=("$j")
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR]=$1} END {print (NR%2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'; }
echo "medians: opencv IPPE_SQUARE $(median "${cv[@]}") us/pose, tagpose lua5.4 $(median "${raw54[@]}")," \
  "luajit $(median "${rawj[@]}") us/pose"
echo "ratio to OpenCV (median of the rounds' ratios): lua5.4 $(median "${l54[@]}")x," \
  "luajit $(median "${lj[@]}")x"
echo "with options.into (no allocation): lua5.4 $(median "${l54i[@]}")x, luajit $(median "${lji[@]}")x"
