#!/usr/bin/env bash
# FIFOs where files belong must not hang stemd (SIGTERM would not get
# through): a FIFO as the config file is refused at once (exit 2), and a
# FIFO among a recording's images is skipped and counted like a corrupt
# frame while the replay goes on to the end; a FIFO as a recording's
# frames.csv, the model or the calibration file is refused at once.
#   fifo.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2
. "$(dirname "$0")/../support/script.sh"

mkfifo "$tmp/config.yaml"
rc=0
timeout 10 "$stemd" --config "$tmp/config.yaml" --check-config 2>"$tmp/err" || rc=$?
[ $rc -eq 2 ] || fail "FIFO config: exit $rc (124: it hung): $(cat "$tmp/err")"
grep -q "config.yaml: cannot read file: not a regular file" "$tmp/err" || fail "FIFO config: $(cat "$tmp/err")"

"$tools/stemd-synth" --out "$tmp/rec" --preset early --frames 3 >/dev/null
second=$(sed -n 3p "$tmp/rec/frames.csv" | cut -d, -f2)
rm "$tmp/rec/$second"
mkfifo "$tmp/rec/$second"
rc=0
timeout 30 "$stemd" --replay "$tmp/rec" --once 2>"$tmp/err" || rc=$?
[ $rc -eq 0 ] || fail "FIFO frame: exit $rc (124: it hung): $(tail -3 "$tmp/err")"
grep -q "not a regular file" "$tmp/err" || fail "FIFO frame not named: $(cat "$tmp/err")"
grep -q "total: 2 frames in, 2 out.*corrupt 1" "$tmp/err" || fail "FIFO frame not counted: $(grep total: "$tmp/err")"
# The recording's table, the classifier's model and the camera's
# calibration as FIFOs: each refused at once (exit 2), naming the file.
mkdir "$tmp/fifo-rec"
mkfifo "$tmp/fifo-rec/frames.csv" "$tmp/model.yaml" "$tmp/camera.yaml"
refused() {
  local expected=$1
  shift
  local rc=0
  timeout 10 "$stemd" "$@" 2>"$tmp/err" || rc=$?
  [ $rc -eq 2 ] || fail "$*: exit $rc (124: it hung): $(tail -3 "$tmp/err")"
  grep -qF "$expected" "$tmp/err" || fail "$*: expected '$expected', got: $(cat "$tmp/err")"
}
refused "fifo-rec is not a recording directory (no frames.csv)" --replay "$tmp/fifo-rec" --once
refused "$tmp/model.yaml: cannot read the model file: not a regular file" \
  --replay "$tmp/rec" --once --set classify.model="$tmp/model.yaml"
refused "$tmp/camera.yaml: cannot read the calibration file: not a regular file" \
  --replay "$tmp/rec" --once --set camera.model=calibrated --set camera.calibration_file="$tmp/camera.yaml"
echo "fifo: ok"
