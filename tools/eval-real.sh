#!/usr/bin/env bash
# Every real data set in DATA_DIR through the default configuration, in one
# table: vegetation mask IoU against the human masks, stems against the
# annotated stems, and the daemon's TARGET commands against the field truth.
# Sets are found by their layout, whatever their folder names (other frames
# of the same sources, say CWFID's test split); a set's GSD comes from
# STEMD_EVAL_GSD="name=MM ...", else from its source (bonirob* 0.395,
# cwfid* 0.11 mm/px), else the configuration's (masks only).
#   tools/eval-real.sh [DATA_DIR] [OUT_DIR]    (defaults: ../shared/data, out/eval-real)
# The tools come from $STEMD_TOOLS and the daemon from $STEMD_DAEMON (default
# $STEMD_TOOLS/../src/runtime/stemd), else build/release (built first when
# missing). Extra configuration for every run: STEMD_EVAL_SET="key=value ...".
# A CWFID-layout set's stems are read from $STEMD_EVAL_STEMS_DIR/NAME-stems.csv
# (default test/data, this project's annotation of cwfid-train).
# Exit 0 when the table was made; 77 (skip) when DATA_DIR is absent; 2 when
# a tool is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/eval-real}
if [ ! -d "$data" ]; then
  echo "eval-real: $data is absent: no real frames to evaluate (see README, Accuracy)" >&2
  exit 77
fi
tools=${STEMD_TOOLS:-}
daemon=${STEMD_DAEMON:-}
if [ -z "$tools" ]; then
  tools=build/release/tools
  daemon=${daemon:-build/release/src/runtime/stemd}
  if [ ! -x "$tools/stemd-detect" ] || [ ! -x "$tools/stemd-eval" ] || [ ! -x "$daemon" ]; then
    cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build build/release -j "$(nproc)" --target stemd stemd-detect stemd-eval
  fi
fi
daemon=${daemon:-$tools/../src/runtime/stemd}
for tool in "$tools/stemd-detect" "$tools/stemd-eval" "$daemon"; do
  [ -x "$tool" ] || { echo "eval-real: no $tool" >&2; exit 2; }
done
. tools/real-sets.sh
mkdir -p "$out"
sets=()
for kv in ${STEMD_EVAL_SET:-}; do sets+=(--set "$kv"); done
rows="$out/rows.jsonl"
: >"$rows"

# One JSON line per result: {"set", "what", "config", ["some_plants_annotated": true,]
# "result": stemd-eval's JSON}.
row() { printf '{"set":"%s","what":"%s","config":"%s"%s,"result":%s}\n' "$1" "$2" "$3" "${5:-}" "$4" >>"$rows"; }

iou() {  # name recording gt_vegetation [--set ...]
  local name=$1 recording=$2 gt=$3
  shift 3
  rm -rf "$out/$name-masks"
  "$tools/stemd-detect" --config config/stemd.yaml "${sets[@]}" "$@" "$recording" \
    --mask-out "$out/$name-masks" >/dev/null 2>"$out/$name-detect.log"
  row "$name" "mask IoU" "default" \
    "$("$tools/stemd-eval" --iou "$out/$name-masks" "$recording" --gt-vegetation "$gt" --json)"
}

stems() {  # name recording stems.csv gsd label [--set ...]
  local name=$1 recording=$2 truth=$3 gsd=$4 label=$5
  shift 5
  "$tools/stemd-detect" --config config/stemd.yaml --set camera.gsd_mm_per_px="$gsd" "${sets[@]}" "$@" \
    "$recording" --csv "$out/$name-$label.csv" >/dev/null 2>"$out/$name-$label-detect.log"
  row "$name" "stems" "$label" \
    "$("$tools/stemd-eval" "$truth" "$out/$name-$label.csv" --gsd-mm-per-px "$gsd" --json)"
}

cwfid_stems() {  # name recording label stems.csv [--set ...]: CWFID's stems within 15 px (1.65 mm at 0.11 mm/px)
  local name=$1 recording=$2 label=$3 truth=$4
  shift 4
  local csv="$out/$name-${label//[ ,]/-}.csv"
  # The recording names frames by path, the annotation by file name.
  "$tools/stemd-detect" --config config/stemd.yaml --set camera.gsd_mm_per_px=0.11 "${sets[@]}" "$@" \
    "$recording" --csv - 2>"${csv%.csv}-detect.log" | sed 's#^[^,]*/##' >"$csv"
  row "$name" stems "$label" \
    "$("$tools/stemd-eval" "$truth" "$csv" --gsd-mm-per-px 0.11 --tol-mm 1.65 --json)" ',"some_plants_annotated":true' 
}

targets() {  # name recording plants.csv gsd label [--set ...]
  local name=$1 recording=$2 truth=$3 gsd=$4 label=$5
  shift 5
  local log="$out/$name-$label-can.log" size=$frame_size
  "$daemon" --config config/stemd.yaml --set camera.gsd_mm_per_px="$gsd" \
    --set source.width_px="${size% *}" --set source.height_px="${size#* }" \
    --set scheduler.policy=all --set source.replay_pacing=recorded "${sets[@]}" "$@" \
    --replay "$recording" --once --can-log "$log" --map "$out/$name-$label-map.jsonl" \
    >/dev/null 2>"$out/$name-$label-stemd.log"
  row "$name" "TARGETs" "$label" \
    "$("$tools/stemd-eval" --targets "$truth" "$log" --config config/stemd.yaml --tol-mm 10 --json || true)"
}

# Every set in DATA_DIR, by its layout: CWFID's (images/, masks/) or a
# recording (frames.csv) with masks, annotated stems (stems.csv) or plants
# in field coordinates (plants.csv).
found=0
for d in "$data"/*/; do
  d=${d%/}
  name=$(basename "$d")
  layout=$(real_set_layout "$d")
  gsd=$(real_set_gsd "$name" "$layout")
  if [ "$layout" = cwfid ]; then
    found=1
    STEMD_CLASSMAP=${STEMD_CLASSMAP:-$tools/stemd-classmap} tools/cwfid-recording.sh "$d" "$out/$name-recording" >/dev/null
    iou "$name" "$out/$name-recording" zero --set camera.gsd_mm_per_px="$gsd"
    # Stems annotated by eye for this project (test/data/cwfid-train-stems.csv,
    # README, "Accuracy"): the sure ones (together, then each kind) and all.
    annotated=${STEMD_EVAL_STEMS_DIR:-test/data}/$name-stems.csv
    if [ -f "$annotated" ]; then
      awk -F, 'NR == 1 || $5 == 1' "$annotated" >"$out/$name-stems-sure.csv"
      cwfid_stems "$name" "$out/$name-recording" "sure, default" "$out/$name-stems-sure.csv"
      cwfid_stems "$name" "$out/$name-recording" "sure, centre of mass" "$out/$name-stems-sure.csv" --set stem.method=com
      cwfid_stems "$name" "$out/$name-recording" "all, default" "$annotated"
      # By kind: the crop's stems and the weeds' fail for different reasons.
      for plant_kind in crop weed; do
        awk -F, -v kind="$plant_kind" 'NR == 1 || ($5 == 1 && $4 == kind)' "$annotated" >"$out/$name-stems-sure-$plant_kind.csv"
        cwfid_stems "$name" "$out/$name-recording" "sure $plant_kind, default" "$out/$name-stems-sure-$plant_kind.csv"
      done
    fi
  elif [ "$layout" = recording ]; then
    found=1
    gsd_set=()
    [ -n "$gsd" ] && gsd_set=(--set camera.gsd_mm_per_px="$gsd")
    if recording_has_column "$d" mask; then
      iou "$name" "$d" nonzero "${gsd_set[@]}"
    fi
    if [ -f "$d/stems.csv" ] || [ -f "$d/plants.csv" ]; then
      if [ -z "$gsd" ]; then
        echo "eval-real: $name: stems or plants to score but no GSD known (STEMD_EVAL_GSD=\"$name=MM\"): skipped" >&2
        continue
      fi
      # With a nir column the default (segment.method auto) reads it; "rgb"
      # is the same camera without its NIR plane.
      if recording_has_column "$d" nir; then
        configs=("rgb+nir, default|" "rgb|segment.method=chromatic_exg" "rgb+nir, ndvi|segment.method=ndvi")
      else
        configs=("rgb, default|")
      fi
      # The daemon takes frames of the configured size only: the recording's
      # (read once per set, for its TARGETs).
      frame_size=""
      [ -f "$d/plants.csv" ] && frame_size=$(recording_frame_size "$d")
      for kind in stems targets; do
        truth=$d/stems.csv
        [ "$kind" = targets ] && truth=$d/plants.csv
        [ -f "$truth" ] || continue
        for c in "${configs[@]}"; do
          extra=()
          [ -n "${c#*|}" ] && extra=(--set "${c#*|}")
          "$kind" "$name" "$d" "$truth" "$gsd" "${c%%|*}" "${extra[@]}"
        done
        if [ "$kind" = stems ]; then
          stems "$name" "$d" "$truth" "$gsd" "rgb, centre of mass" --set segment.method=chromatic_exg --set stem.method=com
        fi
      done
    fi
  else
    real_set_skipped eval-real "$name" "$layout"
  fi
done
[ "$found" = 1 ] || echo "eval-real: no set in $data" >&2

python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
width = max([12] + [len(r["set"]) for r in rows])
print("%-*s %-9s %-22s %s" % (width, "set", "measure", "configuration", "result"))
for r in rows:
    x = r["result"]
    if r["what"] == "mask IoU":
        text = "mean IoU %.3f (min %.3f) over %d frames" % (x["mean_iou"], x["min_iou"], x["frames"])
    elif r["what"] == "stems" and r.get("some_plants_annotated"):
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
    print("%-*s %-9s %-22s %s" % (width, r["set"], r["what"], r["config"], text))
PY
