# shellcheck shell=bash
# Sourced by the command-line tests (test/cli, test/daemon, test/web) after
# `set -euo pipefail`: a scratch folder $tmp removed at exit, the background
# processes whose ids are in $pid (a space-separated list) killed first, and
# fail MESSAGE.
tmp=$(mktemp -d)
pid=
trap 'kill -KILL $pid 2>/dev/null || true; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
support_dir=$(dirname "${BASH_SOURCE[0]}")
. "$support_dir/recording.sh"

# synth_strip DIR LENGTH_MM [SEED]: a moving field strip at 15 fps and
# 2.5 km/h (the same 4.6 mm per frame as 30 fps at 5 km/h), early preset,
# no fragment. In a sanitizer build (STEMD_TEST_SANITIZED=1, set by CMake)
# at half that pace, 7.5 fps and 1.25 km/h, the same 4.6 mm per frame:
# ASan makes the pipeline three to five times slower, and a run that drops
# frames it cannot keep up with would measure the sanitizer, not stemd.
strip_pace=(--fps 15 --speed-kmh 2.5)
if [ "${STEMD_TEST_SANITIZED:-0}" = 1 ]; then strip_pace=(--fps 7.5 --speed-kmh 1.25); fi
synth_strip() {
  "$tools/stemd-synth" --strip --out "$1" --preset early --seed "${3:-5}" --fragment 0 --length-mm "$2" \
    "${strip_pace[@]}" >/dev/null
}

# stemd-train options for the tests of what the tools and the daemon do
# with a model, not how well it classes (classify_real_test.sh measures
# that): small forests on a subsample of the cells, about a tenth of the
# defaults' training time.
small_forests=(--cell-trees 10 --cell-samples 6000)

# The robot's real-time settings (SCHED_FIFO threads, as in the README's
# field setup) for the runs that assert exact TARGETs at the recorded pace:
# a host busy with other tests can stall a normal-priority replay for
# seconds, past what the actuator may extrapolate the odometer, and its
# plants then go untreated (no_odometry). Without the privilege stemd warns
# and runs as before.
realtime_sets=(--set threads.capture_priority=40 --set threads.processing_priority=30
  --set threads.actuator_priority=45)

# score_weeds_only STRIP CAN_LOG MAP CONFIG: stemd-eval of a run under
# weeds only against the strip's plants; fails on any command near a plant
# that is no weed, on no weed commanded, and on a crop sent in the plant
# map. Sets $matched, the weeds commanded.
score_weeds_only() {
  "$tools/stemd-eval" --targets "$1/plants.csv" "$2" --config "$4" --treat weeds --tol-mm 5 >"$tmp/score" 2>&1 || true
  cat "$tmp/score"
  grep -q '^extra            0 commands near no plant' "$tmp/score" || fail "a command for a plant that is no weed"
  matched=$(sed -n 's/^matched *\([0-9]*\) plants.*/\1/p' "$tmp/score")
  [ -n "$matched" ] && [ "$matched" -gt 0 ] || fail "no weed treated"
  grep -q '"class":"crop"' "$3" || fail "no plant classed crop in the map"
  if grep '"class":"crop"' "$3" | grep -q '"reason":"sent"'; then fail "a crop was sent"; fi
}

# start_notify_listener SOCKET OUT TIMEOUT_S [stamp]: a stand-in for
# systemd's notify socket in the background (its id in $listener), one line
# per message in OUT ("<monotonic s> <message>" with stamp); returns once
# the socket is bound.
start_notify_listener() {
  command -v python3 >/dev/null || { echo "SKIP: python3 (the stand-in socket) is not installed"; exit 77; }
  python3 "$support_dir/notify_listener.py" "$@" &
  listener=$!
  pid="$pid $listener"
  for _ in $(seq 100); do [ -e "$1.ready" ] && break; sleep 0.1; done
  [ -e "$1.ready" ] || fail "the stand-in socket did not come up"
}
