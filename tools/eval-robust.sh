#!/usr/bin/env bash
# The real sets of DATA_DIR under other light and a noisier sensor
# (tools/perturb-recording.py: exposure, colour cast, vignetting, motion
# blur, gain noise, YUYV, MJPEG compression), each through the default
# configuration, in one table: mask IoU against the human masks, and stems
# from RGB+NIR (when the set has a NIR plane) and from RGB alone against the
# annotated stems. Every folder is a set by its layout, whatever its name
# (tools/real-sets.sh: CWFID's images/ and masks/; a recording with a mask
# column or a stems.csv), at the GSD of its source or STEMD_EVAL_GSD. The
# first row of each set is the frames as recorded (re-written as PNG, so it
# matches tools/eval-real.sh).
#   tools/eval-robust.sh [DATA_DIR] [OUT_DIR]    (defaults: ../shared/data, out/eval-robust)
# The tools come from $STEMD_TOOLS, else build/release/tools (built first
# when missing). About 5.5 minutes on the shared sets.
# Exit 0 when the table was made; 77 (skip) when DATA_DIR is absent; 2 when
# a tool is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/eval-robust}
if [ ! -d "$data" ]; then
  echo "eval-robust: $data is absent: no real frames to evaluate (see README, Accuracy)" >&2
  exit 77
fi
tools=${STEMD_TOOLS:-}
if [ -z "$tools" ]; then
  tools=build/release/tools
  if [ ! -x "$tools/stemd-detect" ] || [ ! -x "$tools/stemd-eval" ]; then
    cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build build/release -j "$(nproc)" --target stemd-detect stemd-eval stemd-classmap
  fi
fi
for tool in stemd-detect stemd-eval; do
  [ -x "$tools/$tool" ] || { echo "eval-robust: no $tools/$tool" >&2; exit 2; }
done
. tools/real-sets.sh
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
  "$tools/stemd-detect" --config config/stemd.yaml "$@" "$recording" --mask-out "$recording/masks-out" \
    >/dev/null 2>"$recording/detect.log"
  row "$name" "$label" default \
    "$("$tools/stemd-eval" --iou "$recording/masks-out" "$recording" --gt-vegetation "$gt" --json)"
}

# Every folder of DATA_DIR is a set by its layout, whatever its name
# (tools/real-sets.sh): CWFID's, read as a recording with masks
# (cwfid-recording.sh's frames.csv), or a recording, with masks (IoU) and
# stems.csv (stems, from RGB+NIR when it has a NIR plane and from RGB).
names=() layouts=() sources=() gsds=() has_columns=()
for d in "$data"/*/; do
  d=${d%/}
  name=$(basename "$d")
  layout=$(real_set_layout "$d")
  case $layout in
    cwfid)
      STEMD_CLASSMAP=${STEMD_CLASSMAP:-$tools/stemd-classmap} tools/cwfid-recording.sh "$d" "$out/$name-recording" \
        >/dev/null
      sources+=("$out/$name-recording") ;;
    recording) sources+=("$d") ;;
    *) real_set_skipped eval-robust "$name" "$layout"
       continue ;;
  esac
  gsd=$(real_set_gsd "$name" "$layout")
  if [ "$layout" = recording ] && [ -f "$d/stems.csv" ] && [ -z "$gsd" ]; then
    echo "eval-robust: $name: stems to score but no GSD known (STEMD_EVAL_GSD=\"$name=MM\"): its stems skipped" >&2
  fi
  # What each recording holds is read once, not once per condition.
  columns=""
  recording_has_column "${sources[-1]}" mask && columns+=" mask"
  recording_has_column "${sources[-1]}" nir && columns+=" nir"
  names+=("$name") layouts+=("$layout") gsds+=("$gsd") has_columns+=("$columns")
done

for condition in "${conditions[@]}"; do
  read -r label exposure gains noise vignetting blur yuyv jpeg <<<"$condition"
  for i in "${!names[@]}"; do
    name=${names[$i]} source=${sources[$i]} gsd=${gsds[$i]}
    gsd_set=()
    [ -n "$gsd" ] && gsd_set=(--set camera.gsd_mm_per_px="$gsd")
    if [ "${layouts[$i]}" = cwfid ]; then
      iou "$name" "$(perturb "$name" "$source")" zero "${gsd_set[@]}"
      continue
    fi
    stems=no
    [ -f "$source/stems.csv" ] && [ -n "$gsd" ] && stems=yes
    has_mask=no
    [[ "${has_columns[$i]}" == *" mask"* ]] && has_mask=yes
    [ "$has_mask" = yes ] || [ "$stems" = yes ] || continue
    copy=$(perturb "$name" "$source")
    if [ "$has_mask" = yes ]; then
      iou "$name" "$copy" nonzero "${gsd_set[@]}"
    fi
    [ "$stems" = yes ] || continue
    segments=("rgb chromatic_exg")
    [[ "${has_columns[$i]}" == *" nir"* ]] && segments=("rgb+nir auto" "rgb chromatic_exg")
    for segment in "${segments[@]}"; do
      read -r config method <<<"$segment"
      "$tools/stemd-detect" --config config/stemd.yaml "${gsd_set[@]}" \
        --set segment.method="$method" "$copy" --csv "$copy/$config.csv" >/dev/null 2>"$copy/$config-detect.log"
      row "$name" "$label" "$config" \
        "$("$tools/stemd-eval" "$source/stems.csv" "$copy/$config.csv" --gsd-mm-per-px "$gsd" --json)"
    done
  done
done

python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
width = max([12] + [len(r["set"]) for r in rows])
print("%-*s %-24s %-8s %s" % (width, "set", "condition", "config", "result"))
for key in dict.fromkeys(r["set"] for r in rows):  # each set's rows together, in the order found
    for r in (r for r in rows if r["set"] == key):
        x = r["result"]
        if "mean_iou" in x:
            text = "mean IoU %.3f (min %.3f) over %d frames" % (x["mean_iou"], x["min_iou"], x["frames"])
        else:
            text = "%d of %d stems within %g mm, %d reported" % (
                x["true_positives"], x["ground_truth"], x["tol_mm"], x["predictions"])
        print("%-*s %-24s %-8s %s" % (width, r["set"], r["condition"], r["config"], text))
PY
