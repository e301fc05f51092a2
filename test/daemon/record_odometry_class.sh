#!/usr/bin/env bash
# stemd-record --replay keeps what the replayed frames carry beyond pixels:
# the odom_mm of every frame and its class map (class/NNNNNN.png), from a
# `stemd-synth --strip` recording, which has both.
#   record_odometry_class.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2
record=$tools/stemd-record
[ -x "$record" ] || { echo "FAIL: $record not built (ninja stemd-record)" >&2; exit 1; }
. "$(dirname "$0")/../support/script.sh"
# Column $2 of frames.csv in $1, by its header name.
column() { awk -F, -v name="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == name) c = i; next } { print $c }' "$1"; }

"$tools/stemd-synth" --strip --out "$tmp/src" --length-mm 400 --width 160 --height 120 >/dev/null
small=(--set source.width_px=160 --set source.height_px=120 --set source.replay_pacing=fast)
"$record" --replay "$tmp/src" --out "$tmp/dst" "${small[@]}" 2>"$tmp/err" ||
  fail "record exited $?: $(cat "$tmp/err")"

[ "$(head -1 "$tmp/dst/frames.csv")" = "t_ns,rgb,nir,mask,odom_mm,class" ] ||
  fail "header: $(head -1 "$tmp/dst/frames.csv")"
n=$(($(wc -l <"$tmp/src/frames.csv") - 1))
[ "$n" -ge 5 ] || fail "the source strip has only $n frames"
[ "$(($(wc -l <"$tmp/dst/frames.csv") - 1))" -eq "$n" ] || fail "frame count differs"

# The same odometer reading, frame by frame (the shortest text of the same double).
column "$tmp/src/frames.csv" odom_mm >"$tmp/src.odom"
column "$tmp/dst/frames.csv" odom_mm >"$tmp/dst.odom"
[ "$(sort -u "$tmp/src.odom" | wc -l)" -gt 1 ] || fail "the source's odometer does not move"
diff "$tmp/src.odom" "$tmp/dst.odom" >"$tmp/diff" || fail "odom_mm differs: $(head "$tmp/diff")"

# The same class maps: the same pixels, encoded by the same PNG encoder at the same level.
paste -d' ' <(column "$tmp/src/frames.csv" class) <(column "$tmp/dst/frames.csv" class) | while read -r a b; do
  [ -n "$b" ] || fail "a frame lost its class map"
  cmp -s "$tmp/src/$a" "$tmp/dst/$b" || fail "class map $b differs from the source's $a"
done

# The copy replays, class maps and odometer included.
"$stemd" --replay "$tmp/dst" --once --set source.width_px=160 --set source.height_px=120 \
  --set source.replay_pacing=fast 2>"$tmp/err" || fail "stemd --once on the copy exited $?: $(cat "$tmp/err")"
grep -q "total: $n frames in, $n out" "$tmp/err" || fail "replay summary: $(grep total: "$tmp/err")"
echo "daemon record_odometry_class: ok"
