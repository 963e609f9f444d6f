#!/usr/bin/env bash
# tagpose-localize on the two drive logs (bench/dev/drive, clean; bench/dev/drive_hard, hard):
# fused (corners, odometry and gyro) and --single (corners and gyro, each frame on its own),
# each run timed (wall seconds, on the machine named first), then scored with the peers by
# bench/score_drive.lua, one table per log; and a causality check: the fused run on the log cut
# at 30 s (the rows of corners.csv, odometry.csv and gyro.csv with time < 30) must give the
# full run's rows before 30 s, byte for byte; and the fused run's map check against the tag
# the log's meta.json says was moved (bench/map_check.lua).
#
#   bench/drive.sh [LUA]
#
# LUA default lua5.4 (runs the localizer and the scorer). Exits 1 when a run fails, the cut
# run's rows differ from the full run's, or the map check misses the moved tag (after printing
# everything else).
set -u
cd "$(dirname "$0")/.." || exit 1
lua=${1:-lua5.4}
CUT=30
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
status=0

cpu=$(awk -F': ' '/^model name/ {print $2; exit}' /proc/cpuinfo)
echo "machine: $(nproc) CPUs, ${cpu:-unknown CPU}; $("$lua" -v 2>&1 | head -n 1)"
echo

# run NAME DIR OUT [OPTIONS...]: tagpose-localize on DIR's corners, map and cameras; sets secs
run() {
  local name=$1 dir=$2 out=$3
  shift 3
  local t0 t1
  t0=$(date +%s.%N)
  if ! "$lua" bin/tagpose-localize "$dir/corners.csv" --map "$dir/map.json" \
      --cameras "$dir/cameras.lua" "$@" --out "$out" >"$out.stdout" 2>"$out.stderr"; then
    echo "$name: tagpose-localize failed:" >&2
    tail -n 15 "$out.stderr" | sed 's/^/  | /' >&2
    return 1
  fi
  t1=$(date +%s.%N)
  secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.2f", b - a}')
}

for log in drive drive_hard; do
  dir=bench/dev/$log
  work=$tmp/$log
  mkdir -p "$work"
  fused=$work/tagpose_fused.csv single=$work/tagpose_single.csv
  run "$log fused" "$dir" "$fused" --odometry "$dir/odometry.csv" --gyro "$dir/gyro.csv" \
    --map-check "$work/check.csv" || exit 1
  fused_secs=$secs
  run "$log single" "$dir" "$single" --gyro "$dir/gyro.csv" --single || exit 1
  single_secs=$secs
  if [ "$log" = drive ]; then echo "### drive (clean)"; else echo "### drive_hard (hard)"; fi
  echo
  "$lua" bench/score_drive.lua "$dir" "$fused" "$single" "$dir/peer_multitag.csv" \
    "$dir/peer_constrained_w100.csv" "$dir/peer_fused.csv" || exit 1
  echo
  echo "tagpose_fused: corners, odometry and gyro, ${fused_secs} s wall;" \
    "tagpose_single: corners and gyro (--single), ${single_secs} s wall"
  "$lua" bench/map_check.lua "$dir" "$work/check.csv" || status=1

  # causality: the log cut at CUT s, run fused, against the full run's rows before CUT s
  cut=$work/cut
  mkdir -p "$cut"
  for f in corners odometry gyro; do
    awk -F, -v cut="$CUT" 'NR == 1 || $1 + 0 < cut' "$dir/$f.csv" >"$cut/$f.csv"
  done
  cp "$dir/map.json" "$dir/cameras.lua" "$cut/"
  run "$log cut" "$cut" "$cut/tagpose_fused.csv" --odometry "$cut/odometry.csv" \
    --gyro "$cut/gyro.csv" || exit 1
  awk -F, -v cut="$CUT" 'NR == 1 || $1 + 0 < cut' "$fused" >"$cut/full_before.csv"
  awk -F, -v cut="$CUT" 'NR == 1 || $1 + 0 < cut' "$cut/tagpose_fused.csv" >"$cut/cut_before.csv"
  rows=$(($(wc -l <"$cut/full_before.csv") - 1))
  if cmp -s "$cut/full_before.csv" "$cut/cut_before.csv"; then
    echo "causal: $rows rows before $CUT s identical (the log cut at $CUT s, ${secs} s wall)"
  else
    line=$(cmp "$cut/full_before.csv" "$cut/cut_before.csv" 2>&1 | sed -n 's/.*line \([0-9]*\).*/\1/p')
    echo "causal: NOT identical: the full run has $rows rows before $CUT s, the cut run" \
      "$(($(wc -l <"$cut/cut_before.csv") - 1)); first difference, line ${line:-?} (line 1 the header):"
    echo "  full: $(sed -n "${line:-1}p" "$cut/full_before.csv")"
    echo "  cut:  $(sed -n "${line:-1}p" "$cut/cut_before.csv")"
    status=1
  fi
  echo
done
exit $status
