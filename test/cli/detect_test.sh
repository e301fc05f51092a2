#!/usr/bin/env bash
# stemd-detect as a user scripts it: a generated recording, every output
# option, the three segmentations, bad configuration and a corrupt frame.
#   detect_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1 src=$2
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 --seed 11 >/dev/null

# All outputs from one run.
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --csv "$tmp/pred.csv" --mask-out "$tmp/masks" \
  --overlay "$tmp/overlays" --timing "$tmp/rec" >"$tmp/out.txt" 2>"$tmp/err.txt" || fail "detect exited $?"
# The required columns, then the estimator and its confidence.
[ "$(head -1 "$tmp/pred.csv")" = "image,plant,x,y,method,leaves,area_px,estimator,confidence" ] \
  || fail "csv header: $(head -1 "$tmp/pred.csv")"
rows=$(($(wc -l <"$tmp/pred.csv") - 1))
reported=$(sed -n 's/^3 frames, \([0-9]*\) stems, [0-9]* stemless plants, 0 plants over capacity (256 a frame)$/\1/p' "$tmp/out.txt")
[ -n "$reported" ] && [ "$rows" -eq "$reported" ] || fail "csv has $rows rows, summary says '$reported'"
[ "$rows" -gt 0 ] || fail "no plants found"
# Image names as written in frames.csv; methods only leaves|com; x,y numbers.
awk -F, 'NR > 1 && ($1 !~ /^rgb\/00000[0-2]\.png$/ || ($5 != "leaves" && $5 != "com") || $3 !~ /^[0-9.]+$/ ||
  ($8 != "robust" && $8 != "paper" && $8 != "com") || $9 < 0 || $9 > 1) \
  { print "bad row " NR ": " $0; bad = 1 } END { exit bad }' "$tmp/pred.csv" || fail "malformed csv rows"
for f in 000000 000001 000002; do
  [ -s "$tmp/masks/$f.png" ] || fail "no mask $f"
  [ -s "$tmp/overlays/$f.png" ] || fail "no overlay $f"
done
grep -q '^timing median over 3 frames: index' "$tmp/err.txt" || fail "no timing summary"
# exg_and_ndvi computes its indices on every pixel: no tiles to report.
! grep -q 'index tiles computed' "$tmp/err.txt" || fail "tiles reported without the sparse index"
# The RGB index is sparse: each frame says how many of its 21 x 16 tiles
# (64 px) it computed in full, at least the one a plant stands in.
"$tools/stemd-detect" --segment chromatic_exg --timing "$tmp/rec" >/dev/null 2>"$tmp/tiles.txt" ||
  fail "chromatic_exg --timing exited $?"
computed=$(sed -n 's/^timing .*: index [0-9.]* .* total [0-9.]* ms, index tiles computed \([0-9]*\) of 336$/\1/p' "$tmp/tiles.txt")
[ "$(echo "$computed" | grep -c .)" -eq 3 ] || fail "tiles per frame: $(grep '^timing' "$tmp/tiles.txt")"
for c in $computed; do
  [ "$c" -ge 1 ] && [ "$c" -le 336 ] || fail "tiles computed $c of 336"
done
grep -q '^timing median over 3 frames: index tiles computed [0-9.]* %$' "$tmp/tiles.txt" ||
  fail "no tiles summary: $(grep median "$tmp/tiles.txt")"
# The shipped segment.method auto takes the nir column every frame has.
grep -qx 'stemd-detect: segment.method auto: exg_and_ndvi (every frame has a nir image)' "$tmp/err.txt" ||
  fail "auto's choice with nir: $(grep segment "$tmp/err.txt")"

# The detections are good enough to be scored.
recall=$("$tools/stemd-eval" "$tmp/rec/stems.csv" "$tmp/pred.csv" --json | sed 's/.*"recall":\([0-9.]*\).*/\1/')
awk -v r="$recall" 'BEGIN { exit !(r >= 0.5) }' || fail "recall $recall below 0.5"

# NDVI from the nir column, and the true masks through --segment mask.
"$tools/stemd-detect" --segment ndvi --csv "$tmp/ndvi.csv" "$tmp/rec" >/dev/null || fail "ndvi run"
[ "$(wc -l <"$tmp/ndvi.csv")" -gt 1 ] || fail "ndvi found nothing"
"$tools/stemd-detect" --segment mask --csv "$tmp/mask.csv" "$tmp/rec" >/dev/null || fail "mask run"
[ "$(wc -l <"$tmp/mask.csv")" -gt 1 ] || fail "mask found nothing"

# A single image argument is named by its basename.
"$tools/stemd-detect" --csv - "$tmp/rec/rgb/000001.png" 2>/dev/null >"$tmp/single.csv" || fail "single image"
sed -n 2p "$tmp/single.csv" | grep -q '^000001\.png,0,' || fail "single image row: $(sed -n 2p "$tmp/single.csv")"
# An image file has no nir plane: auto runs chromatic_exg, the same rows.
"$tools/stemd-detect" --csv "$tmp/single_auto.csv" "$tmp/rec/rgb/000001.png" >/dev/null 2>"$tmp/single.err" ||
  fail "single image, auto"
grep -qx 'stemd-detect: segment.method auto: chromatic_exg (not every frame has a nir image)' "$tmp/single.err" ||
  fail "auto's choice without nir: $(cat "$tmp/single.err")"
"$tools/stemd-detect" --segment chromatic_exg --csv "$tmp/single_rgb.csv" "$tmp/rec/rgb/000001.png" >/dev/null 2>&1 ||
  fail "single image, chromatic_exg"
cmp -s "$tmp/single_auto.csv" "$tmp/single_rgb.csv" || fail "auto without nir is not chromatic_exg"

# --set overrides; a bad key or value is one line naming it, exit 2.
"$tools/stemd-detect" --set closing.radius_px=6 --csv "$tmp/m6.csv" "$tmp/rec" >/dev/null || fail "--set run"
set +e
"$tools/stemd-detect" --set closing.radius_pz=6 "$tmp/rec" >/dev/null 2>"$tmp/e1"; rc=$?
set -e
[ $rc -eq 2 ] || fail "bad key exited $rc"
grep -q "key 'closing.radius_pz'" "$tmp/e1" || fail "bad key message: $(cat "$tmp/e1")"
[ "$(wc -l <"$tmp/e1")" -eq 1 ] || fail "bad key message is not one line"

printf 'closing:\n  radius_px: 10\nstem:\n  min_leaves: 99\n' >"$tmp/bad.yaml"
set +e
"$tools/stemd-detect" --config "$tmp/bad.yaml" "$tmp/rec" >/dev/null 2>"$tmp/e2"; rc=$?
set -e
[ $rc -eq 2 ] || fail "bad config exited $rc"
grep -q "^stemd-detect: $tmp/bad.yaml:4: key 'stem.min_leaves': " "$tmp/e2" || fail "bad config message: $(cat "$tmp/e2")"

# A corrupt frame is reported, skipped and counted; the others are processed.
cp -r "$tmp/rec" "$tmp/broken"
echo "not a png" >"$tmp/broken/rgb/000001.png"
set +e
"$tools/stemd-detect" --csv "$tmp/broken.csv" "$tmp/broken" >"$tmp/b.out" 2>"$tmp/b.err"; rc=$?
set -e
[ $rc -eq 1 ] || fail "corrupt frame exited $rc"
grep -q "skipped frame: .*000001.png" "$tmp/b.err" || fail "no skip message: $(cat "$tmp/b.err")"
grep -q "^2 frames, .* plants over capacity (256 a frame), 1 frames skipped$" "$tmp/b.out" || fail "summary: $(tail -1 "$tmp/b.out")"
! grep -q "000001.png" "$tmp/broken.csv" || fail "corrupt frame has rows"
grep -q "000002.png" "$tmp/broken.csv" || fail "frame after the corrupt one missing"

# Usage errors.
set +e
"$tools/stemd-detect" >/dev/null 2>&1; rc1=$?
"$tools/stemd-detect" --segment ndvi "$tmp/rec/rgb/000001.png" >/dev/null 2>&1; rc2=$?
"$tools/stemd-detect" --csv - --bogus "$tmp/rec" >/dev/null 2>"$tmp/e3"; rc3=$?
"$tools/stemd-detect" "$tmp/rec" --csv >/dev/null 2>"$tmp/e4"; rc4=$?
set -e
[ $rc1 -eq 2 ] && [ $rc2 -eq 2 ] || fail "usage errors exited $rc1 $rc2"
[ $rc3 -eq 2 ] && grep -q "^stemd-detect: unknown option --bogus$" "$tmp/e3" || fail "unknown option: $rc3 $(cat "$tmp/e3")"
[ $rc4 -eq 2 ] && grep -q "^stemd-detect: --csv needs a value$" "$tmp/e4" || fail "missing value: $rc4 $(cat "$tmp/e4")"
# --segment and --set take effect in the order given: the last method wins
# (ndvi needs a nir plane, which a lone rgb image has not).
"$tools/stemd-detect" --segment ndvi --set segment.method=chromatic_exg "$tmp/rec/rgb/000001.png" >/dev/null 2>&1 ||
  fail "--set after --segment did not win"
rc5=0
"$tools/stemd-detect" --set segment.method=chromatic_exg --segment ndvi "$tmp/rec/rgb/000001.png" >/dev/null 2>&1 || rc5=$?
[ $rc5 -ne 0 ] || fail "--segment after --set did not win"
echo "detect_test: ok ($rows plants)"
