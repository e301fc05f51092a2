#!/usr/bin/env bash
# stemd-synth --strip as a user scripts it: the recording's files and
# headers, byte-identical reruns, usage errors.
#   bash synth_strip_test.sh <dir-of-tools-binaries> <source-dir>
set -euo pipefail

synth="$1/stemd-synth"
[ -x "$synth" ] || { echo "FAIL: $synth is not an executable" >&2; exit 1; }
. "$(dirname "$0")/../support/script.sh"

args=(--strip --length-mm 400 --speed-kmh 6 --fps 25 --preset dense --seed 3 --width 640 --height 480)
"$synth" "${args[@]}" --out "$tmp/a" >"$tmp/out" || fail "stemd-synth --strip failed"
[ "$(wc -l <"$tmp/out")" -eq 1 ] || fail "not one summary line: $(cat "$tmp/out")"
grep -q "frames at 6 km/h, 25 fps" "$tmp/out" || fail "summary: $(cat "$tmp/out")"

[ "$(head -1 "$tmp/a/frames.csv")" = "t_ns,rgb,nir,mask,odom_mm,class" ] || fail "frames.csv header"
[ "$(head -1 "$tmp/a/stems.csv")" = "image,x,y,kind,leaves" ] || fail "stems.csv header"
[ "$(head -1 "$tmp/a/plants.csv")" = "id,s_mm,y_mm,kind,leaves,radius_mm" ] || fail "plants.csv header"
[ "$(sed -n 2p "$tmp/a/frames.csv")" = "1000000000,rgb/000000.png,nir/000000.png,mask/000000.png,0,class/000000.png" ] ||
  fail "first frame row: $(sed -n 2p "$tmp/a/frames.csv")"
grep -qx "camera.forward: up" "$tmp/a/strip.txt" || fail "strip.txt"
frames=$(($(wc -l <"$tmp/a/frames.csv") - 1))
[ "$frames" -gt 5 ] || fail "only $frames frames"
for sub in rgb nir mask class; do
  [ "$(ls "$tmp/a/$sub" | wc -l)" -eq "$frames" ] || fail "$sub: not $frames files"
done
[ "$(($(wc -l <"$tmp/a/plants.csv") - 1))" -gt 0 ] || fail "no plants"
[ "$(($(wc -l <"$tmp/a/stems.csv") - 1))" -gt 0 ] || fail "no stems"

"$synth" "${args[@]}" --out "$tmp/b" >/dev/null
(cd "$tmp/a" && find . -type f | sort | xargs md5sum) >"$tmp/a.md5"
(cd "$tmp/b" && find . -type f | sort | xargs md5sum) >"$tmp/b.md5"
cmp -s "$tmp/a.md5" "$tmp/b.md5" || fail "reruns differ"

# expect_usage ARGS...: exit 2 with one line on stderr.
expect_usage() {
  local rc=0
  "$synth" "$@" >/dev/null 2>"$tmp/err" || rc=$?
  [ "$rc" -eq 2 ] || fail "stemd-synth $*: exit $rc, expected 2"
  [ "$(wc -l <"$tmp/err")" -eq 1 ] || fail "stemd-synth $*: stderr: $(cat "$tmp/err")"
}
expect_usage --strip --out "$tmp/c" --frames 3
expect_usage --out "$tmp/c" --length-mm 100
expect_usage --strip --out "$tmp/c" --speed-kmh 0
expect_usage --strip --out "$tmp/c" --length-mm 200000
"$synth" --help | grep -q -- "--strip" || fail "--help does not document --strip"
echo "ok"
