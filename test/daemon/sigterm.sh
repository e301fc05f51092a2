#!/usr/bin/env bash
# SIGTERM and SIGINT during a looping, paced replay, and SIGTERM while a long
# recording is being preloaded: exit 0 within 1 s.
#   sigterm.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null

for sig in TERM INT; do
  # debug: one line per processed frame, so the test can wait for frames.
  "$stemd" --replay "$tmp/rec" --set log.level=debug --set status.interval_s=0.2 2>"$tmp/err.$sig" &
  pid=$!
  # Wait (up to 60 s) until it has looped once and is processing frames.
  for _ in $(seq 600); do
    grep -q "frame 4 " "$tmp/err.$sig" && break
    kill -0 "$pid" 2>/dev/null || fail "stemd exited early: $(cat "$tmp/err.$sig")"
    sleep 0.1
  done
  grep -q "frame 4 " "$tmp/err.$sig" || fail "no frames processed: $(cat "$tmp/err.$sig")"
  grep -q "status .*in .* fps, out .* fps" "$tmp/err.$sig" || fail "no status line"
  t0=$(date +%s%N)
  kill -"$sig" "$pid"
  set +e
  wait "$pid"; rc=$?
  set -e
  pid=
  ms=$((($(date +%s%N) - t0) / 1000000))
  [ $rc -eq 0 ] || fail "SIG$sig: exit $rc: $(tail -3 "$tmp/err.$sig")"
  [ $ms -lt 1000 ] || fail "SIG$sig: took $ms ms to exit"
  grep -q "SIG$sig: stopping" "$tmp/err.$sig" || fail "no stop message"
  echo "SIG$sig: exit 0 after $ms ms"
done

# A preload of 60 full-size frames takes seconds: SIGTERM must not wait for it.
"$tools/stemd-synth" --out "$tmp/long" --preset late --frames 60 >/dev/null
"$stemd" --replay "$tmp/long" --set source.replay_preload=true 2>"$tmp/err.preload" &
pid=$!
for _ in $(seq 600); do
  grep -q "preloading 60 frames" "$tmp/err.preload" && break
  kill -0 "$pid" 2>/dev/null || fail "stemd exited early: $(cat "$tmp/err.preload")"
  sleep 0.1
done
grep -q "preloading 60 frames" "$tmp/err.preload" || fail "no preload: $(cat "$tmp/err.preload")"
t0=$(date +%s%N)
kill -TERM "$pid"
set +e
wait "$pid"; rc=$?
set -e
ms=$((($(date +%s%N) - t0) / 1000000))
[ $rc -eq 0 ] || fail "SIGTERM during preload: exit $rc: $(tail -3 "$tmp/err.preload")"
[ $ms -lt 1000 ] || fail "SIGTERM during preload: took $ms ms to exit"
grep -q "preload cancelled" "$tmp/err.preload" || fail "the preload ran to its end: $(tail -3 "$tmp/err.preload")"
grep -q "SIGTERM: stopping" "$tmp/err.preload" || fail "no stop message"
echo "SIGTERM during preload: exit 0 after $ms ms"
