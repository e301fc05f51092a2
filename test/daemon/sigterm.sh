#!/usr/bin/env bash
# SIGTERM (and SIGINT) stop stemd in every state it can be in: a looping,
# paced replay; a long recording being preloaded; a replay whose images are
# FIFOs (nothing to read, ever); a gpsd host that never answers the TCP
# handshake (connect() would block for minutes); and start-up, a 1 MiB
# config being read. Each is a bounded wait for the exit: the test fails if
# stemd is still alive 5 s after the signal (the goal is well under 0.5 s;
# the measured time is printed, not asserted, since the machine is shared).
#   sigterm.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1
tools=$2
src=$3
tmp=$(mktemp -d)
pid=
hole=
trap '[ -z "$pid" ] || kill -KILL "$pid" 2>/dev/null || true; [ -z "$hole" ] || kill "$hole" 2>/dev/null || true; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
kBoundMs=5000

# wait_for FILE PATTERN WHAT: up to 60 s for stemd's log to show PATTERN.
wait_for() {
  for _ in $(seq 600); do
    grep -qs "$2" "$1" && return 0
    kill -0 "$pid" 2>/dev/null || fail "$3: stemd exited early: $(tail -3 "$1")"
    sleep 0.1
  done
  fail "$3: no '$2' within 60 s: $(tail -3 "$1")"
}
# stop SIG WHAT: sends SIG, waits (bounded) for the exit; sets rc and ms.
stop() {
  local t0 end
  t0=$(date +%s%N)
  end=$((t0 + kBoundMs * 1000000))
  kill -"$1" "$pid"
  while kill -0 "$pid" 2>/dev/null; do
    [ "$(date +%s%N)" -lt $end ] || fail "$2: stemd still running $kBoundMs ms after SIG$1"
    sleep 0.01
  done
  ms=$((($(date +%s%N) - t0) / 1000000))
  rc=0
  wait "$pid" || rc=$?
  pid=
}

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null

for sig in TERM INT; do
  # debug: one line per processed frame, so the test can wait for frames.
  "$stemd" --replay "$tmp/rec" --set log.level=debug --set status.interval_s=0.2 >/dev/null 2>"$tmp/err.$sig" &
  pid=$!
  wait_for "$tmp/err.$sig" "frame 4 " "running replay"   # looped once, processing frames
  grep -q "status .*in .* fps, out .* fps" "$tmp/err.$sig" || fail "no status line"
  stop "$sig" "running replay"
  [ $rc -eq 0 ] || fail "SIG$sig: exit $rc: $(tail -3 "$tmp/err.$sig")"
  grep -q "SIG$sig: stopping" "$tmp/err.$sig" || fail "no stop message"
  echo "running replay, SIG$sig: exit 0 after $ms ms"
done

# A preload of 60 full-size frames takes seconds: SIGTERM must not wait for it.
"$tools/stemd-synth" --out "$tmp/long" --preset late --frames 60 >/dev/null
"$stemd" --replay "$tmp/long" --set source.replay_preload=true >/dev/null 2>"$tmp/err.preload" &
pid=$!
wait_for "$tmp/err.preload" "preloading 60 frames" "preload"
stop TERM "preload"
[ $rc -eq 0 ] || fail "SIGTERM during preload: exit $rc: $(tail -3 "$tmp/err.preload")"
grep -q "preload cancelled" "$tmp/err.preload" || fail "the preload ran to its end: $(tail -3 "$tmp/err.preload")"
grep -q "SIGTERM: stopping" "$tmp/err.preload" || fail "no stop message"
echo "preload: exit 0 after $ms ms"

# Every image a FIFO: the capture finds nothing to read, frame after frame.
cp -r "$tmp/rec" "$tmp/fifos"
for f in "$tmp"/fifos/rgb/*.png; do rm "$f"; mkfifo "$f"; done
"$stemd" --replay "$tmp/fifos" >/dev/null 2>"$tmp/err.fifo" &
pid=$!
wait_for "$tmp/err.fifo" "not a regular file" "FIFO images"
stop TERM "FIFO images"
[ $rc -eq 0 ] || fail "SIGTERM with FIFO images: exit $rc: $(tail -3 "$tmp/err.fifo")"
echo "FIFO images: exit 0 after $ms ms"

# A gpsd port whose backlog is full: the kernel drops the SYN and a plain
# connect() waits for minutes.
python3 - "$tmp/hole.port" <<'PY' &
import socket, sys, time
s = socket.socket()
s.bind(("127.0.0.1", 0))
s.listen(0)
port = s.getsockname()[1]
held = []
for _ in range(4):   # fill the backlog; these never complete
    c = socket.socket()
    c.setblocking(False)
    try:
        c.connect(("127.0.0.1", port))
    except BlockingIOError:
        pass
    held.append(c)
time.sleep(0.2)
open(sys.argv[1] + ".tmp", "w").write(str(port))
import os
os.rename(sys.argv[1] + ".tmp", sys.argv[1])
time.sleep(300)
PY
hole=$!
for _ in $(seq 100); do [ -s "$tmp/hole.port" ] && break; sleep 0.1; done
[ -s "$tmp/hole.port" ] || fail "the unanswering port did not start"
"$stemd" --replay "$tmp/rec" --can-log /dev/null --set gnss.source=gpsd --set gnss.host=127.0.0.1 \
  --set gnss.port="$(cat "$tmp/hole.port")" --set log.level=debug 2>"$tmp/err.gpsd" &
pid=$!
wait_for "$tmp/err.gpsd" "frame 4 " "gpsd connecting"
stop TERM "gpsd connecting"
[ $rc -eq 0 ] || fail "SIGTERM while gpsd connects: exit $rc: $(tail -3 "$tmp/err.gpsd")"
grep -q "gpsd 127.0.0.1:[0-9]*: .* 0 connections" "$tmp/err.gpsd" || fail "gpsd connected?: $(grep gpsd "$tmp/err.gpsd")"
echo "gpsd never answering: exit 0 after $ms ms"
kill "$hole"; wait "$hole" 2>/dev/null || true; hole=

# Start-up: a 1 MiB config (the size cap), the signal sent at increasing
# delays so that it lands in the loader, the config read or the start. Before
# stemd blocks the signals (while the libraries load) the default action
# ends it: 143. Otherwise it stops cleanly: 0.
cp "$src/config/stemd.yaml" "$tmp/big.yaml"
pad="# $(printf '%0100d' 0)"
n=$(((1000 * 1024 - $(wc -c <"$tmp/big.yaml")) / ${#pad} - 1))
awk -v n="$n" -v p="$pad" 'BEGIN { for (i = 0; i < n; i++) print p }' >>"$tmp/big.yaml"
for delay in 0.05 0.2 0.4 0.6 0.8 1.0; do
  "$stemd" --config "$tmp/big.yaml" --replay "$tmp/rec" --can-log /dev/null 2>"$tmp/err.start" &
  pid=$!
  sleep "$delay"
  kill -0 "$pid" 2>/dev/null || fail "start-up: stemd exited before the signal: $(tail -3 "$tmp/err.start")"
  stop TERM "start-up, signal after $delay s"
  case $rc in
    0) if grep -q "SIGTERM while starting: stopping" "$tmp/err.start"; then where="while starting"; else where="running"; fi ;;
    143) where="before the signals were blocked" ;;
    *) fail "start-up, signal after $delay s: exit $rc: $(tail -3 "$tmp/err.start")" ;;
  esac
  echo "start-up, signal after $delay s ($where): exit $rc after $ms ms"
done
