#!/usr/bin/env bash
# The HEARTBEAT says CAMERA_LOST (state 5) while the source gives no frames,
# and stops saying it once frames come again: a looping replay whose
# recording folder is moved away (every image unreadable, skipped and
# counted) and then put back.
#   camera_lost.sh STEMD TOOLS_DIR SOURCE_DIR
# The robot's real-time settings: a starved normal-priority replay can go
# source.lost_after_ms without a frame while its recording is there.
set -euo pipefail
stemd=$1 tools=$2
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null

# The HEARTBEAT states (base+3 = 0x303, byte 1's high nibble) in the CAN log
# from line $1 on, one character each.
states_from() { tail -n +"$1" "$tmp/can.log" | awk '$3 ~ /^303#/ { printf "%s", substr($3, 7, 1) }'; }
# until SECONDS CONDITION...: the condition holds within the time (stemd alive).
until_true() {
  local n=$(($1 * 10)); shift
  for _ in $(seq "$n"); do
    "$@" && return 0
    kill -0 "$pid" 2>/dev/null || fail "stemd exited: $(tail -3 "$tmp/err")"
    sleep 0.1
  done
  return 1
}

"$stemd" "${realtime_sets[@]}" --replay "$tmp/rec" --can-log "$tmp/can.log" --set source.lost_after_ms=300 \
  --set status.interval_s=0.2 2>"$tmp/err" &
pid=$!
has_frames() { [ -s "$tmp/can.log" ] && states_from 1 | grep -q '[12]'; }
until_true 60 has_frames || fail "no idle or active HEARTBEAT with frames: $(tail -3 "$tmp/err")"
states_from 1 | grep -q 5 && fail "camera_lost while frames came: $(states_from 1)"

mv "$tmp/rec" "$tmp/away"
mark=$(($(wc -l <"$tmp/can.log") + 1))
says_lost() { states_from "$mark" | grep -q 5; }
until_true 60 says_lost || fail "no camera_lost HEARTBEAT with the recording gone: states '$(states_from "$mark")'"
# The log is written off the actuator's path: its line may follow the frame.
loss_logged() { grep -q "no frame for source.lost_after_ms; HEARTBEAT state CAMERA_LOST" "$tmp/err"; }
until_true 60 loss_logged || fail "the loss is not logged"
corrupt_counted() { grep -q "status .*corrupt [1-9]" "$tmp/err"; }
until_true 60 corrupt_counted || fail "the unreadable frames are not counted: $(grep status "$tmp/err" | tail -1)"
echo "recording gone: HEARTBEAT states '$(states_from "$mark")' (5 = camera_lost)"

mv "$tmp/away" "$tmp/rec"
mark=$(($(wc -l <"$tmp/can.log") + 1))
# After the frames are back (logged), the states go back to idle/active.
back() { grep -q "frames again, after [0-9]* ms without one" "$tmp/err"; }
until_true 60 back || fail "frames did not come again: $(tail -3 "$tmp/err")"
mark=$(($(wc -l <"$tmp/can.log") + 1))
# From the first idle/active HEARTBEAT on (one in flight as the frame came
# may still say 5), five more, none of them camera_lost.
after_ok() { states_from "$mark" | sed -n 's/^[^12]*//p'; }
five_more() { [ "$(after_ok | wc -c)" -ge 6 ]; }
until_true 60 five_more || fail "no idle or active HEARTBEAT after frames came again: '$(states_from "$mark")'"
tail=$(after_ok)
case $tail in *5*) fail "camera_lost after frames came again: '$(states_from "$mark")'" ;; esac
echo "recording back: HEARTBEAT states '$(states_from "$mark")'"

kill -TERM "$pid"
rc=0
wait "$pid" || rc=$?
pid=
[ $rc -eq 0 ] || fail "exit $rc after SIGTERM: $(tail -3 "$tmp/err")"
echo "camera_lost: ok"
