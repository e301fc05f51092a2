#!/usr/bin/env bash
# The systemd watchdog contract with a stuck processing thread: stemd under a
# stand-in for systemd (NOTIFY_SOCKET, WATCHDOG_USEC) keeps sending WATCHDOG=1
# while its threads progress, and stops once debug.stall_processing_after_frames
# has stuck the processing thread, so that systemd (WatchdogSec=, Restart=)
# would kill and restart it. Both runs replay the same looping recording,
# with the robot's real-time settings: a starved normal-priority capture
# thread makes no progress for a second and rightly withholds the watchdog
# in the control run too.
#   watchdog_stall.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 20 --fps 10 >/dev/null

# WATCHDOG_USEC as systemd sets it for WatchdogSec=2s: stemd pings every
# 0.5 s and calls a thread stuck after 1 s without progress.
watchdog_usec=2000000

# run NAME SETTING...: stemd looping over the recording under the stand-in;
# the stand-in writes "<monotonic s> <message>" lines to $tmp/NAME.messages.
# Stops stemd with SIGTERM once `until_cmd` succeeds, then observes for
# `observe_s` more seconds before the SIGTERM.
run() {
  local name=$1
  shift
  local socket="$tmp/$name.sock"
  start_notify_listener "$socket" "$tmp/$name.messages" 120 stamp
  NOTIFY_SOCKET="$socket" WATCHDOG_USEC=$watchdog_usec "$stemd" --config "$src/config/stemd.yaml" \
    "${realtime_sets[@]}" --set source.replay_loop=true "$@" --replay "$tmp/rec" >/dev/null 2>"$tmp/$name.err" &
  daemon=$!
  pid="$listener $daemon"
  # Condition first (generous deadline: a loaded machine), then a fixed
  # observation window measured in watchdog intervals.
  local n=0
  until $until_cmd "$name"; do
    n=$((n + 1))
    [ $n -le 600 ] || fail "$name: $until_what within 60 s: $(cat "$tmp/$name.err")"
    kill -0 "$daemon" 2>/dev/null || fail "$name: stemd exited early: $(cat "$tmp/$name.err")"
    sleep 0.1
  done
  sleep "$observe_s"
  local sent
  sent=$(python3 -c 'import time; print("%.3f" % time.monotonic())')
  kill -TERM "$daemon"
  wait "$daemon" || fail "$name: stemd exited $? on SIGTERM: $(cat "$tmp/$name.err")"
  wait "$listener" || true
  pid=
  echo "$sent" > "$tmp/$name.sigterm"
}

# The longest silence between WATCHDOG=1 pings (READY=1 counts as the
# start), and from the last ping to the SIGTERM, in seconds.
longest_silence() {
  awk -v end="$(cat "$tmp/$1.sigterm")" '
    $2 == "READY=1" || $2 == "WATCHDOG=1" { if (last != "" && $1 - last > gap) gap = $1 - last; last = $1; pings += ($2 == "WATCHDOG=1") }
    END { if (end - last > gap) gap = end - last; printf "%.3f %d\n", gap, pings }' "$tmp/$1.messages"
}

# Without the knob: pings all along, never a silence of a watchdog interval.
pinged() { [ "$(grep -c ' WATCHDOG=1$' "$tmp/$1.messages" 2>/dev/null || true)" -ge 4 ]; }
until_cmd=pinged until_what="4 WATCHDOG=1" observe_s=3
run control
read -r gap pings <<<"$(longest_silence control)"
echo "control: $pings WATCHDOG=1, longest silence $gap s"
grep -q " READY=1$" "$tmp/control.messages" || fail "control: no READY=1"
awk -v g="$gap" -v w="$watchdog_usec" 'BEGIN { exit !(g < w / 1e6) }' ||
  fail "control: a silence of $gap s, longer than WatchdogSec (systemd would restart a healthy daemon)"
grep -q "withholding the watchdog" "$tmp/control.err" && fail "control: $(grep withholding "$tmp/control.err")"

# With the knob: the processing thread stops after 20 frames (2 s at 10 fps).
stuck() { grep -q "processing thread has made no progress" "$tmp/$1.err"; }
until_cmd=stuck until_what="the stuck processing thread reported" observe_s=3
run stall --set debug.stall_processing_after_frames=20
read -r gap pings <<<"$(longest_silence stall)"
echo "stall: $pings WATCHDOG=1 before the stall, then silence for $gap s"
grep -q "debug.stall_processing_after_frames: stalling after 20 frames" "$tmp/stall.err" ||
  fail "stall: the knob did not stall the processing thread: $(cat "$tmp/stall.err")"
grep "withholding the watchdog" "$tmp/stall.err"
[ "$pings" -ge 1 ] || fail "stall: no WATCHDOG=1 before the stall"
# The last ping to the SIGTERM: at least the 3 s observation window, more
# than WatchdogSec, so systemd would have killed and restarted it.
awk -v g="$gap" -v w="$watchdog_usec" 'BEGIN { exit !(g > 3 && g > w / 1e6) }' ||
  fail "stall: WATCHDOG=1 went on while the processing thread was stuck (longest silence $gap s)"
# No ping after the stuck thread was reported: every ping precedes the silence.
last_ping=$(awk '$2 == "WATCHDOG=1" { t = $1 } END { print t }' "$tmp/stall.messages")
awk -v t="$last_ping" -v end="$(cat "$tmp/stall.sigterm")" 'BEGIN { exit !(end - t > 3) }' ||
  fail "stall: a WATCHDOG=1 within the observation window"

# The unit: systemd watches (WatchdogSec) and restarts on a watchdog kill
# (Restart=on-failure covers the watchdog's SIGABRT; so do on-watchdog and always).
unit="$src/systemd/stemd.service.in"
grep -Eq '^WatchdogSec=[1-9]' "$unit" || fail "$unit: no WatchdogSec="
grep -Eq '^Restart=(on-failure|on-watchdog|on-abnormal|always)$' "$unit" || fail "$unit: no Restart= that covers the watchdog"
echo "watchdog_stall: ok"
