#!/usr/bin/env bash
# stemd-record end to end: a generated recording recorded through
# `stemd-record --replay` gives the same frames (stemd-detect finds the same
# stems), t_ns strictly increasing, and replays with stemd --once; --frames,
# --seconds, SIGTERM, an existing DIR and a bad key.
#   record.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
record=$tools/stemd-record
[ -x "$record" ] || { echo "FAIL: $record not built (ninja stemd-record)" >&2; exit 1; }
. "$(dirname "$0")/../support/script.sh"
rows() { echo $(($(wc -l <"$1") - 1)); }

"$tools/stemd-synth" --out "$tmp/src" --preset late --frames 5 >/dev/null

# Record the whole recording (fast pacing: as fast as the writer takes frames).
"$record" --replay "$tmp/src" --out "$tmp/dst" --set source.replay_pacing=fast 2>"$tmp/err" ||
  fail "record exited $?: $(cat "$tmp/err")"
grep -q "total: 5 frames written to .* drops: writer_behind 0, corrupt 0, bad_size 0" "$tmp/err" ||
  fail "summary: $(grep total: "$tmp/err")"
[ "$(head -1 "$tmp/dst/frames.csv")" = "t_ns,rgb,nir,mask" ] || fail "header: $(head -1 "$tmp/dst/frames.csv")"
[ "$(rows "$tmp/dst/frames.csv")" -eq "$(rows "$tmp/src/frames.csv")" ] || fail "frame count differs"
awk -F, 'NR > 1 && NR > 2 && $1 <= prev { bad = 1 } NR > 1 { prev = $1 } END { exit bad }' "$tmp/dst/frames.csv" ||
  fail "t_ns not strictly increasing: $(cat "$tmp/dst/frames.csv")"
awk -F, 'NR > 1 { print $2 }' "$tmp/dst/frames.csv" | while read -r png; do
  [ -s "$tmp/dst/$png" ] || fail "missing $png"
done

# Same pixels: stemd-detect finds the same stems in both (image names dropped).
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --csv "$tmp/a.csv" "$tmp/src" >/dev/null || fail "detect src"
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --csv "$tmp/b.csv" "$tmp/dst" >/dev/null || fail "detect dst"
cut -d, -f2- "$tmp/a.csv" >"$tmp/a.cols"
cut -d, -f2- "$tmp/b.csv" >"$tmp/b.cols"
[ "$(rows "$tmp/a.csv")" -gt 0 ] || fail "no detections in the source recording"
diff "$tmp/a.cols" "$tmp/b.cols" >"$tmp/diff" || fail "detections differ: $(head "$tmp/diff")"

# The recording replays.
"$stemd" --replay "$tmp/dst" --once --set source.replay_pacing=fast 2>"$tmp/err" ||
  fail "stemd --once on the recording exited $?: $(cat "$tmp/err")"
grep -q "total: 5 frames in, 5 out" "$tmp/err" || fail "replay summary: $(grep total: "$tmp/err")"

# An existing, non-empty DIR is refused (exit 2) and left alone.
cp "$tmp/dst/frames.csv" "$tmp/before.csv"
set +e
"$record" --replay "$tmp/src" --out "$tmp/dst" --set source.replay_pacing=fast 2>"$tmp/err"; rc=$?
set -e
[ $rc -eq 2 ] || fail "existing DIR: exit $rc"
grep -q "not empty: refusing to overwrite" "$tmp/err" || fail "existing DIR message: $(cat "$tmp/err")"
cmp -s "$tmp/before.csv" "$tmp/dst/frames.csv" || fail "existing DIR was modified"
# An existing empty DIR is fine.
mkdir "$tmp/empty"
"$record" --replay "$tmp/src" --out "$tmp/empty" --frames 1 --set source.replay_pacing=fast 2>"$tmp/err" ||
  fail "empty DIR: exit $?: $(cat "$tmp/err")"

# --frames 3: exactly 3 rows.
"$record" --replay "$tmp/src" --out "$tmp/three" --frames 3 --set source.replay_pacing=fast 2>"$tmp/err" ||
  fail "--frames 3 exited $?: $(cat "$tmp/err")"
[ "$(rows "$tmp/three/frames.csv")" -eq 3 ] || fail "--frames 3: $(rows "$tmp/three/frames.csv") rows"
[ "$(ls "$tmp/three/rgb" | wc -l)" -eq 3 ] || fail "--frames 3: $(ls "$tmp/three/rgb" | wc -l) PNGs"

# A longer, small, paced recording (40 frames at 10 fps = 4 s) for --seconds and SIGTERM.
"$tools/stemd-synth" --out "$tmp/long" --preset late --frames 40 --width 160 --height 120 >/dev/null
small=(--set source.width_px=160 --set source.height_px=120)
"$record" --replay "$tmp/long" --out "$tmp/secs" --seconds 0.5 "${small[@]}" 2>"$tmp/err" ||
  fail "--seconds exited $?: $(cat "$tmp/err")"
n=$(rows "$tmp/secs/frames.csv")
[ "$n" -ge 1 ] && [ "$n" -lt 40 ] || fail "--seconds 0.5: $n rows"

for sig in TERM INT; do
  "$record" --replay "$tmp/long" --out "$tmp/sig$sig" "${small[@]}" 2>"$tmp/err.$sig" &
  pid=$!
  for _ in $(seq 100); do
    [ -f "$tmp/sig$sig/frames.csv" ] && [ "$(rows "$tmp/sig$sig/frames.csv")" -ge 3 ] && break
    kill -0 "$pid" 2>/dev/null || fail "stemd-record exited early: $(cat "$tmp/err.$sig")"
    sleep 0.1
  done
  kill -"$sig" "$pid"
  set +e
  wait "$pid"; rc=$?
  set -e
  pid=
  [ $rc -eq 0 ] || fail "SIG$sig: exit $rc: $(cat "$tmp/err.$sig")"
  grep -q "SIG$sig: stopping" "$tmp/err.$sig" || fail "SIG$sig: no stop message"
  n=$(rows "$tmp/sig$sig/frames.csv")
  [ "$n" -ge 3 ] && [ "$n" -lt 40 ] || fail "SIG$sig: $n rows"
  [ "$(ls "$tmp/sig$sig/rgb" | wc -l)" -eq "$n" ] || fail "SIG$sig: PNGs and rows differ"
  grep -q "total: $n frames written" "$tmp/err.$sig" || fail "SIG$sig summary: $(grep total: "$tmp/err.$sig")"
done

# Bad configuration: exit 2 with file:line: key '...'.
printf 'source:\n  kind: replay\n  replay_pacng: fast\n' >"$tmp/bad.yaml"
set +e
"$record" --config "$tmp/bad.yaml" --replay "$tmp/src" --out "$tmp/bad" >/dev/null 2>"$tmp/e1"; rc=$?
"$record" --replay "$tmp/nowhere" --out "$tmp/bad" >/dev/null 2>"$tmp/e2"; rc2=$?
"$record" --replay "$tmp/src" >/dev/null 2>"$tmp/e3"; rc3=$?
# An odometer source that is not configured: refused before anything is recorded.
printf 'odometry:\n  source: can\n' >"$tmp/can.yaml"
"$record" --config "$tmp/can.yaml" --replay "$tmp/src" --out "$tmp/bad" >/dev/null 2>"$tmp/e4"; rc4=$?
"$record" --set odometry.source=encoder --replay "$tmp/src" --out "$tmp/bad" >/dev/null 2>"$tmp/e5"; rc5=$?
set -e
[ $rc -eq 2 ] || fail "bad key exited $rc"
grep -q "^stemd-record: $tmp/bad.yaml:3: key 'source.replay_pacng': " "$tmp/e1" || fail "bad key message: $(cat "$tmp/e1")"
[ $rc2 -eq 2 ] && grep -q "not a recording directory" "$tmp/e2" || fail "missing recording: $rc2 $(cat "$tmp/e2")"
[ $rc3 -eq 2 ] && grep -q -- "--out DIR is required" "$tmp/e3" || fail "no --out: $rc3 $(cat "$tmp/e3")"
[ $rc4 -eq 2 ] && grep -q "^stemd-record: $tmp/can.yaml:2: key 'odometry.source': can, but can.interface is none" "$tmp/e4" ||
  fail "CAN odometry without an interface: $rc4 $(cat "$tmp/e4")"
[ $rc5 -eq 2 ] && grep -q "^stemd-record: key 'odometry.source' (--set): encoder, but gpio.encoder is none" "$tmp/e5" ||
  fail "encoder odometry without an encoder: $rc5 $(cat "$tmp/e5")"
[ ! -e "$tmp/bad" ] || fail "a refused run created its DIR"
echo "daemon record: ok"
