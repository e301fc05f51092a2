#!/usr/bin/env bash
# tools/eval-real.sh on a data folder of generated sets under names it has
# never seen, laid out as the real ones are: each set is found by its layout
# (a recording with masks and stems, a moving strip with plants.csv,
# CWFID's images/ and masks/ with 0 marking vegetation), its GSD taken from
# STEMD_EVAL_GSD or its source's name; a set it cannot score is named on
# stderr and skipped; an absent folder skips (77) and a missing tool exits 2.
# The figures are not judged here (the real sets' are in the README), only
# that every set gets its rows, and that CWFID's inverted masks are read
# the right way round, that a CWFID-layout set's annotated stems are scored
# in the rows they belong to (sure, all, each kind), and that the daemon is
# run at the recording's frame size (a strip of 320 x 240 frames gets its
# TARGETs).
#   eval_real_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
source_dir=$2
. "$(dirname "$0")/../support/script.sh"
. "$(dirname "$0")/../support/real_sets.sh"
script=$source_dir/tools/eval-real.sh
export STEMD_TOOLS=$tools
export STEMD_DAEMON=$tools/../src/runtime/stemd
[ -x "$STEMD_DAEMON" ] || fail "no daemon at $STEMD_DAEMON"

check_absent_and_missing_tools "$script"

data=$tmp/data
unseen_sets "$data"
"$tools/stemd-synth" --strip --out "$data/strip-b" --length-mm 600 --width 320 --height 240 --seed 4 >/dev/null

# cwfid-d's stems, as test/data/cwfid-train-stems.csv holds CWFID's: the
# frame's true crop stem and a weed, both sure, and a stem that is not.
mkdir -p "$tmp/stems"
{
  echo "image,x,y,kind,sure,polygon"
  awk -F, '$1 == "rgb/000000.png" { printf "000_image.png,%s,%s,%s,1,0\n", $2, $3, $4; exit }' "$data/field-a/stems.csv"
  echo "000_image.png,40,200,weed,1,1"
  echo "000_image.png,300,20,weed,0,2"
} >"$tmp/stems/cwfid-d-stems.csv"
grep -q "^000_image.png,.*,crop,1,0$" "$tmp/stems/cwfid-d-stems.csv" ||
  fail "field-a's first frame has no crop stem to annotate: $(cat "$data/field-a/stems.csv")"

STEMD_EVAL_STEMS_DIR=$tmp/stems STEMD_EVAL_GSD="field-a=0.33 strip-b=0.33" "$script" "$data" "$tmp/out" >"$tmp/table" 2>"$tmp/err" ||
  fail "eval-real exited $?: $(cat "$tmp/err")"
check_skipped "$tmp/err"
grep -q "unknown-c: stems or plants to score but no GSD known" "$tmp/err" ||
  fail "the set without a GSD was not named: $(cat "$tmp/err")"

/usr/bin/python3 - "$tmp/out/rows.jsonl" "$data" <<'PY' || fail "rows: $(cat "$tmp/out/rows.jsonl")"
import csv, json, os, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
frames = {name: sum(1 for _ in csv.DictReader(open(os.path.join(sys.argv[2], name, "frames.csv"))))
          for name in ("field-a", "strip-b", "unknown-c")}
frames["cwfid-d"] = 1
got = sorted((r["set"], r["what"], r["config"]) for r in rows)
stems = ["rgb+nir, default", "rgb", "rgb+nir, ndvi", "rgb, centre of mass"]
# The annotated stems scored, by the rows they belong to: sure ones, all,
# and the sure ones of each kind.
cwfid_stems = {"sure, default": 2, "sure, centre of mass": 2, "all, default": 3,
               "sure crop, default": 1, "sure weed, default": 1}
# unknown-c's masks need no GSD: its IoU is scored, its stems are not.
want = sorted([("field-a", "mask IoU", "default"), ("strip-b", "mask IoU", "default"),
               ("cwfid-d", "mask IoU", "default"), ("unknown-c", "mask IoU", "default")]
              + [("field-a", "stems", c) for c in stems] + [("strip-b", "stems", c) for c in stems]
              + [("strip-b", "TARGETs", c) for c in stems[:3]]
              + [("cwfid-d", "stems", c) for c in cwfid_stems])
if got != want:
    sys.exit("rows %s, expected %s" % (got, want))
for r in rows:
    if r["what"] == "mask IoU":
        assert r["result"]["frames"] == frames[r["set"]], r
    if r["what"] == "stems" and r["set"] == "cwfid-d":
        # CWFID's layout is taken as CWFID's camera, and its stems within 15 px.
        assert r["result"]["gsd_mm_per_px"] == 0.11 and r["result"]["tol_mm"] == 1.65, r
        assert r["result"]["ground_truth"] == cwfid_stems[r["config"]], r
    elif r["what"] == "stems":
        assert r["result"]["gsd_mm_per_px"] == 0.33, r
# Read with soil as vegetation, the CWFID-like mask would barely overlap
# the detection (an IoU near 0; the right way round, near 1).
cwfid = [r for r in rows if r["set"] == "cwfid-d"][0]["result"]
assert cwfid["mean_iou"] > 0.5, "CWFID's masks read the wrong way round: %s" % cwfid
for r in rows:
    if r["what"] == "TARGETs":
        assert r["result"]["commands"] > 0, "no command from the strip: %s" % r
print("rows as expected")
PY
for name in field-a strip-b cwfid-d; do
  grep -q "^$name " "$tmp/table" || fail "$name is not in the table: $(cat "$tmp/table")"
done
echo "eval_real_test: all passed"
