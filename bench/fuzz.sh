#!/usr/bin/env bash
# The full hardening run: spec/fuzz_spec.lua with all its cases (the test suite runs a twentieth),
# or more. SCALE 1 is 100 000 hostile solves, 20 000 lens inversions and 3000 hostile block
# frames; SCALE 10 ten times that. About 25 s per VM at SCALE 1 on Lua 5.4 (2 shared cores).
#
#   bench/fuzz.sh [SCALE] [VM ...]        (default: 1, lua5.4 luajit)
set -eu
cd "$(dirname "$0")/.."
scale=${1:-1}
shift || true
vms=("$@")
[ ${#vms[@]} -gt 0 ] || vms=(lua5.4 luajit)
for vm in "${vms[@]}"; do
  echo "== fuzz x$scale on $vm"
  TAGPOSE_FUZZ_SCALE=$scale busted --lua="$vm" spec/fuzz_spec.lua
done
