#!/usr/bin/env bash
# stemd-eval --sweep on a generated recording: the centre of mass and the
# paper's method per radius, the robust estimator at its own radius, and the
# robust one ahead of the centre of mass on late-stage plants.
#   sweep_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 4 --seed 23 >/dev/null
"$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,10 >"$tmp/table.txt" || fail "sweep exited $?"
for row in "centre of mass, m=1" "centre of mass, m=10" "paper, m=1" "paper, m=10" "robust, m=5"; do
  grep -q "^$row " "$tmp/table.txt" || fail "no row '$row' in: $(cat "$tmp/table.txt")"
done
json=$("$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,10 --json)
[ "$(grep -o '"method":' <<<"$json" | wc -l)" -eq 5 ] || fail "json rows: $json"
# F1 of the robust estimator (last row) against the centre of mass at m=10 (second row)
f1s=($(grep -o '"f1":[0-9.]*' <<<"$json" | cut -d: -f2))
awk -v com="${f1s[1]}" -v robust="${f1s[4]}" 'BEGIN { exit !(robust > com) }' \
  || fail "robust F1 ${f1s[4]} not above centre of mass ${f1s[1]}"

set +e
"$tools/stemd-eval" --sweep "$tmp/rec/stems.csv" "$tmp/rec" --radii 1,x >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -eq 2 ] && grep -q -- "--radii: 'x'" "$tmp/err" || fail "bad --radii: rc $rc, $(cat "$tmp/err")"
echo "sweep_test: ok"
