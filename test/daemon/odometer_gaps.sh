#!/usr/bin/env bash
# A recording whose odom_mm is empty for some frames (stemd-record leaves
# the cell empty where the odometer was not known: a silent bus, the machine
# reversing) replays with those frames not actuated, never placed by a
# constant-speed odometer on another scale: the strip of actuation.sh with
# three consecutive frames' odometer removed must still give exactly one
# TARGET per weed within 5 mm and none for a crop (the plants are seen in the
# frames around), counting the three frames as no_odometry. Before, auto
# placed those frames at odometry.speed_mm_per_s from zero: 16 TARGETs
# near no plant.
# Usage: odometer_gaps.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

synth_strip "$tmp/strip" 2000
# Rows 12-14 (frames 10-12) lose their odom_mm (column 5).
awk -F, 'BEGIN { OFS = "," } NR == 1 && $5 != "odom_mm" { exit 1 } NR >= 12 && NR <= 14 { $5 = "" } { print }' \
  "$tmp/strip/frames.csv" >"$tmp/frames.csv" || fail "the strip's frames.csv has no odom_mm in column 5"
mv "$tmp/frames.csv" "$tmp/strip/frames.csv"

"$stemd" --config "$src/config/stemd.yaml" "${realtime_sets[@]}" --set segment.method=chromatic_exg \
  --set source.replay_preload=true --replay "$tmp/strip" --once --can-log "$tmp/can.log" 2>"$tmp/err" ||
  fail "stemd exited $?: $(tail -5 "$tmp/err")"
grep -q 'odometry.source auto: recording (49 of 52 replayed frames carry odom_mm' "$tmp/err" ||
  fail "auto did not resolve to the recording's column: $(grep 'odometry' "$tmp/err")"

"$tools/stemd-eval" --targets "$tmp/strip/plants.csv" "$tmp/can.log" --config "$src/config/stemd.yaml" \
  --treat weeds --min-radius-mm 5 --tol-mm 5 --require-exact >"$tmp/score" 2>&1 ||
  fail "not exactly one TARGET per weed: $(cat "$tmp/score")
stemd's totals: $(grep 'total:' "$tmp/err")"
cat "$tmp/score"
total=$(grep 'total:' "$tmp/err") || fail "no total line: $(tail -5 "$tmp/err")"
grep -q 'no_odometry 3,' <<<"$total" || fail "not the three frames without an odometer: $total"
echo "PASS: $(grep -o 'no_odometry [0-9]*' <<<"$total"), one TARGET per weed"
