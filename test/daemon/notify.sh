#!/usr/bin/env bash
# stemd under a stand-in for systemd: READY=1 once frames flow, WATCHDOG=1
# while the threads run (WATCHDOG_USEC set), STATUS= lines, STOPPING=1.
#   notify.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 20 --fps 10 >/dev/null

socket="$tmp/notify.sock"
start_notify_listener "$socket" "$tmp/messages" 30

# 20 frames at 10 fps: 2 s of replay; watchdog 0.4 s, so WATCHDOG=1 every 0.1 s.
NOTIFY_SOCKET="$socket" WATCHDOG_USEC=400000 "$stemd" --config "$src/config/stemd.yaml" \
  --set status.interval_s=0.5 --replay "$tmp/rec" --once 2>"$tmp/err" || fail "stemd exited $?: $(cat "$tmp/err")"
wait "$listener" || true

grep -qx "READY=1" "$tmp/messages" || fail "no READY=1: $(cat "$tmp/messages")"
watchdogs=$(grep -cx "WATCHDOG=1" "$tmp/messages" || true)
[ "$watchdogs" -ge 5 ] || fail "only $watchdogs WATCHDOG=1 in 2 s"
grep -q "^STATUS=in .* fps" "$tmp/messages" || fail "no STATUS= line"
[ "$(tail -1 "$tmp/messages")" = "STOPPING=1" ] || fail "last message: $(tail -1 "$tmp/messages")"
# READY comes before the first WATCHDOG.
[ "$(grep -nx -m1 READY=1 "$tmp/messages" | cut -d: -f1)" -lt "$(grep -nx -m1 WATCHDOG=1 "$tmp/messages" | cut -d: -f1)" ] \
  || fail "WATCHDOG=1 before READY=1"
echo "notify: ok ($watchdogs watchdog pings)"
