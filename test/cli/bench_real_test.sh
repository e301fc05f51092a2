#!/usr/bin/env bash
# tools/bench-real.sh on a data folder of generated sets laid out as the
# shared sets are, one under the name of its source (bonirob/) and others
# under names it has never seen (an RGB recording, CWFID's images/ and
# masks/, folders of no set): every set by its layout, one row per
# configuration with its frame count (each set's frames repeated to 30 or
# more), time and paper ratio, rounds and the cvtColor yardstick in
# rows.jsonl, the ratio computed from those rows; an absent folder skips
# (77), and bad rounds or a missing tool exit 2.
# Times are not judged: it is a measurement, not a test of speed.
#   bench_real_test.sh TOOLS_DIR SOURCE_DIR
set -euo pipefail
tools=$1
source_dir=$2
. "$(dirname "$0")/../support/script.sh"
. "$(dirname "$0")/../support/real_sets.sh"
if [ ! -x "$tools/stemd-bench" ]; then
  echo "SKIP: no stemd-bench in $tools (this build has no benchmarks: STEMD_BUILD_BENCH=OFF)"
  exit 77
fi
bench=$source_dir/tools/bench-real.sh
export STEMD_TOOLS=$tools

check_absent_and_missing_tools "$bench"

mkdir -p "$tmp/data"
"$tools/stemd-synth" --out "$tmp/data/bonirob" --preset seedling --frames 2 --seed 3 >/dev/null
"$tools/stemd-synth" --out "$tmp/data/field-rgb" --preset late --frames 2 --seed 4 >/dev/null
# RGB only: the frames without their nir column.
sed -i '2,$ s/^\([^,]*\),\([^,]*\),[^,]*,/\1,\2,,/' "$tmp/data/field-rgb/frames.csv"
# CWFID's layout under another name, three frames.
cwfid_layout "$tmp/data/bonirob" "$tmp/data/held-out" 000000 000001 000000
folders_of_no_set "$tmp/data"

set +e
STEMD_BENCH_RUNS=0 "$bench" "$tmp/data" "$tmp/out" 2>"$tmp/err"
code=$?
set -e
[ "$code" = 2 ] || fail "STEMD_BENCH_RUNS=0 exited $code, not 2"
grep -q "STEMD_BENCH_RUNS" "$tmp/err" || fail "STEMD_BENCH_RUNS=0 without naming it: $(cat "$tmp/err")"

STEMD_BENCH_RUNS=2 "$bench" "$tmp/data" "$tmp/out" >"$tmp/table" 2>"$tmp/err" ||
  fail "bench-real exited $?: $(cat "$tmp/err")"
check_skipped "$tmp/err"
# The example model is made from cwfid-train only (absent here): the
# classifier is timed when the tree already holds the model.
model=no
[ -f "$source_dir/out/models/cwfid.yaml" ] && model=yes
if [ "$model" = no ]; then
  grep -q "held-out: no out/models/cwfid.yaml" "$tmp/err" || fail "the untimed classifier was not named: $(cat "$tmp/err")"
fi
grep -q "^machine: .*cores; load" "$tmp/table" || fail "no machine line: $(cat "$tmp/table")"
/usr/bin/python3 - "$tmp/out/rows.jsonl" "$tmp/table" "$model" <<'PY' || fail "the table does not follow from its rows"
import json, re, statistics, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
table = open(sys.argv[2]).read()
yardsticks = [r["cvtcolor_ms"] for r in rows if "set" not in r]
timed = [r for r in rows if "set" in r]
assert len(yardsticks) == 4, yardsticks  # each of the two rounds' start and end
assert all(v > 0 for v in yardsticks), yardsticks
# Two frames are given 15 times (30 frames), three 10 times.
expected = {("bonirob", "rgb+nir, default"): 30, ("bonirob", "rgb"): 30, ("field-rgb", "default"): 30,
            ("held-out", "default"): 30}
classifier = {("held-out", "classifier (example model)"): 3} if sys.argv[3] == "yes" else {}
assert sorted((r["set"], r["config"], r["round"]) for r in timed) == sorted(
    (s, c, k) for (s, c) in list(expected) + list(classifier) for k in (1, 2)), timed
for (name, config), frames in classifier.items():
    mine = [r for r in timed if (r["set"], r["config"]) == (name, config)]
    assert all(r["frames"] == frames and r["classify_cpu_ms"] > 0 for r in mine), mine
for (name, config), frames in expected.items():
    mine = [r for r in timed if (r["set"], r["config"]) == (name, config)]
    assert all(r["frames"] == frames and r["frame_ms"] > 0 for r in mine), mine
    median = statistics.median(r["frame_ms"] for r in mine)
    line = [l for l in table.splitlines() if l.startswith(name) and ("  %s " % config) in l]
    assert len(line) == 1, (name, config, table)
    fields = re.search(r" (\d+)  frame +([0-9.]+) \(([0-9.]+)-([0-9.]+)\) +([0-9.]+) +([0-9.]+)x the paper", line[0])
    assert fields, line[0]
    assert int(fields.group(1)) == frames, line[0]
    assert abs(float(fields.group(2)) - median) < 0.006, (line[0], median)
    assert float(fields.group(3)) <= float(fields.group(2)) <= float(fields.group(4)), line[0]
    assert abs(float(fields.group(5)) - median / statistics.median(yardsticks)) < 0.051, line[0]
    assert abs(float(fields.group(6)) - 62.2 / median) < 0.006, (line[0], 62.2 / median)
PY
echo "bench-real: table, rounds and ratios checked"
