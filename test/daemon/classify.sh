#!/usr/bin/env bash
# End to end with the crop/weed classifier and no class column: a model
# trained by stemd-train on one generated strip, the daemon replaying
# another strip whose frames.csv has no class column. scheduler.policy auto
# with a model treats weeds only: no TARGET may come near a crop (or any
# plant that is not a weed), every crop in the plant map is held back by
# policy, and with classify.min_confidence 1 the unsure plants are unknown
# and never commanded.
# Usage: classify.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

# The strips carry NIR; the classifier is tested on RGB, as before segment.method
# auto (which would take the NIR plane: bonirob_real.sh runs it).
synth_strip "$tmp/train" 3000 6
synth_strip "$tmp/strip" 2000
# Small forests (script.sh) and three folds: the daemon's use of a model.
"$tools/stemd-train" --out "$tmp/model.yaml" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg \
  --folds 3 --trees 30 "${small_forests[@]}" "$tmp/train" >"$tmp/train.txt" 2>&1 ||
  fail "stemd-train exited $?: $(cat "$tmp/train.txt")"
drop_class_column "$tmp/strip"

"$stemd" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" --replay "$tmp/strip" --once \
  --can-log "$tmp/can.log" --map "$tmp/map.jsonl" 2>"$tmp/err" || fail "stemd exited $?: $(tail -5 "$tmp/err")"
grep -q "classify.model $tmp/model.yaml" "$tmp/err" || fail "the model is not named at start"

# No command near anything but a weed (plants of every size), some weeds
# treated, and crops never sent.
score_weeds_only "$tmp/strip" "$tmp/can.log" "$tmp/map.jsonl" "$src/config/stemd.yaml"

# Weeds wider than a strike's reach get further targets: counted in the
# summary, and still no command near a plant that is no weed, no crop sent.
"$stemd" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set classify.weed_cover_radius_mm=2 --replay "$tmp/strip" --once --can-log "$tmp/cover.log" \
  --map "$tmp/cover.jsonl" 2>"$tmp/cover.err" || fail "stemd (cover) exited $?: $(tail -5 "$tmp/cover.err")"
cover=$(sed -n 's/.*total: .*weed targets: parts [0-9]*, stemless [0-9]*, cover \([0-9]*\).*/\1/p' "$tmp/cover.err")
[ -n "$cover" ] && [ "$cover" -gt 0 ] || fail "no further target on a wide weed: $(grep total: "$tmp/cover.err")"
grep -q "total: .*weed targets: parts [0-9]*, stemless [0-9]*, cover 0 |" "$tmp/err" || fail "cover without a radius: $(grep total: "$tmp/err")"
if grep '"class":"crop"' "$tmp/cover.jsonl" | grep -q '"reason":"sent"'; then fail "a crop was sent (cover)"; fi
sent_one=$(grep -c '"reason":"sent"' "$tmp/map.jsonl" || true)
sent_cover=$(grep -c '"reason":"sent"' "$tmp/cover.jsonl" || true)
[ "$sent_cover" -gt "$sent_one" ] || fail "no more targets sent with cover ($sent_cover) than without ($sent_one)"

# A budget of 100 cells a frame, below most frames' vegetated cells: the
# classifier leaves the rest out, counted in the summary, and what it could
# not see in whole is unknown and never commanded. The cells nearest the
# edge plants enter by go first, and the tracker fixes a plant's class on
# its first sightings there, so most weeds are still treated (the cells
# nearest the exit edge first treat about a quarter of them). Without a
# budget (the default) no frame of the strip is over.
grep -q "total: .*cells over budget 0 in 0 frames" "$tmp/err" || fail "cells over the default budget: $(grep total: "$tmp/err")"
"$stemd" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set classify.max_cells=100 --replay "$tmp/strip" --once --can-log "$tmp/budget.log" \
  --map "$tmp/budget.jsonl" 2>"$tmp/budget.err" || fail "stemd (max_cells 100) exited $?: $(tail -5 "$tmp/budget.err")"
over=$(sed -n 's/.*total: .*cells over budget \([0-9]*\) in [0-9]* frames.*/\1/p' "$tmp/budget.err")
[ -n "$over" ] && [ "$over" -gt 0 ] || fail "no cell over a budget of 100: $(grep total: "$tmp/budget.err")"
if grep '"reason":"sent"' "$tmp/budget.jsonl" | grep -vq '"class":"weed"'; then fail "a plant that is no weed was sent (budget)"; fi
"$tools/stemd-eval" --targets "$tmp/strip/plants.csv" "$tmp/budget.log" --config "$src/config/stemd.yaml" --treat weeds \
  --tol-mm 5 >"$tmp/budget.score" 2>&1 || true
matched_budget=$(sed -n 's/^matched *\([0-9]*\) plants.*/\1/p' "$tmp/budget.score")
[ -n "$matched_budget" ] && [ $((4 * matched_budget)) -ge $((3 * matched)) ] ||
  fail "a budget of 100 cells treated ${matched_budget:-no} weeds, under three quarters of $matched: $(cat "$tmp/budget.score")"

# Only certainty counts: below a weed probability of 1 a plant is unknown,
# and no unknown plant is commanded under auto.
"$stemd" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" \
  --set classify.min_confidence=1 --replay "$tmp/strip" --once --can-log "$tmp/unsure.log" \
  --map "$tmp/unsure.jsonl" 2>"$tmp/unsure.err" || fail "stemd (min_confidence 1) exited $?"
if grep '"class":"unknown"' "$tmp/unsure.jsonl" | grep -q '"reason":"sent"'; then fail "an unknown plant was sent"; fi
if grep '"reason":"sent"' "$tmp/unsure.jsonl" | grep -vq '"class":"weed"'; then fail "a plant that is no weed was sent"; fi
grep -q '"class":"unknown"' "$tmp/unsure.jsonl" || fail "no unknown plant in the map"

# A model for another GSD is refused at start, naming the file.
set +e
"$stemd" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg --set classify.model="$tmp/model.yaml" --set camera.gsd_mm_per_px=0.2 \
  --replay "$tmp/strip" --once --check-config >/dev/null 2>"$tmp/gsd.err"
rc=$?
set -e
[ $rc -eq 2 ] || fail "a model of another GSD: exit $rc"
grep -q "$tmp/model.yaml.*gsd" "$tmp/gsd.err" || fail "GSD refusal: $(cat "$tmp/gsd.err")"
echo "PASS: $matched weeds treated, no crop commanded; $cover further targets on wide weeds; $matched_budget with a budget of 100 cells ($over cells left out)"
