#!/usr/bin/env bash
# tools/perturb-recording.py on a generated recording: exposure and gains
# scale each channel (nir by the exposure alone), vignetting darkens the
# corners to the asked share and leaves the centre, motion blur runs along
# the columns only, YUYV shares colour between horizontal pairs, JPEG
# stays near its input, noise is reproducible for
# a seed, masks stay where they were, the copy is a recording stemd-detect
# reads, and bad arguments exit 2 naming the option.
#   perturb_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
source_dir=$2
. "$(dirname "$0")/../support/script.sh"
/usr/bin/python3 -c 'import cv2, numpy' 2>/dev/null ||
  { echo "SKIP: python3-opencv and python3-numpy (tools/perturb-recording.py) are not installed"; exit 77; }
perturb=$source_dir/tools/perturb-recording.py

"$tools/stemd-synth" --out "$tmp/rec" --preset seedling --frames 2 --seed 3 >/dev/null
head -1 "$tmp/rec/frames.csv" | grep -q nir || fail "the synthetic recording has no nir column"

"$perturb" "$tmp/rec" "$tmp/dark" --exposure 0.5 --gains 1,1,2 >/dev/null || fail "perturb exited $?"
/usr/bin/python3 - "$tmp/rec" "$tmp/dark" <<'PY' || fail "exposure and gains"
import csv, os, sys
import cv2, numpy as np
src, dst = sys.argv[1:]
a = list(csv.DictReader(open(os.path.join(src, "frames.csv"))))
b = list(csv.DictReader(open(os.path.join(dst, "frames.csv"))))
assert len(a) == len(b) == 2, (len(a), len(b))
def path(d, p): return p if os.path.isabs(p) else os.path.join(d, p)
for ra, rb in zip(a, b):
    assert ra["t_ns"] == rb["t_ns"]
    rgb, out = (cv2.imread(path(d, r["rgb"])).astype(np.float64) for d, r in ((src, ra), (dst, rb)))
    # B and G halved, R (gain 2) as it was, each rounded to 8 bits.
    expected = np.clip(np.rint(rgb * np.array([0.5, 0.5, 1.0])), 0, 255)
    assert np.abs(out - expected).max() <= 0.5, np.abs(out - expected).max()
    nir, nir_out = (cv2.imread(path(d, r["nir"]), 0).astype(np.float64) for d, r in ((src, ra), (dst, rb)))
    assert np.abs(nir_out - np.rint(nir * 0.5)).max() <= 0.5
    if ra.get("mask"):
        assert os.path.samefile(path(src, ra["mask"]), rb["mask"]), (ra["mask"], rb["mask"])
PY

"$perturb" "$tmp/rec" "$tmp/vignetted" --vignetting 0.25 >/dev/null || fail "perturb --vignetting exited $?"
/usr/bin/python3 - "$tmp/rec" "$tmp/vignetted" <<'PY' || fail "vignetting"
import csv, os, sys
import cv2, numpy as np
src, dst = sys.argv[1:]
ra = next(csv.DictReader(open(os.path.join(src, "frames.csv"))))
rb = next(csv.DictReader(open(os.path.join(dst, "frames.csv"))))
def path(d, p): return p if os.path.isabs(p) else os.path.join(d, p)
for column, flags in (("rgb", cv2.IMREAD_COLOR), ("nir", cv2.IMREAD_GRAYSCALE)):
    a = cv2.imread(path(src, ra[column]), flags).astype(np.float64)
    b = cv2.imread(path(dst, rb[column]), flags).astype(np.float64)
    h, w = a.shape[:2]
    # The corners get a quarter of the light, each value rounded to 8 bits.
    for y, x in ((0, 0), (0, w - 1), (h - 1, 0), (h - 1, w - 1)):
        assert np.abs(b[y, x] - a[y, x] * 0.25).max() <= 0.501, (column, y, x, a[y, x], b[y, x])
    # The centre keeps its light; halfway to a corner, cos^4 gives
    # 1 / (1 + a / 4)^2 with (1 + a)^2 = 4: a = 1, so 0.64.
    assert np.abs(b[h // 2, w // 2] - a[h // 2, w // 2]).max() <= 1, column
    ys, xs = (h - 1) // 4, (w - 1) // 4
    bright = a[ys - 2:ys + 3, xs - 2:xs + 3].sum()
    assert bright > 0
    share = b[ys - 2:ys + 3, xs - 2:xs + 3].sum() / bright
    assert 0.6 < share < 0.68, (column, share)
PY

# Stripes: columns of alternating colour (constant down each column) and
# rows of alternating brightness (constant along each row).
/usr/bin/python3 - "$tmp/stripes" <<'PY' || fail "writing the stripes"
import os, sys
import cv2, numpy as np
d = sys.argv[1]
os.makedirs(d)
columns = np.zeros((32, 64, 3), np.uint8)
columns[:, 0::2] = (30, 160, 60)    # green leaf
columns[:, 1::2] = (40, 70, 120)    # reddish soil
rows = np.zeros((32, 64, 3), np.uint8)
rows[0::2] = 50
rows[1::2] = 150
cv2.imwrite(os.path.join(d, "columns.png"), columns)
cv2.imwrite(os.path.join(d, "rows.png"), rows)
open(os.path.join(d, "frames.csv"), "w").write("t_ns,rgb\n0,columns.png\n1,rows.png\n")
PY
"$perturb" "$tmp/stripes" "$tmp/blurred" --motion-blur-px 5 >/dev/null || fail "perturb --motion-blur-px exited $?"
"$perturb" "$tmp/stripes" "$tmp/yuyv" --yuyv >/dev/null || fail "perturb --yuyv exited $?"
"$perturb" "$tmp/rec" "$tmp/jpeg" --jpeg-quality 50 >/dev/null || fail "perturb --jpeg-quality exited $?"
/usr/bin/python3 - "$tmp" <<'PY' || fail "motion blur, YUYV, JPEG"
import csv, os, sys
import cv2, numpy as np
t = sys.argv[1]
def image(d, name): return cv2.imread(os.path.join(t, d, name)).astype(np.float64)
# Travel runs down the columns: a pattern constant down them is kept, one
# that alternates down them is averaged to its mean (5 rows: 3 of one, 2
# of the other, so within 20 DN of 100).
assert np.array_equal(image("blurred", "columns.png"), image("stripes", "columns.png"))
middle = image("blurred", "rows.png")[4:-4]
assert np.abs(middle - 100).max() <= 20, np.abs(middle - 100).max()
# YUYV: each horizontal pair shares its colour, so the leaf and soil
# columns come out with nearly the same hue; a flat field keeps its values.
yuyv = image("yuyv", "columns.png")
colour = yuyv[..., 1] - yuyv[..., 2]                 # G - R
stripes = image("stripes", "columns.png")
assert np.abs(colour[:, 0::2] - colour[:, 1::2]).max() < 0.2 * np.abs(stripes[:, 0::2, 1] - stripes[:, 0::2, 2] - (stripes[:, 1::2, 1] - stripes[:, 1::2, 2])).min()
assert np.abs(image("yuyv", "rows.png") - image("stripes", "rows.png")).max() <= 1
# JPEG at quality 50 changes a field frame's values but keeps the picture.
ra = next(csv.DictReader(open(os.path.join(t, "rec", "frames.csv"))))
rb = next(csv.DictReader(open(os.path.join(t, "jpeg", "frames.csv"))))
source = cv2.imread(ra["rgb"] if os.path.isabs(ra["rgb"]) else os.path.join(t, "rec", ra["rgb"])).astype(np.float64)
jpeg = image("jpeg", rb["rgb"])
assert 0 < np.abs(jpeg - source).mean() < 8, np.abs(jpeg - source).mean()
PY

"$perturb" "$tmp/rec" "$tmp/noisy1" --noise-dn 3 --seed 4 >/dev/null
"$perturb" "$tmp/rec" "$tmp/noisy2" --noise-dn 3 --seed 4 >/dev/null
first=$(head -2 "$tmp/rec/frames.csv" | tail -1 | cut -d, -f2)
first=$(basename "${first%.*}").png
cmp -s "$tmp/noisy1/$first" "$tmp/noisy2/$first" || fail "the same seed gave other noise"
/usr/bin/python3 - "$tmp/rec" "$tmp/noisy1" <<'PY' || fail "noise of 3 DN"
import csv, os, sys
import cv2, numpy as np
src, dst = sys.argv[1:]
ra = next(csv.DictReader(open(os.path.join(src, "frames.csv"))))
rb = next(csv.DictReader(open(os.path.join(dst, "frames.csv"))))
a = cv2.imread(ra["rgb"] if os.path.isabs(ra["rgb"]) else os.path.join(src, ra["rgb"])).astype(np.float64)
b = cv2.imread(os.path.join(dst, rb["rgb"])).astype(np.float64)
inside = (a > 20) & (a < 235)   # away from saturation, where clipping would bias the spread
spread = (b - a)[inside].std()
assert 2.7 < spread < 3.3, spread
PY

"$tools/stemd-detect" "$tmp/dark" --csv "$tmp/dark.csv" >/dev/null 2>&1 || fail "stemd-detect on the copy exited $?"
[ "$(wc -l <"$tmp/dark.csv")" -gt 1 ] || fail "no stems on the darker copy"

set +e
"$perturb" "$tmp/rec" "$tmp/bad" --gains 1,2 >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -eq 2 ] && grep -q -- "--gains" "$tmp/err" || fail "bad --gains: rc $rc, $(cat "$tmp/err")"
set +e
"$perturb" "$tmp/rec" "$tmp/bad" --vignetting 0 >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -eq 2 ] && grep -q -- "--vignetting" "$tmp/err" || fail "bad --vignetting: rc $rc, $(cat "$tmp/err")"
for bad in "--motion-blur-px 0" "--jpeg-quality 101"; do
  set +e
  # shellcheck disable=SC2086  # the option and its value, split on purpose
  "$perturb" "$tmp/rec" "$tmp/bad" $bad >/dev/null 2>"$tmp/err"; rc=$?
  set -e
  [ $rc -eq 2 ] && grep -q -- "${bad% *}" "$tmp/err" || fail "bad $bad: rc $rc, $(cat "$tmp/err")"
done
set +e
"$perturb" "$tmp/missing" "$tmp/bad" >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -ne 0 ] && grep -q "frames.csv" "$tmp/err" || fail "missing recording: rc $rc, $(cat "$tmp/err")"
echo "perturb_test: ok"
