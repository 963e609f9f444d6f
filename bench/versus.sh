#!/usr/bin/env bash
# A solve of this checkout against another revision's, on one Lua: bench/versus.lua run by each
# in turn (A B A B ..., so that the machine's drift falls on both alike), and the median of the
# pairs' ratios of CPU time (this checkout over REV), with their range.
#
#   bench/versus.sh REV [MODE] [LUA] [PAIRS] [DATASET_DIR]
#
# MODE plain (default), read (confidence and covariance of every pose read), alternative
# (its alternative read) or tracker (tracker:update of one detection a frame); LUA default
# lua5.4; PAIRS default 11; DATASET_DIR default bench/dev/noise_0.5 (bench/dev/sequences for
# tracker). REV is anything git names (v0.2.0, a commit).
set -eu
cd "$(dirname "$0")/.."
rev=$1 mode=${2:-plain} lua=${3:-lua5.4} pairs=${4:-11}
default=bench/dev/noise_0.5
[ "$mode" = tracker ] && default=bench/dev/sequences
dir=${5:-$default}
other=$(mktemp -d)
trap 'rm -rf "$other"' EXIT
git archive "$rev" src | tar -x -C "$other"
ratios=""
for _ in $(seq "$pairs"); do
  a=$("$lua" bench/versus.lua src "$mode" "$dir")
  b=$("$lua" bench/versus.lua "$other/src" "$mode" "$dir")
  ratios+=" $(awk "BEGIN {printf \"%.4f\", $a / $b}")"
done
printf '%s\n' $ratios | sort -g | awk -v rev="$rev" -v mode="$mode" -v lua="$lua" '
  {v[NR] = $1}
  END {m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
    printf "%s, %s: this checkout / %s = %.3f (median of %d pairs; %.3f to %.3f)\n",
      lua, mode, rev, m, NR, v[1], v[NR]}'
