#!/usr/bin/env bash
# Bad input, end to end: stemd --replay and stemd-detect read frames.csv by
# one rule (header, t_ns, odom_mm), and refuse an image from its header
# before decoding it.
#   inputs.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# A stall must fail the test, not hang it.
run() { timeout 60 "$@"; }

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null
cp "$tmp/rec/frames.csv" "$tmp/frames.good"
fast=(--once --set source.replay_pacing=fast)

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

echo "inputs: ok"
