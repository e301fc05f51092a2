#!/usr/bin/env bash
# stemd under a stand-in for systemd: READY=1 once frames flow, WATCHDOG=1
# while the threads run (WATCHDOG_USEC set), STATUS= lines, STOPPING=1.
#   notify.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1
tools=$2
src=$3
tmp=$(mktemp -d)
trap 'kill "$listener" 2>/dev/null || true; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
command -v python3 >/dev/null || { echo "SKIP: python3 (the stand-in socket) is not installed"; exit 77; }

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 20 --fps 10 >/dev/null

socket="$tmp/notify.sock"
python3 - "$socket" "$tmp/messages" <<'PY' &
import socket, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(sys.argv[1])
s.settimeout(30)
with open(sys.argv[2], "w", buffering=1) as out:
    open(sys.argv[1] + ".ready", "w").close()
    while True:
        try:
            msg = s.recv(4096).decode()
        except socket.timeout:
            break
        out.write(msg.replace("\n", " ") + "\n")
        if msg == "STOPPING=1":
            break
PY
listener=$!
for _ in $(seq 100); do [ -e "$socket.ready" ] && break; sleep 0.1; done
[ -e "$socket.ready" ] || fail "the stand-in socket did not come up"

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
