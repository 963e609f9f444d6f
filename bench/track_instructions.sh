#!/usr/bin/env bash
# Instructions per row of a plain solve, of a solve whose confidence and covariance are read,
# and of tracker:update (one detection a frame), counted
# by valgrind's callgrind (repeatable whatever the machine's load): the count of N rows less the
# count of none, over N (bench/track_instructions.lua runs the rows).
#
#   bench/track_instructions.sh [LUA] [N] [SEQUENCES_DIR]   (default lua5.4, 1000 rows,
#                                                            bench/dev/sequences)
#
# Needs valgrind (Debian: apt-get install valgrind).
set -eu
cd "$(dirname "$0")/.."
lua=${1:-lua5.4}
n=${2:-1000}
dir=${3:-bench/dev/sequences}
count() {
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$lua" bench/track_instructions.lua \
    "$1" "$2" "$dir" 2>&1 | sed -n 's/.*Collected : //p'
}
p0=$(count plain 0); p=$(count plain "$n")
r0=$(count read 0); r=$(count read "$n")
t0=$(count tracker 0); t=$(count tracker "$n")
plain=$(( (p - p0) / n )); read=$(( (r - r0) / n )); tracker=$(( (t - t0) / n ))
times() { awk "BEGIN {printf \"%.2f\", $1 / $plain}"; }
echo "$lua, $n rows of $dir: plain solve $plain instructions a row," \
  "read $read ($(times "$read") times), tracker:update $tracker ($(times "$tracker") times)"
