#!/usr/bin/env bash
# The flake check: the full Release test suite (the VM tests included), run
# N times in a row on one build, as CI runs it (`ctest -j$(nproc)`). A test
# that fails once in N is a red CI waiting to happen.
#
#   tools/flake-loop.sh [--runs N] [--build DIR] [--out DIR]
#
# Needs a built DIR (default build/release) with its VM prepared
# (tools/test.sh does both). Writes one line per run to OUT/loop.log
# (time, duration, the host's load, ctest's summary, the streak of passes)
# and keeps each run's ctest output and LastTest.log (every test's own
# output, the VM checks' measurements too) as OUT/run-I.log and
# OUT/tests-I.log. Runs every N even after a failure, so one failure shows
# whether it repeats. Exit status 0 only when all N passed.
#
# Run it on a quiet host: other work on the cores is a harsher host than
# CI's (README, Reliability) and the count would say little about CI.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=20 build=build/release out=
while [ $# -gt 0 ]; do
  case $1 in
    --runs) runs=${2:?--runs needs a count}; shift 2 ;;
    --build) build=${2:?--build needs a folder}; shift 2 ;;
    --out) out=${2:?--out needs a folder}; shift 2 ;;
    *) echo "usage: $0 [--runs N] [--build DIR] [--out DIR]" >&2; exit 2 ;;
  esac
done
case $runs in '' | *[!0-9]* | 0) echo "$0: --runs: a positive whole number, not '$runs'" >&2; exit 2 ;; esac
[ -f "$build/CTestTestfile.cmake" ] || { echo "$0: $build: no built test tree (run tools/test.sh first)" >&2; exit 2; }
out=${out:-$build/flake-loop}
mkdir -p "$out"
log=$out/loop.log
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
dirty=$(git status --porcelain --untracked-files=no 2>/dev/null | grep -q . && echo " (uncommitted changes)" || true)
printf '%s: %d full runs of %s, commit %s%s, %s cores, %s\n' "$(date -u +%FT%TZ)" "$runs" "$build" "$commit" \
  "$dirty" "$(nproc)" "$(uname -r)" | tee -a "$log"

passed=0 streak=0 longest=0
for i in $(seq 1 "$runs"); do
  start=$(date +%s)
  rc=0
  ctest --test-dir "$build" --output-on-failure -j "$(nproc)" >"$out/run-$i.log" 2>&1 || rc=$?
  seconds=$(($(date +%s) - start))
  cp "$build/Testing/Temporary/LastTest.log" "$out/tests-$i.log" 2>/dev/null || true
  if [ "$rc" -eq 0 ]; then
    passed=$((passed + 1)) streak=$((streak + 1))
  else
    streak=0
  fi
  [ "$streak" -gt "$longest" ] && longest=$streak
  summary=$(grep -E 'tests passed' "$out/run-$i.log" | tail -1 || true)
  printf '%s run %d/%d: exit %d in %d s, load %s | %s | streak %d\n' "$(date -u +%T)" "$i" "$runs" "$rc" \
    "$seconds" "$(cut -d' ' -f1-3 /proc/loadavg)" "${summary:-no summary}" "$streak" | tee -a "$log"
  if [ "$rc" -ne 0 ]; then
    grep -E '\((Failed|Timeout|SEGFAULT|Subprocess aborted|Child aborted)\)' "$out/run-$i.log" | sed 's/^/    /' |
      tee -a "$log" || true
  fi
done
printf '%s: %d of %d runs passed, longest streak %d\n' "$(date -u +%FT%TZ)" "$passed" "$runs" "$longest" | tee -a "$log"
[ "$passed" -eq "$runs" ]
