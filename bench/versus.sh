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
# tracker). REV is anything git names (a commit, a branch, a tag) or a release,
# v0.2.0 or 0.2.0: a release is its tag when the clone has it, and otherwise the commit that
# added the release's rockspec (rockspec/tagpose-0.2.0-1.rockspec: the release commit, which
# also set _VERSION), so that no tag is needed (the repository has none).
#
#   bench/versus.sh --resolve REV     prints the commit REV names and how, and compares nothing
set -eu
cd "$(dirname "$0")/.."

# the commit REV names, on stdout; how, on stderr
resolve() {
  local rev=$1 version commit
  if commit=$(git rev-parse -q --verify "$rev^{commit}"); then
    echo "$rev: $commit (git names it)" >&2
    echo "$commit"
    return
  fi
  if [[ $rev =~ ^v?[0-9]+\.[0-9]+\.[0-9]+$ ]]; then
    version=${rev#v}
    commit=$(git log --diff-filter=A --format=%H -- "rockspec/tagpose-$version-1.rockspec" \
      | tail -n 1)
    if [ -n "$commit" ]; then
      echo "$rev: $commit (no tag $rev: the commit that added" \
        "rockspec/tagpose-$version-1.rockspec)" >&2
      echo "$commit"
      return
    fi
  fi
  echo "bench/versus.sh: $rev is neither a revision git names nor a release with a rockspec" >&2
  exit 2
}

if [ "${1:-}" = "--resolve" ]; then
  resolve "${2:?usage: bench/versus.sh --resolve REV}"
  exit 0
fi
rev=${1:?usage: bench/versus.sh REV [MODE] [LUA] [PAIRS] [DATASET_DIR]}
mode=${2:-plain} lua=${3:-lua5.4} pairs=${4:-11}
default=bench/dev/noise_0.5
[ "$mode" = tracker ] && default=bench/dev/sequences
dir=${5:-$default}
commit=$(resolve "$rev")
other=$(mktemp -d)
trap 'rm -rf "$other"' EXIT
git archive "$commit" src | tar -x -C "$other"
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
