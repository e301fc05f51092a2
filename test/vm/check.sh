#!/usr/bin/env bash
# One CTest test per guest check: reports what the "vm" fixture (boot.sh) left
# in OUTDIR for CHECK. Exit 0 passed, 77 skipped (reason printed), 1 failed.
#   check.sh OUTDIR CHECK
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 OUTDIR CHECK" >&2; exit 2; }
out=$1 check=$2

if [ -f "$out/skip" ]; then
  cat "$out/skip"
  exit 77
fi
if [ ! -f "$out/$check.rc" ]; then
  echo "FAILED: no result for $check in $out (the VM did not run it; see the console-*.log files there)"
  exit 1
fi
cat "$out/$check.log" 2>/dev/null || true
rc=$(cat "$out/$check.rc")
case $rc in
  0) exit 0 ;;
  77) exit 77 ;;
  *) echo "FAILED: guest check $check exited $rc"; exit 1 ;;
esac
