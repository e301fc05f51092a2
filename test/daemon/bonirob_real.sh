#!/usr/bin/env bash
# The daemon end to end on real frames: BoniRob's three RGB+NIR frames with
# the robot's wheel odometry (../shared/data/bonirob, or $STEMD_REAL_DATA/
# bonirob). Sugar beets 1 and 2 of plants.csv are each seen whole in two
# frames 265 mm apart: each must get exactly one TARGET, within 10 mm of
# the truth, and no second one within 30 mm, from RGB alone and from RGB+NIR
# (NDVI, and the default, which takes the NIR plane the recording has).
# All four plants of plants.csv get exactly one TARGET within 10 mm (the
# last one is seen only in the last frame: the end of the recording must not
# drop it). Three runs of the same paced replay send the same TARGETs and
# write the same plant map, byte for byte: what is sent does not depend on
# how long the pipeline took. Skipped (77) when the data is absent.
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

run() {  # method log map
  "$stemd" --config "$src/config/stemd.yaml" "${realtime_sets[@]}" --set camera.gsd_mm_per_px=0.395 --set segment.method=$1 \
    --set scheduler.policy=all --replay "$data" --once --can-log "$2" --map "$3" 2>"$2.err" ||
    fail "$1: stemd exited $?: $(tail -5 "$2.err")"
}

# The same replay three times: the same TARGET frames (CAN id base+1 = 0x301,
# timestamps cut) and the same plant map.
for i in 1 2 3; do
  run chromatic_exg "$tmp/again$i.log" "$tmp/again$i.map"
  grep ' 301#' "$tmp/again$i.log" | cut -d' ' -f2- >"$tmp/again$i.targets"
  [ -s "$tmp/again$i.targets" ] || fail "run $i sent no TARGET"
done
for i in 2 3; do
  cmp -s "$tmp/again1.targets" "$tmp/again$i.targets" ||
    fail "run $i sent other TARGETs than run 1: $(diff "$tmp/again1.targets" "$tmp/again$i.targets" | head -5)"
  cmp -s "$tmp/again1.map" "$tmp/again$i.map" ||
    fail "run $i wrote another plant map than run 1: $(diff "$tmp/again1.map" "$tmp/again$i.map" | head -5)"
done
echo "3 runs: the same $(wc -l <"$tmp/again1.targets") TARGETs and plant map"
score=$("$tools/stemd-eval" --targets "$data/plants.csv" "$tmp/again1.log" --config "$src/config/stemd.yaml" \
  --tol-mm 10 --json)
python3 - "$score" <<'PY' || fail "every plant: $score"
import json, sys
s = json.loads(sys.argv[1])
print("all plants, within 10 mm: %d of %d with a command, %d second commands, %d others (weeds and straw: "
      "plants.csv has the sugar beets only), error max %.1f mm"
      % (s["matched"], s["plants"], s["duplicates"], s["extra"], s["error_max_mm"]))
sys.exit(0 if s["plants"] == 4 and s["matched"] == 4 and s["duplicates"] == 0 else 1)
PY

# auto is the shipped default: the recording has a nir column, so it must
# take the NIR plane (exg_and_ndvi) and say so.
for method in chromatic_exg ndvi auto; do
  run $method "$tmp/$method.log" "$tmp/$method.map"
  if [ $method = auto ]; then
    grep -q 'segment.method auto: exg_and_ndvi (every replayed frame has a nir image)' "$tmp/$method.log.err" ||
      fail "auto: no log line choosing exg_and_ndvi: $(grep -i 'segment' "$tmp/$method.log.err" | head -3)"
  fi
  total=$(grep 'total:' "$tmp/$method.log.err") || fail "$method: no total line"
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
