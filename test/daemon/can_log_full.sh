#!/usr/bin/env bash
# A CAN log that cannot be written (a full disk: /dev/full gives ENOSPC):
# every frame is a bus error, stemd says the log is incomplete and exits 1.
#   can_log_full.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

synth_strip "$tmp/strip" 600
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --once --can-log "$tmp/can.log" 2>"$tmp/err" ||
  fail "a writable log exited $?: $(tail -3 "$tmp/err")"
grep -q "total: .* sent [1-9][0-9]*, .* bus_errors 0," "$tmp/err" || fail "nothing sent: $(grep total: "$tmp/err")"

rc=0
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --once --can-log /dev/full 2>"$tmp/err" || rc=$?
[ $rc -eq 1 ] || fail "/dev/full exited $rc: $(grep total: "$tmp/err")"
grep -q "total: .* sent 0, .* bus_errors [1-9][0-9]*," "$tmp/err" || fail "not bus errors: $(grep total: "$tmp/err")"
grep -q "canlog:/dev/full: write failed: No space left on device" "$tmp/err" || fail "no write error: $(cat "$tmp/err")"
grep -q "canlog:/dev/full: [0-9]* frames could not be written (sent 0); the CAN log is incomplete" "$tmp/err" ||
  fail "no closing error line: $(tail -3 "$tmp/err")"
echo "can_log_full: ok"
