#!/usr/bin/env bash
# Instructions per row of a plain solve and of a solve whose confidence and covariance are
# read, once LuaJIT's traces are formed: valgrind's callgrind counts 13 passes over a data set's
# first N rows less 3 passes, over the 10 N solves between (bench/track_instructions.lua). LuaJIT
# seeds its random numbers afresh in every run, and with them which traces it forms, so the
# count differs from run to run (by a few per cent): RUNS runs of each, and their median.
#
#   bench/jit_instructions.sh [LUA] [N] [RUNS] [DATASET_DIR]
#                               (default luajit, 2000 rows, 5 runs, bench/dev/noise_0.5)
#
# Needs valgrind (Debian: apt-get install valgrind). A run of the defaults takes some minutes.
set -eu
cd "$(dirname "$0")/.."
lua=${1:-luajit}
n=${2:-2000}
runs=${3:-5}
dir=${4:-bench/dev/noise_0.5}
count() {
  valgrind --tool=callgrind --smc-check=all-non-file --callgrind-out-file=/dev/null "$lua" \
    bench/track_instructions.lua "$1" "$n" "$dir" "$2" 2>&1 | sed -n 's/.*Collected : //p'
}
median() { printf '%s\n' "$@" | sort -n | awk '{v[NR]=$1} END {print (NR%2) ? v[(NR+1)/2] : int((v[NR/2]+v[NR/2+1])/2)}'; }
for mode in plain read; do
  all=""
  for _ in $(seq "$runs"); do
    a=$(count "$mode" 3); b=$(count "$mode" 13)
    all+=" $(( (b - a) / (10 * n) ))"
  done
  eval "$mode=\$(median $all)"
  echo "$mode:$all"
done
echo "$lua, $n rows of $dir, 10 passes once warm: plain solve $plain instructions a row," \
  "read $read ($(awk "BEGIN {printf \"%.2f\", $read / $plain}") times); median of $runs runs"
