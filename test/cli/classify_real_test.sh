#!/usr/bin/env bash
# The crop/weed classifier on the real shared sets (../shared/data, or
# $STEMD_REAL_DATA): stemd-train's cross-validation by frame on carrot-dev
# and cwfid-train, with the context stage (a second cell forest on the
# first one's probabilities around each cell). Per pixel of vegetation,
# each cell's class at p 0.5 must reach a balanced accuracy of 0.80
# (measured 2026-11-28: carrot-dev 0.851 / 0.859 / 0.862 for seeds 1-3,
# cwfid-train 0.803), the class map at its fitted bar 0.80 (0.852 / 0.861 /
# 0.864, 0.803), and the cell-size ceiling (every segmented pixel its 3 mm
# cell's majority class) 0.90 (0.943, 0.939). Per plant (by the share of
# its cells) at the default decision, at most 5 % of crop plants may be
# called weed (2, 2 and 1 of 44; 2 of 57 measured) with a weed recall of
# at least 0.8 on carrot-dev (0.967 / 0.960 / 0.957) and
# 0.49 on cwfid-train (0.636; 0.49 is what the class-blind detector treats
# of CWFID's weeds). A higher min_confidence never calls more crops weed.
# Both sets' figures are the medians over forests of three seeds (see
# below); cwfid-train's first forest is the example model's.
# Skipped (exit 77) when the data is absent, as on a user's machine.
# cwfid-train goes through tools/cwfid-model.sh, the example model's script.
#   classify_real_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1 src=$2
data=${STEMD_REAL_DATA:-$src/../shared/data}
if [ ! -f "$data/carrot-dev/frames.csv" ] || [ ! -d "$data/cwfid-train/annotations" ]; then
  echo "SKIP: real data sets carrot-dev/ and cwfid-train/ absent under $data (set STEMD_REAL_DATA)"
  exit 77
fi
. "$(dirname "$0")/../support/script.sh"

# figures OUTPUT: one line from stemd-train's output, "pixel map ceiling
# safety_p05 safety_default crops weed_recall": per-pixel balanced accuracy
# at p 0.5, the class map's at its fitted bar, the cell-size ceiling, crop
# plants called weed (by the share of their cells) at p 0.5 and at the
# default decision, crop plants, weed recall per plant at the default.
figures() {
  local out=$1
  grep -q ' 30 cell trees, 30 context trees,' "$out" || fail "$out: the model has no context forest: $(tail -1 "$out")"
  local pixel map ceiling block safety crops weed_recall
  pixel=$(sed -n "s/^  pixels of vegetation (each cell's class at this decision): .* balanced accuracy \([0-9.]*\);.*/\1/p" "$out")
  [ "$(wc -l <<<"$pixel")" -eq 2 ] || fail "$out: no per-pixel figures: $(cat "$out")"
  map=$(sed -n 's/^  class map bar fitted: [0-9.]* (balanced accuracy \([0-9.]*\) .*/\1/p' "$out")
  [ -n "$map" ] || fail "$out: no fitted class map bar: $(cat "$out")"
  ceiling=$(sed -n "s/.*cell ceiling, every segmented pixel its cell's majority class: \([0-9.]*\)).*/\1/p" "$out" | head -1)
  # Per plant by the share of its cells: the recalls line and the crop
  # safety line after its title, at p 0.5 then at the default decision.
  block=$(grep -A2 '^  plants by the share of its cells:' "$out")
  safety=$(sed -n 's/^    crop safety: \([0-9]*\) of .*/\1/p' <<<"$block")
  crops=$(sed -n 's/^  plants by the share of its cells: \([0-9]*\) crop,.*/\1/p' <<<"$block" | head -1)
  weed_recall=$(sed -n 's/^    crop: .* | weed: precision [0-9.]* recall \([0-9.]*\) .*/\1/p' <<<"$block" | sed -n 2p)
  [ "$(wc -l <<<"$safety")" -eq 2 ] && [ -n "$weed_recall" ] && [ -n "$ceiling" ] ||
    fail "$out: no per-plant figures: $(cat "$out")"
  echo "$(head -1 <<<"$pixel") $map $ceiling $(tr '\n' ' ' <<<"$safety")$crops $weed_recall"
}

# check NAME MIN_WEED_RECALL OUTPUT...: the median of each figure over the
# outputs (forests of different seeds on the same frames) against the
# bounds; each model on its own must call no more crops weed at the default
# decision than at p 0.5.
check() {
  local name=$1 min_weed_recall=$2
  shift 2
  local rows="" out
  for out in "$@"; do
    local row
    row=$(figures "$out")
    awk -v r="$row" 'BEGIN { split(r, f, " "); exit !(f[5] <= f[4]) }' ||
      fail "$name ($out): more crop plants called weed at the default decision than at p 0.5: $row"
    rows+="$row"$'\n'
  done
  rows=${rows%$'\n'}
  local median="" column n
  n=$(wc -l <<<"$rows")
  for column in 1 2 3 4 5 6 7; do
    median+="$(cut -d' ' -f"$column" <<<"$rows" | sort -g | sed -n "$(((n + 1) / 2))p") "
  done
  local pixel map ceiling safety crops weed_recall
  read -r pixel map ceiling _ safety crops weed_recall <<<"$median"
  awk -v a="$pixel" 'BEGIN { exit !(a >= 0.80) }' || fail "$name: per-pixel balanced accuracy $pixel at p 0.5, under 0.80"
  awk -v a="$map" 'BEGIN { exit !(a >= 0.80) }' || fail "$name: class map balanced accuracy $map, under 0.80"
  awk -v a="$ceiling" 'BEGIN { exit !(a >= 0.90) }' || fail "$name: cell-size ceiling '$ceiling', under 0.90"
  awk -v n="$safety" -v c="$crops" 'BEGIN { exit !(c > 0 && n / c <= 0.05) }' ||
    fail "$name: $safety of $crops crop plants called weed at the default decision, over 5 %"
  awk -v r="$weed_recall" -v m="$min_weed_recall" 'BEGIN { exit !(r >= m) }' ||
    fail "$name: weed recall $weed_recall per plant at the default decision, under $min_weed_recall"
  echo "$name (median of $#): pixel balanced accuracy $pixel (class map $map, cell ceiling $ceiling); crop plants called weed $safety of $crops; weed recall $weed_recall"
}

# carrot-dev with the forests of three seeds: one forest's random draws
# move its per-plant figures by a plant or two of 44 crop plants (seeds 1,
# 2 and 3 on 2026-11-27: 3, 1 and 1 called weed at the default decision;
# on 2026-11-28, with the folds' forests drawing no importance, 2, 2 and
# 1), so the median measures the classifier rather than one draw.
for seed in 1 2 3; do
  "$tools/stemd-train" --seed "$seed" --out "$tmp/carrot-$seed.yaml" --set camera.gsd_mm_per_px=0.25 "$data/carrot-dev" \
    >"$tmp/carrot-$seed.txt" 2>&1 || fail "stemd-train carrot-dev (seed $seed) exited $?: $(cat "$tmp/carrot-$seed.txt")"
done
check carrot-dev 0.8 "$tmp"/carrot-{1,2,3}.txt
# CWFID through the example-model script: its class recording, then
# stemd-train on it (the script's seed, 1), and the forests of seeds 2 and
# 3 on the same recording. One forest's draws move CWFID's crop plants
# called weed as carrot-dev's (seeds 1-5 on 2026-12-07: 4, 2, 1, 1 and 2
# of 57; the tree before that day's plant-colour rows, 2, 3, 1, 1 and 3),
# so the median of three is checked here too.
STEMD_TOOLS="$tools" "$src/tools/cwfid-model.sh" "$data/cwfid-train" "$tmp/models/cwfid.yaml" \
  >"$tmp/cwfid.txt" 2>&1 || fail "cwfid-model.sh exited $?: $(cat "$tmp/cwfid.txt")"
head -1 "$tmp/models/cwfid-recording/frames.csv" | grep -q ',class$' || fail "cwfid-recording.sh wrote no class column"
for seed in 2 3; do
  "$tools/stemd-train" --seed "$seed" --out "$tmp/cwfid-$seed.yaml" --set camera.gsd_mm_per_px=0.11 \
    "$tmp/models/cwfid-recording" >"$tmp/cwfid-$seed.txt" 2>&1 ||
    fail "stemd-train cwfid-train (seed $seed) exited $?: $(cat "$tmp/cwfid-$seed.txt")"
done
check cwfid-train 0.49 "$tmp/cwfid.txt" "$tmp"/cwfid-{2,3}.txt
# The example model classes plants with stemd-detect (on the frames it was
# trained on: this shows it loads and runs, not how well it does).
"$tools/stemd-detect" --set camera.gsd_mm_per_px=0.11 --set classify.model="$tmp/models/cwfid.yaml" \
  --csv "$tmp/classes.csv" "$tmp/models/cwfid-recording" >/dev/null 2>&1 ||
  fail "stemd-detect with the example model exited $?"
grep -q ',crop,[0-9.]*$' "$tmp/classes.csv" && grep -q ',weed,[0-9.]*$' "$tmp/classes.csv" ||
  fail "the example model called no plant crop or none weed: $(head "$tmp/classes.csv")"
