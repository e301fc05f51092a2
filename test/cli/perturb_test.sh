#!/usr/bin/env bash
# tools/perturb-recording.py on a generated recording: exposure and gains
# scale each channel (nir by the exposure alone), vignetting darkens the
# corners to the asked share and leaves the centre, noise is reproducible for
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
set +e
"$perturb" "$tmp/missing" "$tmp/bad" >/dev/null 2>"$tmp/err"; rc=$?
set -e
[ $rc -ne 0 ] && grep -q "frames.csv" "$tmp/err" || fail "missing recording: rc $rc, $(cat "$tmp/err")"
echo "perturb_test: ok"
