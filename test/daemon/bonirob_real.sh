#!/usr/bin/env bash
# The daemon end to end on real frames: BoniRob's three RGB+NIR frames with
# the robot's wheel odometry (../shared/data/bonirob, or $STEMD_REAL_DATA/
# bonirob). Sugar beets 1 and 2 of plants.csv are each seen whole in two
# frames 265 mm apart: each must get exactly one TARGET, within 10 mm of
# the truth, and no second one within 30 mm, from RGB alone and from RGB+NIR.
# Skipped (77) when the data is absent.
# Usage: bonirob_real.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
data=${STEMD_REAL_DATA:-$src/../shared/data}/bonirob
if [ ! -f "$data/frames.csv" ]; then
  echo "SKIP: real data $data is absent (set STEMD_REAL_DATA to the folder holding bonirob/)"
  exit 77
fi
. "$(dirname "$0")/../support/script.sh"

# The two plants seen twice (ids 1 and 2).
awk -F, 'NR == 1 || $1 == 1 || $1 == 2' "$data/plants.csv" >"$tmp/seen-twice.csv"
[ "$(wc -l <"$tmp/seen-twice.csv")" -eq 3 ] || fail "plants 1 and 2 not in $data/plants.csv"

for method in chromatic_exg ndvi; do
  "$stemd" --config "$src/config/stemd.yaml" --set camera.gsd_mm_per_px=0.395 --set segment.method=$method \
    --set scheduler.policy=all --replay "$data" --once --can-log "$tmp/$method.log" 2>"$tmp/$method.err" ||
    fail "$method: stemd exited $?: $(tail -5 "$tmp/$method.err")"
  total=$(grep 'total:' "$tmp/$method.err") || fail "$method: no total line"
  grep -q '3 frames in, 3 out' <<<"$total" || fail "$method: not every frame went through: $total"
  grep -q 'deadline_misses 0,' <<<"$total" || fail "$method: deadline misses: $total"
  for tol in 10 30; do
    score=$("$tools/stemd-eval" --targets "$tmp/seen-twice.csv" "$tmp/$method.log" \
      --config "$src/config/stemd.yaml" --tol-mm $tol --json)
    python3 - "$method" "$tol" "$score" <<'PY' || fail "$method: $score"
import json, sys
method, tol, s = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
ok = s["plants"] == 2 and s["matched"] == 2 and s["duplicates"] == 0
print("%s, within %s mm: %d of 2 plants with a command, %d second commands, error max %.1f mm"
      % (method, tol, s["matched"], s["duplicates"], s["error_max_mm"]))
sys.exit(0 if ok else 1)
PY
  done
done
