#!/usr/bin/env bash
# Bad input, end to end: stemd --replay and stemd-detect read frames.csv by
# one rule (header, t_ns, odom_mm), refuse an image from its header before
# decoding it, and report what they cannot use (class values, plants
# beyond the per-frame capacity) in the total line, never silently.
#   inputs.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"
# A stall must fail the test, not hang it.
run() { timeout 60 "$@"; }

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null
cp "$tmp/rec/frames.csv" "$tmp/frames.good"
fast=(--once --set source.replay_pacing=fast --can-log "$tmp/can.log")

# --- frames.csv: stemd refuses what stemd-detect refuses, naming file and line.
expect_refused() {  # WHAT EXPECTED_MESSAGE: frames.csv already written
  local what=$1 message=$2 rc=0 rc_detect=0
  run "$stemd" --replay "$tmp/rec" "${fast[@]}" >/dev/null 2>"$tmp/err" || rc=$?
  run "$tools/stemd-detect" "$tmp/rec" >/dev/null 2>"$tmp/err.detect" || rc_detect=$?
  [ $rc -eq 1 ] || fail "$what: stemd exited $rc: $(tail -3 "$tmp/err")"
  [ $rc_detect -eq 2 ] || fail "$what: stemd-detect exited $rc_detect: $(cat "$tmp/err.detect")"
  grep -qF "$tmp/rec/frames.csv:$message" "$tmp/err" || fail "$what: stemd says: $(grep -i error "$tmp/err")"
  grep -qF "$tmp/rec/frames.csv:$message" "$tmp/err.detect" || fail "$what: stemd-detect says: $(cat "$tmp/err.detect")"
}
header() { { echo "$1"; tail -n +2 "$tmp/frames.good" | sed "$2"; } >"$tmp/rec/frames.csv"; }
header "t_ns,rgb,nir,mask,speed" 's/$/,1/'
expect_refused "unknown column" "1: unknown column 'speed'"
header "t_ns,rgb,mask,nir" 's/x/x/'
expect_refused "reordered columns" "1: header must start with 't_ns,rgb,nir,mask'"
header "t_ns,rgb" 's/^\([^,]*,[^,]*\),.*/\1/'
expect_refused "no nir and mask" "1: header must start with 't_ns,rgb,nir,mask'"
header "t_ns,rgb,nir,mask,odom_mm,odom_mm" 's/$/,1,1/'
expect_refused "repeated column" "1: column 'odom_mm' appears twice"

# --- t_ns: increasing from 0, at most 60 s between frames (the replay paces by it).
times() {  # T1 T2 T3
  awk -F, -v OFS=, -v t="$*" 'BEGIN { split(t, ts, " ") } NR == 1 { print; next } { $1 = ts[NR - 1]; print }' \
    "$tmp/frames.good" >"$tmp/rec/frames.csv"
}
times 0 100000000 100000000
expect_refused "repeated t_ns" "4: t_ns 100000000 repeats line 3's"
times 0 100000000 50000000
expect_refused "decreasing t_ns" "4: t_ns 50000000 is before line 3's"
times -9223372036854775807 0 9223372036854775807
expect_refused "t_ns at the int64 limits" "2: t_ns -9223372036854775807 is negative"
times 0 1000000000000000 1000000000000001
expect_refused "a 1e15 ns gap" "3: t_ns 1000000000000000 is 1000000 s after line 2's"

# --- odom_mm: never decreasing, within +-1e9 mm.
odom() { awk -F, -v OFS=, -v o="$*" 'BEGIN { split(o, os, " ") } { print $0, NR == 1 ? "odom_mm" : os[NR - 1] }' \
  "$tmp/frames.good" >"$tmp/rec/frames.csv"; }
odom 10 20 15
expect_refused "decreasing odometer" "4: odom_mm 15 is less than line 3's"
odom 0 1e300 1e300
expect_refused "odom_mm 1e300" "3: odom_mm 1e300 is beyond +-1e9 mm"
cp "$tmp/frames.good" "$tmp/rec/frames.csv"

# --- An image declaring 30000x30000: refused from its header, never decoded.
python3 - "$tmp/rec/rgb/000001.png" <<'PY'
import struct, sys, zlib
path = sys.argv[1]
png = bytearray(open(path, 'rb').read())
png[16:24] = struct.pack('>II', 30000, 30000)
png[29:33] = struct.pack('>I', zlib.crc32(bytes(png[12:29])))
open(path, 'wb').write(png)
PY
run "$stemd" --replay "$tmp/rec" "${fast[@]}" 2>"$tmp/err" || fail "stemd exited $?: $(tail -3 "$tmp/err")"
grep -q "000001.png: declares 30000x30000, the frames are 1296x966; skipped, not decoded" "$tmp/err" ||
  fail "no message naming the oversized frame: $(grep 000001 "$tmp/err")"
grep -q "total: 2 frames in, 2 out.*corrupt 0, bad_size 1" "$tmp/err" || fail "not counted: $(grep total: "$tmp/err")"
rc=0
run "$tools/stemd-detect" "$tmp/rec" >"$tmp/out" 2>"$tmp/err" || rc=$?
[ $rc -eq 1 ] || fail "stemd-detect exited $rc: $(cat "$tmp/err")"
grep -q "skipped frame: .*000001.png: declares 30000x30000, more than 8192 px a side; not decoded" "$tmp/err" ||
  fail "stemd-detect message: $(cat "$tmp/err")"
grep -q "^2 frames, .*, 1 frames skipped$" "$tmp/out" || fail "stemd-detect summary: $(tail -1 "$tmp/out")"

# --- Plants beyond the 256 a frame holds: counted in both summaries.
# A 720x720 mask with an 18x18 grid of 12x12 px squares, 28 px apart
# (farther than closing and grouping join): 324 plants a frame.
mkdir -p "$tmp/many/mask"
python3 - "$tmp/many/mask/0.pgm" <<'PY'
import sys
size, pitch, side = 720, 40, 12
rows = []
for y in range(size):
    on = (y % pitch) >= 20 and (y % pitch) < 20 + side
    rows.append(bytes(255 if on and (x % pitch) >= 20 and (x % pitch) < 20 + side else 0 for x in range(size)))
open(sys.argv[1], 'wb').write(b'P5\n%d %d\n255\n' % (size, size) + b''.join(rows))
PY
printf 't_ns,rgb,nir,mask\n0,,,mask/0.pgm\n100000000,,,mask/0.pgm\n' >"$tmp/many/frames.csv"
over=$((18 * 18 - 256))
"$tools/stemd-detect" --segment mask "$tmp/many" >"$tmp/out" 2>"$tmp/err" || fail "stemd-detect: $(cat "$tmp/err")"
grep -q "^2 frames, 512 stems, 0 stemless plants, $((2 * over)) plants over capacity (256 a frame)$" "$tmp/out" ||
  fail "stemd-detect summary: $(tail -1 "$tmp/out")"
run "$stemd" --replay "$tmp/many" "${fast[@]}" --set segment.method=mask --set source.width_px=720 \
  --set source.height_px=720 2>"$tmp/err" || fail "stemd exited $?: $(tail -3 "$tmp/err")"
grep -q "total: 2 frames in, 2 out, 512 stems .*over_capacity $((2 * over)), " "$tmp/err" ||
  fail "stemd total: $(grep total: "$tmp/err")"

# --- Class values above 2 (no such class): counted in the total line.
synth_strip "$tmp/strip" 600
"$stemd" --replay "$tmp/strip" "${fast[@]}" 2>"$tmp/err" || fail "strip: $(tail -3 "$tmp/err")"
grep -q "total: .*, bad_class 0 |" "$tmp/err" || fail "good class maps: $(grep total: "$tmp/err")"
python3 - "$tmp/strip/class" <<'PY'
import glob, struct, sys, zlib
def chunk(t, d):
    return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d))
for path in glob.glob(sys.argv[1] + '/*.png'):
    png = open(path, 'rb').read()
    w, h = struct.unpack('>II', png[16:24])
    pixels = zlib.compress((b'\0' + bytes([3]) * w) * h)   # class 3 everywhere
    open(path, 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 0, 0, 0, 0))
                           + chunk(b'IDAT', pixels) + chunk(b'IEND', b''))
PY
"$stemd" --replay "$tmp/strip" "${fast[@]}" 2>"$tmp/err" || fail "strip: $(tail -3 "$tmp/err")"
stems=$(sed -n 's/.*total: .* out, \([0-9]*\) stems.*/\1/p' "$tmp/err")
bad=$(sed -n 's/.*total: .*, bad_class \([0-9]*\) |.*/\1/p' "$tmp/err")
[ -n "$bad" ] && [ "$bad" -gt 0 ] && [ "$bad" -le "$stems" ] || fail "class 3 not counted: $(grep total: "$tmp/err")"
echo "inputs: ok"
