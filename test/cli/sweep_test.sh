#!/usr/bin/env bash
# stemd-eval --sweep on a generated recording: one row per method and radius,
# the leaf method ahead of the centre of mass on late-stage plants.
#   sweep_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 4 --seed 23 >/dev/null
"$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,10 >"$tmp/table.txt" || fail "sweep exited $?"
for row in "centre of mass, m=1" "centre of mass, m=10" "leaves, m=1" "leaves, m=10"; do
  grep -q "^$row " "$tmp/table.txt" || fail "no row '$row' in: $(cat "$tmp/table.txt")"
done
json=$("$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,10 --json)
[ "$(grep -o '"method":' <<<"$json" | wc -l)" -eq 4 ] || fail "json rows: $json"
# recall of leaves at m=1 against the centre of mass at m=1
recalls=($(grep -o '"recall":[0-9.]*' <<<"$json" | cut -d: -f2))
awk -v com="${recalls[0]}" -v leaves="${recalls[2]}" 'BEGIN { exit !(leaves > com) }' \
  || fail "leaves recall ${recalls[2]} not above centre of mass ${recalls[0]}"

set +e
"$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,x >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -eq 2 ] && grep -q -- "--radii: 'x'" "$tmp/err" || fail "bad --radii: rc $rc, $(cat "$tmp/err")"
echo "sweep_test: ok"
