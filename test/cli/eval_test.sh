#!/usr/bin/env bash
# stemd-eval as a user scripts it: exact JSON numbers on hand-made stem CSVs
# and masks, exit code 2 with one clear stderr line on bad input.
#   bash eval_test.sh <dir-of-tools-binaries> <source-dir>
set -euo pipefail

eval_bin="$1/stemd-eval"
[ -x "$eval_bin" ] || { echo "FAIL: $eval_bin is not an executable" >&2; exit 1; }
. "$(dirname "$0")/../support/script.sh"

# expect_json EXPECTED ARGS...: exit 0 and stdout exactly the one line EXPECTED.
expect_json() {
  local expected=$1
  shift
  local rc=0
  "$eval_bin" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?
  [ "$rc" -eq 0 ] || fail "stemd-eval $*: exit $rc: $(cat "$tmp/err")"
  [ "$(wc -l <"$tmp/out")" -eq 1 ] || fail "stemd-eval $*: not exactly one line: $(cat "$tmp/out")"
  [ "$(cat "$tmp/out")" = "$expected" ] || fail "stemd-eval $*:
  got      $(cat "$tmp/out")
  expected $expected"
}

# expect_error MESSAGE ARGS...: exit 2, nothing on stdout, exactly the one line MESSAGE on stderr.
expect_error() {
  local message=$1
  shift
  local rc=0
  "$eval_bin" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?
  [ "$rc" -eq 2 ] || fail "stemd-eval $*: exit $rc, expected 2"
  [ ! -s "$tmp/out" ] || fail "stemd-eval $*: unexpected stdout: $(cat "$tmp/out")"
  [ "$(cat "$tmp/err")" = "$message" ] || fail "stemd-eval $*:
  got      $(cat "$tmp/err")
  expected $message"
}

# --- stem matching -------------------------------------------------------------
# At 0.5 mm/px and 5 mm (10 px):
#   a.png (100,100)-(103,104): 5 px = 2.5 mm, match
#   a.png (200,200)-(200,206): 6 px = 3 mm, match
#   a.png (300,300) missed, prediction (400,400) false
#   b.png (50,50)-(50,62): 12 px = 6 mm, too far; (80,80) missed
#   c.png only in GT: missed; d.png only in PRED: false
# GT 6, PRED 5, TP 2: precision 2/5, recall 2/6, F1 2*2/(6+5) = 4/11, mean (2.5+3)/2.
cat >"$tmp/stems.csv" <<'EOF'
image,x,y,kind,leaves
a.png,100,100,crop,4
a.png,200,200,weed,2
a.png,300,300,crop,3
b.png,50,50,crop,2
b.png,80,80,weed,1
c.png,10,10,weed,1
EOF
cat >"$tmp/pred.csv" <<'EOF'
image,plant,x,y,method,leaves,area_px
a.png,0,103.000,104.000,leaves,4,1500
a.png,1,200.000,206.000,centre,0,300
a.png,2,400.000,400.000,leaves,3,900
b.png,0,50.000,62.000,leaves,2,700
d.png,0,1.000,1.000,centre,0,50
EOF

expect_json '{"ground_truth":6,"predictions":5,"true_positives":2,"precision":0.4,"recall":0.3333333333333333,"f1":0.36363636363636365,"mean_error_mm":2.75,"tol_mm":5,"gsd_mm_per_px":0.5}' \
  "$tmp/stems.csv" "$tmp/pred.csv" --gsd-mm-per-px 0.5 --json

# 2.5 mm: the 2.5 mm pair is exactly at the tolerance (inside), the 3 mm one is not.
# TP 1: precision 1/5, recall 1/6, F1 2/11.
expect_json '{"ground_truth":6,"predictions":5,"true_positives":1,"precision":0.2,"recall":0.16666666666666666,"f1":0.18181818181818182,"mean_error_mm":2.5,"tol_mm":2.5,"gsd_mm_per_px":0.5}' \
  --json --tol-mm 2.5 "$tmp/stems.csv" --gsd-mm-per-px 0.5 "$tmp/pred.csv"

# Defaults 5 mm at 0.33 mm/px (15.15 px): the 12 px pair in b.png matches too.
# TP 3: precision 3/5, recall 3/6, F1 6/11, mean (5+6+12)*0.33/3 mm.
expect_json '{"ground_truth":6,"predictions":5,"true_positives":3,"precision":0.6,"recall":0.5,"f1":0.5454545454545454,"mean_error_mm":2.53,"tol_mm":5,"gsd_mm_per_px":0.33}' \
  "$tmp/stems.csv" "$tmp/pred.csv" --json

# No predictions at all: every ratio is 0, no NaN.
echo "image,plant,x,y,method,leaves,area_px" >"$tmp/empty.csv"
expect_json '{"ground_truth":6,"predictions":0,"true_positives":0,"precision":0,"recall":0,"f1":0,"mean_error_mm":0,"tol_mm":5,"gsd_mm_per_px":0.33}' \
  "$tmp/stems.csv" "$tmp/empty.csv" --json

# The text summary.
"$eval_bin" "$tmp/stems.csv" "$tmp/pred.csv" --gsd-mm-per-px 0.5 >"$tmp/out"
for line in "ground truth    6 stems" "predictions     5 stems" "true positives  2" "precision       40.0 %" \
  "recall          33.3 %" "F1              36.4 %" "mean error      2.75 mm over 2 matches" \
  "tolerance       5 mm = 10.0 px at 0.5 mm/px"; do
  grep -qxF "$line" "$tmp/out" || fail "summary lacks '$line':
$(cat "$tmp/out")"
done
if grep -qi nan "$tmp/out"; then fail "NaN in summary"; fi

# --- errors ----------------------------------------------------------------------
expect_error "stemd-eval: $tmp/missing.csv: cannot open: No such file or directory (errno 2)" "$tmp/stems.csv" "$tmp/missing.csv"
expect_error "stemd-eval: $tmp/missing.csv: cannot open: No such file or directory (errno 2)" "$tmp/missing.csv" "$tmp/pred.csv" --json
for bad in 0 -1 abc nan inf 5mm ""; do
  expect_error "stemd-eval: --tol-mm: '$bad' is not a number > 0 (see stemd-eval --help)" \
    "$tmp/stems.csv" "$tmp/pred.csv" --tol-mm "$bad"
done
expect_error "stemd-eval: --gsd-mm-per-px: '0' is not a number > 0 (see stemd-eval --help)" \
  "$tmp/stems.csv" "$tmp/pred.csv" --gsd-mm-per-px 0
expect_error "stemd-eval: --tol-mm needs a value (see stemd-eval --help)" "$tmp/stems.csv" "$tmp/pred.csv" --tol-mm
expect_error "stemd-eval: unknown option --tolerance (see stemd-eval --help)" \
  "$tmp/stems.csv" "$tmp/pred.csv" --tolerance 5
expect_error "stemd-eval: stem matching takes 2 operands (GT.csv PRED.csv), got 1 (see stemd-eval --help)" \
  "$tmp/stems.csv"
printf 'image,x,y\na.png,1,2\na.png,oops,2\n' >"$tmp/bad.csv"
expect_error "stemd-eval: $tmp/bad.csv:3: x 'oops' is not a finite number" "$tmp/stems.csv" "$tmp/bad.csv"
printf 'image,plant,x\na.png,0,1\n' >"$tmp/nocol.csv"
expect_error "stemd-eval: $tmp/nocol.csv: header has no column 'y' (columns: image,plant,x)" \
  "$tmp/nocol.csv" "$tmp/pred.csv"

"$eval_bin" --help >"$tmp/out" || fail "--help: exit $?"
grep -q "^usage: stemd-eval" "$tmp/out" || fail "--help prints no usage"

# --- mask IoU ----------------------------------------------------------------------
# 4x2 binary PGMs (OpenCV reads the format from the content, so a PGM may be
# named .png like the masks stemd-detect --mask-out writes).
pgm() { # FILE ROW-BYTES (the same row twice)
  printf "P5\n4 2\n255\n$2$2" >"$1"
}
mkdir -p "$tmp/rec/mask" "$tmp/pred"
cat >"$tmp/rec/frames.csv" <<'EOF'
t_ns,rgb,nir,mask
0,rgb/f0.jpg,,mask/f0.pgm
1,rgb/f1.png,,mask/f1.pgm
2,rgb/f2.png,,
EOF
# f0: prediction columns 0-1, truth columns 1-2: intersection 2, union 6, IoU 1/3.
pgm "$tmp/pred/f0.png" '\xff\xff\x00\x00'
pgm "$tmp/rec/mask/f0.pgm" '\x00\xff\xff\x00'
# f1: identical: IoU 1. f2 has no mask and is skipped.
pgm "$tmp/pred/f1.png" '\x00\x00\x07\xff'
pgm "$tmp/rec/mask/f1.pgm" '\x00\x00\x01\x01'

expect_json '{"frames":2,"mean_iou":0.6666666666666666,"min_iou":0.3333333333333333}' \
  --iou "$tmp/pred" "$tmp/rec" --json
# Zero = vegetation in the truth: f0 truth columns 0,3 (IoU 2/6), f1 truth columns 0-1 (IoU 0).
expect_json '{"frames":2,"mean_iou":0.16666666666666666,"min_iou":0}' \
  --iou "$tmp/pred" "$tmp/rec" --gt-vegetation zero --json

"$eval_bin" --iou "$tmp/pred" "$tmp/rec" >"$tmp/out" || fail "--iou text: exit $?"
grep -qxF "rgb/f0.jpg  IoU 0.3333  (intersection 2 px, union 6 px)" "$tmp/out" || fail "--iou f0 line: $(cat "$tmp/out")"
grep -qxF "rgb/f1.png  IoU 1.0000  (intersection 4 px, union 4 px)" "$tmp/out" || fail "--iou f1 line: $(cat "$tmp/out")"
grep -qxF "mean IoU 0.6667 over 2 frames (min 0.3333: rgb/f0.jpg)" "$tmp/out" || fail "--iou mean line: $(cat "$tmp/out")"

expect_error "stemd-eval: --gt-vegetation: 'soil' is neither nonzero nor zero (see stemd-eval --help)" \
  --iou "$tmp/pred" "$tmp/rec" --gt-vegetation soil
expect_error "stemd-eval: --tol-mm does not apply to --iou (see stemd-eval --help)" \
  --iou "$tmp/pred" "$tmp/rec" --tol-mm 5
rm "$tmp/pred/f1.png"
expect_error "stemd-eval: prediction $tmp/pred/f1.png: cannot open: No such file or directory (errno 2)" --iou "$tmp/pred" "$tmp/rec"
echo "not an image" >"$tmp/pred/f1.png"
expect_error "stemd-eval: prediction $tmp/pred/f1.png: cannot decode: not a PNG, JPEG, BMP or PNM image" \
  --iou "$tmp/pred" "$tmp/rec"

# --- class maps --------------------------------------------------------------------
# Each frame is two equal rows. Truth f0: crop crop weed weed; its map: crop weed
# weed soil. Truth f1: crop soil crop crop; its map: crop crop soil crop. Pooled:
# crop 6 of 10 right (2 called weed, 2 soil), weed 2 of 4 (2 soil): balanced
# accuracy (0.6 + 0.5) / 2; 4 of the 14 annotated pixels soil. f0 0.5, f1 4/6.
mkdir -p "$tmp/crec/class" "$tmp/cpred"
cat >"$tmp/crec/frames.csv" <<'EOF'
t_ns,rgb,nir,mask,class
0,rgb/f0.png,,,class/f0.pgm
1,rgb/f1.png,,,class/f1.pgm
2,rgb/f2.png,,,
EOF
pgm "$tmp/crec/class/f0.pgm" '\x01\x01\x02\x02'
pgm "$tmp/cpred/f0.png" '\x01\x02\x02\x00'
pgm "$tmp/crec/class/f1.pgm" '\x01\x00\x01\x01'
pgm "$tmp/cpred/f1.png" '\x01\x01\x00\x01'
expect_json '{"frames":2,"crop_px":10,"weed_px":4,"crop_recall":0.6,"weed_recall":0.5,"balanced_accuracy":0.55,"crop_as_weed":0.2,"weed_as_crop":0,"not_segmented":0.2857142857142857,"min_frame_balanced_accuracy":0.5}' \
  --classes "$tmp/cpred" "$tmp/crec" --json
"$eval_bin" --classes "$tmp/cpred" "$tmp/crec" >"$tmp/out" || fail "--classes text: exit $?"
grep -qxF "rgb/f0.png  balanced accuracy 0.5000  (crop 2 of 4 px, weed 2 of 4 px)" "$tmp/out" \
  || fail "--classes f0 line: $(cat "$tmp/out")"
grep -qxF "balanced accuracy 0.5500 over 2 frames, every pixel together (min frame 0.5000: rgb/f0.png)" "$tmp/out" \
  || fail "--classes summary line: $(cat "$tmp/out")"
expect_error "stemd-eval: --gt-vegetation does not apply to --classes (see stemd-eval --help)" \
  --classes "$tmp/cpred" "$tmp/crec" --gt-vegetation zero
pgm "$tmp/cpred/f1.png" '\x01\x01\x03\x01'
expect_error "stemd-eval: $tmp/cpred/f1.png vs $tmp/crec/class/f1.pgm: predicted class map holds 3 at (2, 0): not 0 soil, 1 crop or 2 weed" \
  --classes "$tmp/cpred" "$tmp/crec"
expect_error "stemd-eval: $tmp/rec/frames.csv: no frame has a class path, nothing to evaluate" \
  --classes "$tmp/cpred" "$tmp/rec"

echo "eval_test: all passed"
