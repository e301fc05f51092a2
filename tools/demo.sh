#!/usr/bin/env bash
# The run command, until the daemon exists: installs what it needs, builds,
# generates a synthetic field recording, detects stems in it (CSV and
# overlays), and scores them against the ground truth.
#   tools/demo.sh [OUT_DIR]        (default: out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/demo}

tools/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/release -j "$(nproc)" --target stemd-synth stemd-detect stemd-eval
bin=build/release/tools

rm -rf "$out"
mkdir -p "$out"
echo "== generating 10 late-stage frames (1296x966, seed 1) in $out/recording"
"$bin/stemd-synth" --out "$out/recording" --preset late --frames 10 --seed 1
echo "== detecting stems (config/stemd.yaml)"
"$bin/stemd-detect" --config config/stemd.yaml --csv "$out/stems-detected.csv" --overlay "$out/overlays" \
  --mask-out "$out/masks" --timing "$out/recording"
echo "== scoring against the ground truth (0.5 cm tolerance, as in the paper)"
"$bin/stemd-eval" "$out/recording/stems.csv" "$out/stems-detected.csv"
echo "== leaf method against centre of mass, closing radius m = 1, 6, 10, 20"
"$bin/stemd-eval" --sweep "$out/recording/stems.csv" "$out/recording" --config config/stemd.yaml
echo
echo "detections: $out/stems-detected.csv   overlays: $out/overlays/   masks: $out/masks/"
