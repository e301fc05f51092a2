#!/usr/bin/env bash
# The real sets of DATA_DIR under other light and a noisier sensor
# (tools/perturb-recording.py: exposure, colour cast, vignetting, motion
# blur, gain noise, YUYV, MJPEG compression), each
# through the default configuration, in one table: mask IoU on carrot-dev
# and cwfid-train against their human masks, and BoniRob's stems from
# RGB+NIR and from RGB alone. The first row of each set is the frames as
# recorded (re-written as PNG, so it matches tools/eval-real.sh).
#   tools/eval-robust.sh [DATA_DIR] [OUT_DIR]    (defaults: ../shared/data, out/eval-robust)
# Builds Release first when the tools are missing. About 5.5 minutes.
# Exit 0 when the table was made; 77 (skip) when DATA_DIR is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/eval-robust}
bin=build/release
if [ ! -d "$data" ]; then
  echo "eval-robust: $data is absent: no real frames to evaluate (see README, Evaluation on real frames)" >&2
  exit 77
fi
if [ ! -x "$bin/tools/stemd-detect" ] || [ ! -x "$bin/tools/stemd-eval" ]; then
  cmake -S . -B "$bin" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$bin" -j "$(nproc)" --target stemd-detect stemd-eval
fi
mkdir -p "$out"
rows="$out/rows.jsonl"
: >"$rows"

# label exposure gains noise_dn vignetting blur_px yuyv jpeg_quality: the
# conditions, each a plausible field departure from the recorded frames
# (two stops under, a 25 % warm or cool cast, a lens's cos^4 falloff to one
# or two stops at the corners, 5 px of travel during the exposure, read
# noise of a few DN, the colour at half horizontal resolution of the V4L2
# source's default YUYV, a USB camera's MJPEG at quality 75 and 50) and
# exposure and noise combined.
conditions=(
  "as-recorded 1 1,1,1 0 1 1 0 0"
  "exposure-0.5 0.5 1,1,1 0 1 1 0 0"
  "exposure-0.25 0.25 1,1,1 0 1 1 0 0"
  "warm-cast 1 0.8,1,1.25 0 1 1 0 0"
  "cool-cast 1 1.25,1,0.8 0 1 1 0 0"
  "vignetting-0.5 1 1,1,1 0 0.5 1 0 0"
  "vignetting-0.25 1 1,1,1 0 0.25 1 0 0"
  "motion-blur-5px 1 1,1,1 0 1 5 0 0"
  "yuyv-422 1 1,1,1 0 1 1 1 0"
  "mjpeg-q75 1 1,1,1 0 1 1 0 75"
  "mjpeg-q50 1 1,1,1 0 1 1 0 50"
  "noise-2dn 1 1,1,1 2 1 1 0 0"
  "noise-4dn 1 1,1,1 4 1 1 0 0"
  "exposure-0.5+noise-2dn 0.5 1,1,1 2 1 1 0 0"
  "exposure-0.3+noise-2dn 0.3 1,1,1 2 1 1 0 0"
)

row() { printf '{"set":"%s","condition":"%s","config":"%s","result":%s}\n' "$1" "$2" "$3" "$4" >>"$rows"; }

# The current condition ($label $exposure $gains $noise $vignetting $blur $yuyv $jpeg, set by the loop below).
perturb() {  # name source: a copy of the recording under the condition
  local copy="$out/$1-$label" camera=()
  rm -rf "$copy"
  if [ "$yuyv" = 1 ]; then camera=(--yuyv); fi
  tools/perturb-recording.py "$2" "$copy" --exposure "$exposure" --gains "$gains" --noise-dn "$noise" \
    --vignetting "$vignetting" --motion-blur-px "$blur" "${camera[@]}" --jpeg-quality "$jpeg"
  echo "$copy"
}
iou() {  # name recording gt_vegetation [--set ...]
  local name=$1 recording=$2 gt=$3
  shift 3
  "$bin/tools/stemd-detect" --config config/stemd.yaml "$@" "$recording" --mask-out "$recording/masks-out" \
    >/dev/null 2>"$recording/detect.log"
  row "$name" "$label" default \
    "$("$bin/tools/stemd-eval" --iou "$recording/masks-out" "$recording" --gt-vegetation "$gt" --json)"
}

# A CWFID copy as a recording with masks (cwfid-recording.sh's frames.csv).
cwfid=""
if [ -d "$data/cwfid-train/images" ]; then
  cwfid=$out/cwfid-train-recording
  tools/cwfid-recording.sh "$data/cwfid-train" "$cwfid" >/dev/null
fi

for condition in "${conditions[@]}"; do
  read -r label exposure gains noise vignetting blur yuyv jpeg <<<"$condition"
  if [ -f "$data/carrot-dev/frames.csv" ]; then
    iou carrot-dev "$(perturb carrot-dev "$data/carrot-dev")" nonzero
  fi
  if [ -n "$cwfid" ]; then
    iou cwfid-train "$(perturb cwfid-train "$cwfid")" zero --set camera.gsd_mm_per_px=0.11
  fi
  if [ -f "$data/bonirob/frames.csv" ]; then
    copy=$(perturb bonirob "$data/bonirob")
    for segment in "rgb+nir auto" "rgb chromatic_exg"; do
      read -r config method <<<"$segment"
      "$bin/tools/stemd-detect" --config config/stemd.yaml --set camera.gsd_mm_per_px=0.395 \
        --set segment.method="$method" "$copy" --csv "$copy/$config.csv" >/dev/null 2>"$copy/$config-detect.log"
      row bonirob "$label" "$config" \
        "$("$bin/tools/stemd-eval" "$data/bonirob/stems.csv" "$copy/$config.csv" --gsd-mm-per-px 0.395 --json)"
    done
  fi
done

python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
print("%-12s %-24s %-8s %s" % ("set", "condition", "config", "result"))
for key in ("carrot-dev", "cwfid-train", "bonirob"):
    for r in (r for r in rows if r["set"] == key):
        x = r["result"]
        if "mean_iou" in x:
            text = "mean IoU %.3f (min %.3f) over %d frames" % (x["mean_iou"], x["min_iou"], x["frames"])
        else:
            text = "%d of %d stems within %g mm, %d reported" % (
                x["true_positives"], x["ground_truth"], x["tol_mm"], x["predictions"])
        print("%-12s %-24s %-8s %s" % (r["set"], r["condition"], r["config"], text))
PY
