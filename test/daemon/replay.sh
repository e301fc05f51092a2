#!/usr/bin/env bash
# stemd end to end on a generated recording: --once, --detections-csv equal
# to stemd-detect, an odom_mm column, a corrupt frame, --check-config.
#   replay.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 5 >/dev/null

# Columns named in the daemon's header (t_ns dropped), taken by name from a CSV.
columns() {  # FILE COLS
  awk -F, -v want="$2" 'NR == 1 { n = split(want, w, ","); for (i = 1; i <= NF; i++) col[$i] = i;
      for (j = 1; j <= n; j++) if (!(w[j] in col)) { print "missing column " w[j] > "/dev/stderr"; exit 1 } }
    { line = ""; for (j = 1; j <= n; j++) line = line (j > 1 ? "," : "") $(col[w[j]]); print line }' "$1"
}

# --once: every frame, then exit 0; detections equal stemd-detect's.
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/rec" --once --detections-csv "$tmp/d.csv" \
  2>"$tmp/err" || fail "--once exited $?: $(cat "$tmp/err")"
"$tools/stemd-detect" --config "$src/config/stemd.yaml" --csv "$tmp/g.csv" "$tmp/rec" >/dev/null || fail "stemd-detect"
header=$(head -1 "$tmp/d.csv")
case $header in t_ns,image,plant,x,y,method,leaves,area_px*) ;; *) fail "header: $header" ;; esac
cols=${header#t_ns,}
columns "$tmp/d.csv" "$cols" >"$tmp/d.cols"
columns "$tmp/g.csv" "$cols" >"$tmp/g.cols"
diff "$tmp/d.cols" "$tmp/g.cols" >"$tmp/diff" || fail "detections differ from stemd-detect: $(head "$tmp/diff")"
rows=$(($(wc -l <"$tmp/d.csv") - 1))
[ "$rows" -gt 0 ] || fail "no detections"
# t_ns is each frame's recorded t_ns (frames.csv).
awk -F, 'NR == FNR { if (FNR > 1) t[$2] = $1; next } FNR > 1 && t[$2] != $1 { print; bad = 1 } END { exit bad }' \
  "$tmp/rec/frames.csv" "$tmp/d.csv" || fail "t_ns column is not the recording's t_ns"
grep -q "total: 5 frames in, 5 out" "$tmp/err" || fail "summary: $(grep total: "$tmp/err")"
# Every row went through the writer thread, none lost (the header is written at open).
grep -q "files: lines written $rows, lost 0" "$tmp/err" || fail "files in the summary: $(grep total: "$tmp/err")"

# An extra odom_mm column is tolerated; pacing fast and preload give the same rows.
awk -F, -v OFS=, '{ print $0, (NR == 1 ? "odom_mm" : (NR - 2) * 25) }' "$tmp/rec/frames.csv" >"$tmp/f.csv"
mv "$tmp/f.csv" "$tmp/rec/frames.csv"
"$stemd" --replay "$tmp/rec" --once --set source.replay_pacing=fast --set source.replay_preload=true \
  --detections-csv "$tmp/o.csv" 2>"$tmp/err" || fail "odom_mm recording exited $?: $(cat "$tmp/err")"
cmp -s "$tmp/o.csv" "$tmp/d.csv" || fail "odom_mm/fast/preload run differs"

# A corrupt frame: counted, skipped, the daemon goes on and exits 0.
echo "not a png" >"$tmp/rec/rgb/000002.png"
"$stemd" --replay "$tmp/rec" --once --set source.replay_pacing=fast --detections-csv "$tmp/c.csv" \
  2>"$tmp/err" || fail "corrupt frame: exited $?: $(cat "$tmp/err")"
grep -q "000002.png: cannot decode" "$tmp/err" || fail "no message naming the corrupt file: $(cat "$tmp/err")"
grep -q "total: 4 frames in, 4 out.*corrupt 1" "$tmp/err" || fail "corrupt not counted: $(grep total: "$tmp/err")"
! grep -q "000002.png" "$tmp/c.csv" || fail "the corrupt frame has rows"
grep -q "000003.png" "$tmp/c.csv" || fail "the frame after the corrupt one is missing"

# --check-config: 0 when valid, 2 with one file:line:key line when not.
"$stemd" --check-config --config "$src/config/stemd.yaml" >/dev/null || fail "--check-config of the default config"
printf 'ring:\n  capacity: 4\n  overflw: drop_newest\n' >"$tmp/bad.yaml"
set +e
"$stemd" --check-config --config "$tmp/bad.yaml" >/dev/null 2>"$tmp/e1"; rc=$?
"$stemd" --check-config --set ring.capacity=0 >/dev/null 2>"$tmp/e2"; rc2=$?
"$stemd" --replay "$tmp/nowhere" --once >/dev/null 2>"$tmp/e3"; rc3=$?
set -e
[ $rc -eq 2 ] || fail "bad key exited $rc"
grep -q "^stemd: $tmp/bad.yaml:3: key 'ring.overflw': " "$tmp/e1" || fail "bad key message: $(cat "$tmp/e1")"
[ "$(wc -l <"$tmp/e1")" -eq 1 ] || fail "bad key message is not one line"
[ $rc2 -eq 2 ] && grep -q "key 'ring.capacity': 0 is out of range \[1, 64\] frames" "$tmp/e2" ||
  fail "out of range: $rc2 $(cat "$tmp/e2")"
[ $rc3 -eq 2 ] && grep -q "not a recording directory" "$tmp/e3" || fail "missing recording: $rc3 $(cat "$tmp/e3")"
# What the daemon would refuse at start, --check-config refuses too, naming
# the file line of the key to blame.
printf 'gpio:\n  chip: gpiochip0\n  enable_line: -1\n' >"$tmp/gpio.yaml"
set +e
"$stemd" --check-config --config "$tmp/gpio.yaml" >/dev/null 2>"$tmp/e4"; rc4=$?
"$stemd" --check-config --set odometry.source=can >/dev/null 2>"$tmp/e5"; rc5=$?
"$stemd" --check-config --set odometry.source=encoder >/dev/null 2>"$tmp/e6"; rc6=$?
set -e
printf 'tools:\n  - id: 0\n  - id: 1\n    learn_latency: true\n    latency_min_ms: 30\n    latency_max_ms: 20\n' >"$tmp/tools.yaml"
set +e
"$stemd" --check-config --config "$tmp/tools.yaml" >/dev/null 2>"$tmp/e7"; rc7=$?
set -e
[ $rc7 -eq 2 ] && grep -q "^stemd: $tmp/tools.yaml:6: key 'tools\[1\].latency_max_ms': below latency_min_ms" "$tmp/e7" ||
  fail "a list item's key is named with its line: $rc7 $(cat "$tmp/e7")"
[ $rc4 -eq 2 ] && grep -q "^stemd: $tmp/gpio.yaml:3: key 'gpio.enable_line': " "$tmp/e4" ||
  fail "GPIO chip without an enable line: $rc4 $(cat "$tmp/e4")"
[ $rc5 -eq 2 ] && grep -q "key 'odometry.source' (--set): can, but can.interface is none" "$tmp/e5" ||
  fail "CAN odometry without a bus: $rc5 $(cat "$tmp/e5")"
[ $rc6 -eq 2 ] && grep -q "key 'odometry.source' (--set): encoder, but gpio.encoder is none" "$tmp/e6" ||
  fail "encoder odometry without an encoder: $rc6 $(cat "$tmp/e6")"
echo "daemon replay: ok ($rows detections)"
