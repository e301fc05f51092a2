#!/usr/bin/env bash
# The crop/weed classifier on the real shared sets (../shared/data, or
# $STEMD_REAL_DATA): stemd-train's cross-validation by frame on carrot-dev
# and cwfid-train must do clearly better than chance per plant (mean of crop
# and weed recall above 0.7; always saying weed gives 0.5), and a higher
# classify.min_confidence must never call more crop plants weed. Skipped
# (exit 77) when the data is absent, as on a user's machine.
#   classify_real_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1 src=$2
data=${STEMD_REAL_DATA:-$src/../shared/data}
if [ ! -f "$data/carrot-dev/frames.csv" ] || [ ! -d "$data/cwfid-train/annotations" ]; then
  echo "SKIP: real data sets carrot-dev/ and cwfid-train/ absent under $data (set STEMD_REAL_DATA)"
  exit 77
fi
. "$(dirname "$0")/../support/script.sh"

STEMD_CLASSMAP="$tools/stemd-classmap" "$src/tools/cwfid-recording.sh" "$data/cwfid-train" "$tmp/cwfid" >/dev/null
head -1 "$tmp/cwfid/frames.csv" | grep -q ',class$' || fail "cwfid-recording.sh wrote no class column"

check() {   # name, output of stemd-train
  local name=$1 out=$2
  # The two recalls of each block: 0.5, then classify.min_confidence.
  local recalls
  recalls=$(sed -n 's/^  crop: precision [0-9.]* recall \([0-9.]*\) | weed: precision [0-9.]* recall \([0-9.]*\).*/\1 \2/p' "$out")
  [ "$(wc -l <<<"$recalls")" -eq 2 ] || fail "$name: no cross-validation figures: $(cat "$out")"
  local first
  first=$(head -1 <<<"$recalls")
  awk -v r="$first" 'BEGIN { split(r, a, " "); exit !((a[1] + a[2]) / 2 > 0.7) }' ||
    fail "$name: per-plant balanced accuracy of recalls $first not above 0.7"
  local safety
  safety=$(sed -n 's/^  crop safety: \([0-9]*\) of .*/\1/p' "$out")
  [ "$(sed -n 2p <<<"$safety")" -le "$(sed -n 1p <<<"$safety")" ] ||
    fail "$name: more crop plants called weed at the higher min_confidence: $safety"
  echo "$name: recalls (crop weed) $first; crop plants called weed $(tr '\n' ' ' <<<"$safety")"
}

"$tools/stemd-train" --out "$tmp/carrot.yaml" --set camera.gsd_mm_per_px=0.25 "$data/carrot-dev" \
  >"$tmp/carrot.txt" 2>&1 || fail "stemd-train carrot-dev exited $?: $(cat "$tmp/carrot.txt")"
check carrot-dev "$tmp/carrot.txt"
"$tools/stemd-train" --out "$tmp/cwfid.yaml" --set camera.gsd_mm_per_px=0.11 "$tmp/cwfid" \
  >"$tmp/cwfid.txt" 2>&1 || fail "stemd-train cwfid-train exited $?: $(cat "$tmp/cwfid.txt")"
check cwfid-train "$tmp/cwfid.txt"
