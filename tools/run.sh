#!/usr/bin/env bash
# The daemon's run command: installs what it needs, builds Release, generates
# a synthetic moving field strip (once), and runs stemd on it the way the
# robot would, with no camera and no CAN bus: replayed at its own pace (30 fps,
# 5 km/h), TARGET commands written as a candump log, every plant in the map.
# Then it shows the commands and scores them against the field's truth.
#   tools/run.sh [OUT_DIR]        (default: out/run)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/run}

tools/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/release -j "$(nproc)" --target stemd stemd-synth stemd-eval
bin=build/release

mkdir -p "$out"
if [ ! -f "$out/strip/plants.csv" ]; then
  echo "== generating a 3 m late-stage field strip (5 km/h, 30 fps, seed 1) in $out/strip"
  "$bin/tools/stemd-synth" --strip --out "$out/strip" --preset late --seed 1 --length-mm 3000
fi
echo "== stemd --replay $out/strip --once --can-log $out/can.log --map $out/map.jsonl (preloaded)"
# Preloaded: a camera delivers its frames decoded, and decoding the strip's
# RGB and NIR PNGs (the default segment.method auto reads both) would
# hold the replay below 30 fps on two cores.
"$bin/src/runtime/stemd" --config config/stemd.yaml --set status.interval_s=1 --set source.replay_preload=true \
  --replay "$out/strip" --once --detections-csv "$out/detections.csv" \
  --can-log "$out/can.log" --map "$out/map.jsonl"
echo "== the first TARGET commands (candump -L; id 0x301 = TARGET, 0x303 = HEARTBEAT; see config/stemd.dbc)"
grep ' can0 301#' "$out/can.log" | head -5
echo "   ... $(grep -c ' can0 301#' "$out/can.log") TARGET frames in $out/can.log"
echo "== the plant map ($out/map.jsonl), first lines"
head -3 "$out/map.jsonl"
echo "== commands against the truth (policy: weeds only, from the class map)"
"$bin/tools/stemd-eval" --targets "$out/strip/plants.csv" "$out/can.log" --config config/stemd.yaml --treat weeds
echo "== per-frame stem detections against the truth"
cut -d, -f2- "$out/detections.csv" >"$out/detections-no-t.csv"
"$bin/tools/stemd-eval" "$out/strip/stems.csv" "$out/detections-no-t.csv"
