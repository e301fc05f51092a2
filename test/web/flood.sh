#!/usr/bin/env bash
# The live view under a flood of connections that send nothing (a port
# scanner, a stuck client): it holds at most kWorkers (2) +
# kMaxWaitingConnections (16) + 2 of the process's descriptors, so the
# daemon's own files keep theirs. Under `ulimit -n 40` (stemd itself needs
# about 8) and a client opening idle connections for 15 s, the replay opens
# every frame: none counted corrupt, no "Too many open files"; and the view
# answers again once the flood is gone. Without the bound the view took
# every descriptor left and the replay lost its frames.
#   flood.sh STEMD TOOLS_DIR SOURCE_DIR
. "$(dirname "$0")/common.sh" "$@"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 10 --fps 10 >/dev/null
real_stemd=$stemd
stemd="$tmp/limited-stemd"
printf '#!/usr/bin/env bash\nulimit -n 40\nexec "%s" "$@"\n' "$real_stemd" >"$stemd"
chmod +x "$stemd"
# Looping replay (a new file opened for every frame), the view on.
start_stemd "$tmp/err" --config "$src/config/stemd.yaml" --replay "$tmp/rec" --can-log "$tmp/can.log" \
  --set web.listen=127.0.0.1:0 --set status.interval_s=1
fetch / "$tmp/page.html"
port=${base##*:}
fds() { find "/proc/$stemd_pid/fd" -mindepth 1 -maxdepth 1 2>/dev/null | wc -l; }
before=$(fds)

/usr/bin/python3 - "$port" "$tmp/flood.done" <<'PY' &
import socket, sys, time
# Connections that send nothing, opened one after another (each connect
# returns once the kernel has queued it for the view) until 300 are held or
# 15 s have passed: a bounded view soon stops accepting and the connects
# time out; an unbounded one takes them all.
port, done = int(sys.argv[1]), sys.argv[2]
held = []
give_up = time.monotonic() + 15
while len(held) < 300 and time.monotonic() < give_up:
    s = socket.socket()
    s.settimeout(0.5)
    try:
        s.connect(("127.0.0.1", port))
        held.append(s)
    except OSError:
        s.close()
time.sleep(5)
print(f"flood: {len(held)} connections held", flush=True)
for s in held:
    s.close()
open(done, "w").close()
PY
flood=$!
most=$before
while [ ! -e "$tmp/flood.done" ]; do
  n=$(fds)
  [ "$n" -gt "$most" ] && most=$n
  kill -0 "$stemd_pid" 2>/dev/null || fail "stemd exited under the flood: $(tail -5 "$tmp/err")"
  sleep 0.1
done
wait "$flood"

# The view answers again (fetch retries while the queued idle sockets close).
fetch /api/status "$tmp/status.json"
stop_stemd
! grep -q "Too many open files" "$tmp/err" || fail "descriptors ran out: $(grep -m3 'Too many open files' "$tmp/err")"
summary=$(grep "status.*total:" "$tmp/err" | tail -1)
[ -n "$summary" ] || fail "no summary: $(tail -5 "$tmp/err")"
echo "$summary" | grep -q "corrupt 0," || fail "frames lost: $summary"
grep -q "web view: 16 connections wait for its 2 workers" "$tmp/err" \
  || fail "the flood was not logged (descriptors before $before, at most $most): $(grep -v 'status ' "$tmp/err" | tail -5)"
# 2 workers + 16 waiting + the listening socket and the connection served on
# it, and the replay's frame file open at that moment.
[ $((most - before)) -le 21 ] || fail "the view held $((most - before)) descriptors (before: $before, most: $most)"
echo "flood: stemd held $before descriptors before, at most $most during the idle connections; no frame lost"
