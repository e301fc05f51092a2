#!/usr/bin/env bash
# tools/eval-robust.sh on a data folder of generated sets under names it has
# never seen, laid out as the real ones are: every set is found by its
# layout (a recording with masks and stems, the same without a known GSD,
# CWFID's images/ and masks/ with 0 marking vegetation) and gets its rows
# under every condition; a folder of neither layout and stems without a GSD
# are named on stderr; an absent folder skips (77) and a missing tool exits
# 2. The figures are not judged (the real sets' are in the README), except
# that CWFID's inverted masks are read the right way round.
#   eval_robust_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
source_dir=$2
. "$(dirname "$0")/../support/script.sh"
. "$(dirname "$0")/../support/real_sets.sh"
script=$source_dir/tools/eval-robust.sh
export STEMD_TOOLS=$tools

check_absent_and_missing_tools "$script"

data=$tmp/data
unseen_sets "$data"

STEMD_EVAL_GSD="field-a=0.33" "$script" "$data" "$tmp/out" >"$tmp/table" 2>"$tmp/err" ||
  fail "eval-robust exited $?: $(cat "$tmp/err")"
check_skipped "$tmp/err"
grep -q "unknown-c: stems to score but no GSD known" "$tmp/err" ||
  fail "the set without a GSD was not named: $(cat "$tmp/err")"

/usr/bin/python3 - "$tmp/out/rows.jsonl" "$tmp/table" "$script" <<'PY' || fail "rows: $(cat "$tmp/out/rows.jsonl")"
import json, re, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
table = open(sys.argv[2]).read().splitlines()
# The conditions as the script lists them (label first).
body = open(sys.argv[3]).read()
conditions = re.findall(r'^  "([a-z0-9.+-]+) ', body.split("conditions=(")[1].split(")\n")[0], re.M)
assert len(conditions) >= 10 and conditions[0] == "as-recorded", conditions
per_condition = [("cwfid-d", "default"), ("field-a", "default"), ("field-a", "rgb+nir"), ("field-a", "rgb"),
                 ("unknown-c", "default")]
got = sorted((r["set"], r["condition"], r["config"]) for r in rows)
want = sorted((s, c, k) for c in conditions for (s, k) in per_condition)
if got != want:
    sys.exit("rows %s, expected %s" % (got, want))
for r in rows:
    if r["config"] == "default":
        assert r["result"]["frames"] == (1 if r["set"] == "cwfid-d" else 2), r
    else:
        assert r["result"]["gsd_mm_per_px"] == 0.33, r
cwfid = [r for r in rows if r["set"] == "cwfid-d" and r["condition"] == "as-recorded"][0]["result"]
assert cwfid["mean_iou"] > 0.5, "CWFID's masks read the wrong way round: %s" % cwfid
assert len(table) == 1 + len(rows), table
PY
echo "eval_robust_test: all passed"
