#!/usr/bin/env bash
# Every real data set in DATA_DIR through the default configuration, in one
# table: vegetation mask IoU against the human masks, stems against the
# annotated stems, and the daemon's TARGET commands against the field truth.
#   tools/eval-real.sh [DATA_DIR] [OUT_DIR]    (defaults: ../shared/data, out/eval-real)
# Builds Release first when the tools are missing. Extra configuration for
# every run: STEMD_EVAL_SET="key=value key=value".
# Exit 0 when the table was made; 77 (skip) when DATA_DIR is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/eval-real}
bin=build/release
if [ ! -d "$data" ]; then
  echo "eval-real: $data is absent: no real frames to evaluate (see README, Evaluation on real frames)" >&2
  exit 77
fi
if [ ! -x "$bin/tools/stemd-detect" ] || [ ! -x "$bin/tools/stemd-eval" ] || [ ! -x "$bin/src/runtime/stemd" ]; then
  cmake -S . -B "$bin" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$bin" -j "$(nproc)" --target stemd stemd-detect stemd-eval
fi
mkdir -p "$out"
sets=()
for kv in ${STEMD_EVAL_SET:-}; do sets+=(--set "$kv"); done
rows="$out/rows.jsonl"
: >"$rows"

# One JSON line per result: {"set", "what", "config", ...stemd-eval's JSON}.
row() { printf '{"set":"%s","what":"%s","config":"%s","result":%s}\n' "$1" "$2" "$3" "$4" >>"$rows"; }

iou() {  # name recording gt_vegetation [--set ...]
  local name=$1 recording=$2 gt=$3
  shift 3
  rm -rf "$out/$name-masks"
  "$bin/tools/stemd-detect" --config config/stemd.yaml "${sets[@]}" "$@" "$recording" \
    --mask-out "$out/$name-masks" >/dev/null 2>"$out/$name-detect.log"
  row "$name" "mask IoU" "default" \
    "$("$bin/tools/stemd-eval" --iou "$out/$name-masks" "$recording" --gt-vegetation "$gt" --json)"
}

stems() {  # name recording stems.csv gsd label [--set ...]
  local name=$1 recording=$2 truth=$3 gsd=$4 label=$5
  shift 5
  "$bin/tools/stemd-detect" --config config/stemd.yaml --set camera.gsd_mm_per_px="$gsd" "${sets[@]}" "$@" \
    "$recording" --csv "$out/$name-$label.csv" >/dev/null 2>"$out/$name-$label-detect.log"
  row "$name" "stems" "$label" \
    "$("$bin/tools/stemd-eval" "$truth" "$out/$name-$label.csv" --gsd-mm-per-px "$gsd" --json)"
}

cwfid_stems() {  # label stems.csv [--set ...]: CWFID's stems within 15 px (1.65 mm at 0.11 mm/px)
  local label=$1 truth=$2
  shift 2
  local csv="$out/cwfid-train-${label//[ ,]/-}.csv"
  # The recording names frames by path, the annotation by file name.
  "$bin/tools/stemd-detect" --config config/stemd.yaml --set camera.gsd_mm_per_px=0.11 "${sets[@]}" "$@" \
    "$out/cwfid-train-recording" --csv - 2>"${csv%.csv}-detect.log" | sed 's#^[^,]*/##' >"$csv"
  row cwfid-train stems "$label" \
    "$("$bin/tools/stemd-eval" "$truth" "$csv" --gsd-mm-per-px 0.11 --tol-mm 1.65 --json)"
}

targets() {  # name recording plants.csv gsd label [--set ...]
  local name=$1 recording=$2 truth=$3 gsd=$4 label=$5
  shift 5
  local log="$out/$name-$label-can.log"
  "$bin/src/runtime/stemd" --config config/stemd.yaml --set camera.gsd_mm_per_px="$gsd" \
    --set scheduler.policy=all --set source.replay_pacing=recorded "${sets[@]}" "$@" \
    --replay "$recording" --once --can-log "$log" --map "$out/$name-$label-map.jsonl" \
    >/dev/null 2>"$out/$name-$label-stemd.log"
  row "$name" "TARGETs" "$label" \
    "$("$bin/tools/stemd-eval" --targets "$truth" "$log" --config config/stemd.yaml --tol-mm 10 --json || true)"
}

if [ -f "$data/carrot-dev/frames.csv" ]; then
  iou carrot-dev "$data/carrot-dev" nonzero
else echo "eval-real: no $data/carrot-dev: skipped" >&2; fi

if [ -d "$data/cwfid-train/images" ]; then
  tools/cwfid-recording.sh "$data/cwfid-train" "$out/cwfid-train-recording" >/dev/null
  iou cwfid-train "$out/cwfid-train-recording" zero --set camera.gsd_mm_per_px=0.11
  # Stems annotated by eye for this project (test/data/cwfid-train-stems.csv,
  # README "Evaluation on real frames"): the sure ones, and all of them.
  awk -F, 'NR == 1 || $5 == 1' test/data/cwfid-train-stems.csv >"$out/cwfid-train-stems-sure.csv"
  cwfid_stems "sure, default" "$out/cwfid-train-stems-sure.csv"
  cwfid_stems "sure, centre of mass" "$out/cwfid-train-stems-sure.csv" --set stem.method=com
  cwfid_stems "all, default" test/data/cwfid-train-stems.csv
else echo "eval-real: no $data/cwfid-train: skipped" >&2; fi

if [ -f "$data/bonirob/frames.csv" ]; then
  b=$data/bonirob
  # The recording has a nir column: the default (segment.method auto)
  # reads it; "rgb" is the same camera without its NIR plane.
  stems bonirob "$b" "$b/stems.csv" 0.395 "rgb+nir, default"
  stems bonirob "$b" "$b/stems.csv" 0.395 rgb --set segment.method=chromatic_exg
  stems bonirob "$b" "$b/stems.csv" 0.395 "rgb+nir, ndvi" --set segment.method=ndvi
  stems bonirob "$b" "$b/stems.csv" 0.395 "rgb, centre of mass" --set segment.method=chromatic_exg --set stem.method=com
  targets bonirob "$b" "$b/plants.csv" 0.395 "rgb+nir, default"
  targets bonirob "$b" "$b/plants.csv" 0.395 rgb --set segment.method=chromatic_exg
  targets bonirob "$b" "$b/plants.csv" 0.395 "rgb+nir, ndvi" --set segment.method=ndvi
else echo "eval-real: no $data/bonirob: skipped" >&2; fi

python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
print("%-12s %-9s %-22s %s" % ("set", "measure", "configuration", "result"))
for r in rows:
    x = r["result"]
    if r["what"] == "mask IoU":
        text = "mean IoU %.3f (min %.3f) over %d frames" % (x["mean_iou"], x["min_iou"], x["frames"])
    elif r["what"] == "stems" and r["set"] == "cwfid-train":
        # Not every plant is annotated, so a precision would mean nothing.
        text = "%d of %d stems within %g mm, %d reported, mean error %.2f mm" % (
            x["true_positives"], x["ground_truth"], x["tol_mm"], x["predictions"], x["mean_error_mm"])
    elif r["what"] == "stems":
        text = "%d of %d stems within %g mm, precision %.0f %% (%d reported), mean error %.2f mm" % (
            x["true_positives"], x["ground_truth"], x["tol_mm"], 100 * x["precision"], x["predictions"],
            x["mean_error_mm"])
    else:
        text = "%d of %d plants with a command within %g mm, %d duplicates, %d extra, error p50 %.1f max %.1f mm" % (
            x["matched"], x["plants"], x["tol_mm"], x["duplicates"], x["extra"], x["error_p50_mm"],
            x["error_max_mm"])
    print("%-12s %-9s %-22s %s" % (r["set"], r["what"], r["config"], text))
PY
