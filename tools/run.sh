#!/usr/bin/env bash
# The daemon's run command: installs what it needs, builds Release, generates
# a synthetic field recording (once), and runs stemd on it once, with its
# status lines on the terminal, then summarises the detections.
#   tools/run.sh [OUT_DIR]        (default: out/run)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/run}

tools/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/release -j "$(nproc)" --target stemd stemd-synth stemd-eval
bin=build/release

mkdir -p "$out"
if [ ! -f "$out/recording/frames.csv" ]; then
  echo "== generating 30 late-stage frames (1296x966, 10 fps, seed 1) in $out/recording"
  "$bin/tools/stemd-synth" --out "$out/recording" --preset late --frames 30 --seed 1
fi
echo "== stemd --replay $out/recording --once (paced by the recording's t_ns; status every second)"
"$bin/src/runtime/stemd" --config config/stemd.yaml --set status.interval_s=1 \
  --replay "$out/recording" --once --detections-csv "$out/detections.csv"
echo "== summary"
frames=$(($(wc -l <"$out/recording/frames.csv") - 1))
rows=$(($(wc -l <"$out/detections.csv") - 1))
echo "$frames frames replayed, $rows stems detected -> $out/detections.csv"
# The detections file is stemd-detect's CSV with a leading t_ns column.
cut -d, -f2- "$out/detections.csv" >"$out/detections-no-t.csv"
"$bin/tools/stemd-eval" "$out/recording/stems.csv" "$out/detections-no-t.csv"
