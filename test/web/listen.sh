#!/usr/bin/env bash
# web.listen: a bad address is a configuration error naming the file, line
# and key (exit 2); a taken port is logged with the address and errno, and
# the daemon runs on without the view, its status line saying so.
#   listen.sh STEMD TOOLS_DIR SOURCE_DIR
. "$(dirname "$0")/common.sh" "$@"
holder=""
trap '[ -z "$holder" ] || kill "$holder" 2>/dev/null || true; rm -rf "$tmp"' EXIT

printf 'web:\n  listen: localhost:8080\n' >"$tmp/bad.yaml"
set +e
"$stemd" --config "$tmp/bad.yaml" --check-config 2>"$tmp/err"
rc=$?
set -e
[ "$rc" -eq 2 ] || fail "bad web.listen: exit $rc, expected 2"
grep -q "^stemd: $tmp/bad.yaml:2: key 'web.listen': 'localhost:8080': not a numeric IPv4 address" "$tmp/err" \
  || fail "message: $(cat "$tmp/err")"
for bad in 127.0.0.1 127.0.0.1:70000 '::1:80'; do
  set +e
  "$stemd" --set "web.listen=$bad" --check-config 2>"$tmp/err"
  rc=$?
  set -e
  [ "$rc" -eq 2 ] || fail "web.listen=$bad: exit $rc"
  grep -q "key 'web.listen'" "$tmp/err" || fail "web.listen=$bad: $(cat "$tmp/err")"
done
# IPv6 in brackets: quoted, or YAML reads a list.
"$stemd" --set 'web.listen="[::1]:8080"' --check-config >/dev/null || fail "[::1]:8080 refused"

# A port held by another process: stemd runs the recording through anyway.
/usr/bin/python3 - "$tmp/port" <<'PY' &
import socket, sys, time
s = socket.socket()
s.bind(("127.0.0.1", 0))
s.listen(1)
open(sys.argv[1] + ".tmp", "w").write(str(s.getsockname()[1]))
import os; os.rename(sys.argv[1] + ".tmp", sys.argv[1])
while True:  # until the EXIT trap kills it: it must outlive stemd's run
    time.sleep(3600)
PY
holder=$!
for _ in $(seq 300); do [ -s "$tmp/port" ] && break; sleep 0.1; done
[ -s "$tmp/port" ] || fail "the port holder did not start"
port=$(cat "$tmp/port")
# Replayed as fast as the pipeline takes the frames (dropping none, whatever
# the host's speed); 40 frames, two PNGs each, outlast several 0.1 s status
# intervals.
"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 40 --fps 10 >/dev/null
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/rec" --once --set source.replay_pacing=fast \
  --can-log "$tmp/can.log" --set "web.listen=127.0.0.1:$port" --set status.interval_s=0.1 2>"$tmp/err" \
  || fail "stemd exited $? with the port taken: $(cat "$tmp/err")"
grep -q "web view: cannot listen on 127.0.0.1:$port: Address already in use (errno 98); running without it" "$tmp/err" \
  || fail "no bind error line: $(grep -i web "$tmp/err")"
grep -q "| web not serving (127.0.0.1:$port: Address already in use (errno 98))" "$tmp/err" \
  || fail "the status line does not say the view is off: $(grep status "$tmp/err" | head -2)"
grep -q "total: 40 frames in, 40 out" "$tmp/err" || fail "the run did not complete: $(grep total: "$tmp/err")"
echo "listen: ok"
