#!/usr/bin/env bash
# tagpose's whole check, as CI runs it: install what is missing (Debian packages), lint, run the
# specs on every Lua, build the LDoc reference and check its links, lint the rockspecs, and check
# that the rockspec installs the library that then loads.
# Ends with one line "N passed, N failed" summing every run.
#
#   ./test.sh            everything
#   ./test.sh lua5.4     the specs on the named VMs only (plus lint and the rockspec)
set -u
cd "$(dirname "$0")" || exit 1

VMS=${*:-"lua5.1 lua5.2 lua5.3 lua5.4 luajit"}
# liblua5.4-dev: LuaRocks builds for Lua 5.4 with it (the README's install); libxml2-utils:
# xmllint checks the plots; librsvg2-bin: rsvg-convert renders them; lua-ldoc
# and lua-discount (its Markdown): the API reference
PACKAGES="lua5.1 lua5.2 lua5.3 lua5.4 liblua5.4-dev luajit lua-busted lua-check luarocks libxml2-utils
  librsvg2-bin lua-ldoc lua-discount"

missing=""
for p in $PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "installing:$missing"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  if ! { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq \
      $missing >/dev/null; }; then
    echo "could not install:$missing"
    echo "0 passed, 1 failed"
    exit 1
  fi
fi

passed=0
failed=0
pass() { passed=$((passed + $1)); }
fail() { failed=$((failed + $1)); }

echo "== luacheck"
if luacheck --no-color -q .; then pass 1; else fail 1; fi

# TAP lines of a busted run: passes and failures added to the totals (failures shown)
tally() {
  local name=$1 out=$2
  ok=$(printf '%s\n' "$out" | grep -c '^ok ')
  nok=$(printf '%s\n' "$out" | grep -c '^not ok ')
  if [ "$ok" -eq 0 ] && [ "$nok" -eq 0 ]; then
    printf '%s\n' "$out" | tail -n 20
    nok=1
  elif [ "$nok" -gt 0 ]; then
    printf '%s\n' "$out" | grep -A 12 '^not ok'
  fi
  echo "$name: $ok passed, $nok failed"
  pass "$ok"
  fail "$nok"
}

for vm in $VMS; do
  echo "== specs on $vm"
  out=$(busted --lua="$vm" -o TAP 2>&1)
  tally "$vm" "$out"
done

# every command the README and docs/ show, once (each names its Lua: lua5.4, luajit)
echo "== the commands of the README and docs/"
out=$(busted --lua=lua5.4 --tags=docs --exclude-tags=none -o TAP 2>&1)
tally "docs" "$out"

echo "== ldoc builds the API reference without warnings"
doc=$(mktemp -d)
ldoc --fatalwarnings -d "$doc/html" . >"$doc/log" 2>&1
status=$?
# anything but its two progress lines is a warning (or a missing Markdown processor)
if [ "$status" -eq 0 ] && [ -f "$doc/html/index.html" ] \
    && ! grep -v -e '^reading configuration from ' -e '^output written to ' "$doc/log" | grep -q .
then
  pass 1
else
  cat "$doc/log"
  echo "ldoc failed (exit $status)"
  fail 1
fi
echo "== every link of the API reference lands (a page, an #anchor)"
if lua5.4 bench/check_links.lua "$doc/html"; then pass 1; else fail 1; fi
rm -rf "$doc"

for rockspec in rockspec/*.rockspec; do
  echo "== luarocks lint $rockspec"
  if luarocks lint "$rockspec"; then pass 1; else fail 1; fi
done

echo "== the rocks install into a fresh tree as the README says: the library loads, the command runs"
tree=$(mktemp -d)
if luarocks --lua-version 5.4 --tree "$tree" make rockspec/tagpose-scm-1.rockspec \
      >"$tree/make.log" 2>&1 \
    && luarocks --lua-version 5.4 --tree "$tree" make rockspec/tagpose-tools-scm-1.rockspec \
      >>"$tree/make.log" 2>&1
then
  data=$(pwd)/examples/data
  if (cd "$tree" && eval "$(luarocks --lua-version 5.4 --tree "$tree" path)" && lua5.4 -e "
      local tagpose = require('tagpose')
      local src = debug.getinfo(tagpose.solve, 'S').source
      assert(src:sub(1, #'@$tree') == '@$tree', 'loaded from ' .. src)
      local pose = assert(tagpose.solve({{280, 280}, {360, 280}, {360, 200}, {280, 200}},
        {fx = 883.98, fy = 883.98, cx = 319.5, cy = 239.5}, 0.024))
      print('installed copy loads from ' .. src:sub(2) .. ', z = ' .. pose.position.z)
    " && "$tree/bin/tagpose-replay" "$data/approach.csv" --svg approach.svg | tail -n 1); then
    pass 1
  else
    fail 1
  fi
else
  cat "$tree/make.log"
  fail 1
fi
rm -rf "$tree"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
