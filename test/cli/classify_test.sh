#!/usr/bin/env bash
# The crop/weed classifier as a user scripts it: stemd-train on a generated
# strip (its class column), then stemd-detect with the model: the csv's
# class columns, class maps, and the refusals (GSD, channels, no model).
#   classify_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1 src=$2
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --strip --out "$tmp/rec" --length-mm 1500 --width 640 --height 480 --seed 5 >/dev/null
# The strip carries NIR; the classifier is tested on RGB (segment.method
# auto would take the NIR plane: tested in detect_test.sh and on BoniRob).

"$tools/stemd-train" --out "$tmp/model.yaml" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --folds 3 --trees 20 "${small_forests[@]}" --jobs 1 "$tmp/rec" \
  >"$tmp/train.txt" 2>&1 || fail "stemd-train exited $?: $(cat "$tmp/train.txt")"
grep -q '^3-fold cross-validation by frame' "$tmp/train.txt" || fail "no cross-validation figures"
grep -q 'crop safety: [0-9]* of [0-9]* crop plants called weed' "$tmp/train.txt" || fail "no crop-safety figure"
grep -q "pixels of vegetation (each cell's class at this decision).*balanced accuracy" "$tmp/train.txt" || fail "no per-pixel figure"
grep -q '^  class map bar fitted: ' "$tmp/train.txt" || fail "no fitted class map bar"
grep -Eq '^ +cell_trees: [1-9]' "$tmp/model.yaml" || fail "model file says no cell trees"
grep -q '^cell_forest:' "$tmp/model.yaml" || fail "model file has no cell_forest section"
grep -q '^stemd_plant_classifier:' "$tmp/model.yaml" || fail "model file has no metadata section"
grep -q 'channels: rgb$' "$tmp/model.yaml" || fail "model file does not say rgb"
grep -Eq 'gsd_mm_per_px: (0?\.33$|3\.30*[0-9]*e-01)' "$tmp/model.yaml" || fail "model file does not hold the GSD"
grep -q "$tmp/rec" "$tmp/model.yaml" || fail "model file does not name its recording"

# Same data, same seed: the same forests and figures, on one thread or on
# three (the four models of three folds and the final one at once).
# (With --cells-csv, which must not change the training.)
"$tools/stemd-train" --out "$tmp/again.yaml" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --folds 3 --trees 20 "${small_forests[@]}" \
  --jobs 3 --cells-csv "$tmp/cells.csv" "$tmp/rec" >"$tmp/again.txt" 2>&1 || fail "second training: $(cat "$tmp/again.txt")"
# (Both forests: the plant forest's section runs on into the cell forest's.)
diff <(sed -n '/^forest:/,$p' "$tmp/model.yaml") <(sed -n '/^forest:/,$p' "$tmp/again.yaml") >/dev/null \
  || fail "training is not deterministic"
diff <(sed '$d' "$tmp/train.txt") <(sed '$d' "$tmp/again.txt") >/dev/null ||
  fail "the figures depend on the thread count: $(diff <(sed '$d' "$tmp/train.txt") <(sed '$d' "$tmp/again.txt"))"

# The cells' rows: a header naming every feature, one line per vegetated
# cell with as many fields, labelled pixels on some, folds 0-2, and as many
# cells as the model file says were labelled at least.
head -1 "$tmp/cells.csv" | grep -q '^frame,image,fold,cell,gx,gy,plant,crop_px,weed_px,cell_fill,cell_r_mean,.*,log_area_mm2,' ||
  fail "cells csv header: $(head -1 "$tmp/cells.csv")"
awk -F, 'NR == 1 { n = NF; next } NF != n { print "line " NR " has " NF " fields, the header " n; bad = 1 }
  $3 < 0 || $3 > 2 { print "line " NR ": fold " $3; bad = 1 }
  $8 + $9 > 0 { labelled++ }
  END { if (NR < 2 || labelled == 0) { print "no labelled cell"; bad = 1 } exit bad }' "$tmp/cells.csv" ||
  fail "cells csv rows"
# Frame i of the strip's n frames is in fold i mod 3; with --split blocks,
# in fold floor(3 i / n): runs of consecutive frames, the title saying so.
n=$(($(wc -l <"$tmp/rec/frames.csv") - 1))
awk -F, 'NR > 1 && $3 != $1 % 3 { print "line " NR ": frame " $1 " in fold " $3; bad = 1 } END { exit bad }' \
  "$tmp/cells.csv" || fail "interleaved folds"
"$tools/stemd-train" --out "$tmp/blocks.yaml" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --folds 3 --trees 20 "${small_forests[@]}" \
  --split blocks --cells-csv "$tmp/blocks.csv" "$tmp/rec" >"$tmp/blocks.txt" 2>&1 || fail "training in blocks: $(cat "$tmp/blocks.txt")"
grep -q '^3-fold cross-validation by frame (folds of consecutive frames)' "$tmp/blocks.txt" ||
  fail "the blocks' figures do not say so: $(head -3 "$tmp/blocks.txt")"
awk -F, -v n="$n" 'NR > 1 && $3 != int(3 * $1 / n) { print "line " NR ": frame " $1 " of " n " in fold " $3; bad = 1 }
  END { exit bad }' "$tmp/blocks.csv" || fail "folds of consecutive frames"
[ "$(awk -F, 'NR > 1 { print $3 }' "$tmp/blocks.csv" | sort -u | tr -d '\n')" = 012 ] || fail "blocks: not three folds"
if "$tools/stemd-train" --out "$tmp/x.yaml" --split random "$tmp/rec" >"$tmp/x.txt" 2>&1; then fail "--split random accepted"; fi
grep -q -- "--split" "$tmp/x.txt" || fail "--split random without naming the option: $(cat "$tmp/x.txt")"

labelled=$(sed -n 's/.* plants and \([0-9]*\) labelled cells from .*/\1/p' "$tmp/train.txt")
[ -n "$labelled" ] && [ "$(awk -F, 'NR > 1 && $8 + $9 > 0' "$tmp/cells.csv" | wc -l)" -eq "$labelled" ] ||
  fail "cells csv: not the $labelled labelled cells stemd-train counted"

"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --csv "$tmp/pred.csv" --class-out "$tmp/class" "$tmp/rec" >/dev/null 2>"$tmp/err.txt" \
  || fail "detect with a model exited $?: $(cat "$tmp/err.txt")"
[ "$(head -1 "$tmp/pred.csv")" = "image,plant,x,y,method,leaves,area_px,estimator,confidence,class,weed_probability" ] \
  || fail "csv header: $(head -1 "$tmp/pred.csv")"
[ "$(wc -l <"$tmp/pred.csv")" -gt 1 ] || fail "no plants"
# weed_probability is empty only for a plant no classified cell holds: unknown.
awk -F, 'NR > 1 && $11 == "" && $10 != "unknown" { print "bad row " NR ": " $0; bad = 1 }
  NR > 1 && $11 != "" && (($10 != "crop" && $10 != "weed" && $10 != "unknown") || $11 < 0 || $11 > 1 ||
  ($10 == "weed" && $11 < 0.85) || ($10 == "crop" && $11 > 0.4) || ($10 == "unknown" && ($11 >= 0.85 || $11 <= 0.4))) \
  { print "bad row " NR ": " $0; bad = 1 } END { exit bad }' "$tmp/pred.csv" || fail "class columns disagree with min_confidence 0.6, weed_confidence 0.85"
frames=$(($(wc -l <"$tmp/rec/frames.csv") - 1))
[ "$(ls "$tmp/class" | wc -l)" -eq "$frames" ] || fail "class maps: $(ls "$tmp/class" | wc -l) for $frames frames"
[ -s "$tmp/class/000000.png" ] || fail "class map not named like its input"

# min_confidence 1: no plant is sure enough, every one is unknown.
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set classify.min_confidence=1 --csv "$tmp/sure.csv" "$tmp/rec" >/dev/null 2>&1 || fail "min_confidence 1 run"
awk -F, 'NR > 1 && $10 != "unknown" && ($11 == "" || !($11 == 1 || $11 == 0)) { bad = 1 } END { exit bad }' "$tmp/sure.csv" \
  || fail "a plant below certainty was classed"

# A budget of one cell a frame: the report counts the cells left out, and
# only a plant the one cell holds whole can be classed (with at most one
# weed target from that cell): every other plant is unknown.
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set classify.max_cells=1 --csv "$tmp/budget.csv" "$tmp/rec" 2>"$tmp/budget.txt" >"$tmp/budget.out" || fail "max_cells 1 run"
grep -q "[0-9]* vegetated cells left unclassified (classify.max_cells 1)" "$tmp/budget.out" "$tmp/budget.txt" ||
  fail "no count of the cells left out: $(tail -2 "$tmp/budget.out")"
classed=$(awk -F, 'NR > 1 && $10 != "unknown"' "$tmp/budget.csv" | wc -l)
[ "$classed" -le $((2 * frames)) ] || fail "$classed plants classed with one cell a frame over $frames frames"
[ "$(awk -F, 'NR > 1 && $10 == "unknown"' "$tmp/budget.csv" | wc -l)" -gt 0 ] || fail "no plant unknown with one cell a frame"

# Refusals, each naming the model file.
set +e
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set camera.gsd_mm_per_px=0.5 "$tmp/rec" >/dev/null 2>"$tmp/gsd.txt"
rc=$?
set -e
[ $rc -eq 2 ] || fail "a model of another GSD: exit $rc"
grep -q "$tmp/model.yaml.*gsd" "$tmp/gsd.txt" || fail "GSD refusal: $(cat "$tmp/gsd.txt")"
set +e
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --segment exg_and_ndvi "$tmp/rec" >/dev/null 2>"$tmp/nir.txt"
rc=$?
set -e
[ $rc -eq 2 ] || fail "an rgb model on rgb+nir: exit $rc"
grep -q "$tmp/model.yaml.*rgb+nir" "$tmp/nir.txt" || fail "channel refusal: $(cat "$tmp/nir.txt")"
set +e
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --class-out "$tmp/none" "$tmp/rec" >/dev/null 2>"$tmp/nomodel.txt"
rc=$?
set -e
[ $rc -eq 2 ] || fail "--class-out without a model: exit $rc"
grep -q 'classify.model' "$tmp/nomodel.txt" || fail "no-model refusal: $(cat "$tmp/nomodel.txt")"

# Without a model the csv keeps its columns.
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --csv "$tmp/plain.csv" "$tmp/rec" >/dev/null 2>&1
[ "$(head -1 "$tmp/plain.csv")" = "image,plant,x,y,method,leaves,area_px,estimator,confidence" ] \
  || fail "csv header without a model: $(head -1 "$tmp/plain.csv")"

# A recording without a class column cannot train.
"$tools/stemd-synth" --out "$tmp/plain" --frames 3 --width 320 --height 240 >/dev/null
set +e
"$tools/stemd-train" --out "$tmp/no.yaml" "$tmp/plain" >/dev/null 2>"$tmp/noclass.txt"
rc=$?
set -e
[ $rc -eq 2 ] || fail "training without a class column: exit $rc"
grep -q 'no frame with a class image' "$tmp/noclass.txt" || fail "no-class refusal: $(cat "$tmp/noclass.txt")"
echo "classify_test: ok"
