#!/usr/bin/env bash
# SIGKILL in the middle of a paced replay: the plant map, the detections CSV
# and the CAN log hold what was written up to the kill, every line complete.
# The kill comes once the files have grown while stemd runs (a condition
# with a timeout, not a guess at how long that takes): a buffered writer
# fails that wait, since nothing reaches the file before its buffer fills.
#   kill.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

synth_strip "$tmp/strip" 1500
# Looping: the run cannot end before the kill.
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --map "$tmp/map.jsonl" \
  --detections-csv "$tmp/d.csv" --can-log "$tmp/can.log" 2>"$tmp/err" &
pid=$!
lines() { [ -f "$1" ] && wc -l <"$1" || echo 0; }
grown=
for _ in $(seq 600); do
  if [ "$(lines "$tmp/map.jsonl")" -ge 5 ] && [ "$(lines "$tmp/d.csv")" -ge 20 ]; then grown=1; break; fi
  kill -0 "$pid" 2>/dev/null || fail "stemd exited early: $(tail -5 "$tmp/err")"
  sleep 0.1
done
[ -n "$grown" ] || fail "within 60 s, the map has $(lines "$tmp/map.jsonl") lines and the CSV $(lines "$tmp/d.csv"): \
lines are held back while stemd runs"
kill -KILL "$pid"
wait "$pid" 2>/dev/null || true

python3 - "$tmp/map.jsonl" "$tmp/d.csv" "$tmp/can.log" <<'PY' || fail "incomplete lines after SIGKILL"
import json, re, sys
map_path, csv_path, can_path = sys.argv[1:]
def lines(path):
    data = open(path, 'rb').read().decode()
    if data and not data.endswith('\n'):
        sys.exit(f'{path}: ends on a torn line: {data.splitlines()[-1]!r}')
    return data.splitlines()
keys = {'id', 's_mm', 'y_mm', 'class', 'leaves', 'sightings', 'first_frame', 'last_frame', 'treated', 'reason'}
for n, line in enumerate(lines(map_path), 1):
    try:
        plant = json.loads(line)
    except ValueError as e:
        sys.exit(f'{map_path}:{n}: not JSON ({e}): {line!r}')
    if not keys <= plant.keys():
        sys.exit(f'{map_path}:{n}: lacks {sorted(keys - plant.keys())}')
csv = lines(csv_path)
if csv[0] != 't_ns,image,plant,x,y,method,leaves,area_px,estimator,confidence':
    sys.exit(f'{csv_path}:1: header {csv[0]!r}')
row = re.compile(r'^\d+,[^,]+,\d+,-?\d+\.\d{3},-?\d+\.\d{3},(leaves|com),\d+,\d+,\w+,\d\.\d{3}$')
for n, line in enumerate(csv[1:], 2):
    if not row.match(line):
        sys.exit(f'{csv_path}:{n}: not a complete row: {line!r}')
frame = re.compile(r'^\(\d+\.\d{6}\) can0 [0-9A-F]{3}#[0-9A-F]*$')
for n, line in enumerate(lines(can_path), 1):
    if not frame.match(line):
        sys.exit(f'{can_path}:{n}: not a complete candump line: {line!r}')
print(f'{len(lines(map_path))} plants, {len(csv) - 1} detections, {len(lines(can_path))} CAN frames, all complete')
PY
echo "kill: ok"
