#!/usr/bin/env bash
# stemd-calibrate end to end on rendered PNGs: intrinsics from twelve views
# and a blank one (rejected), the ground pose from the board on the ground
# with those intrinsics, the fragment accepted by stemd --check-config (alone
# and as a second --config on the default configuration) and close to the
# rendering's camera; usage errors exit 2.
#   bash calibrate_e2e.sh <stemd-calibrate> <stemd-test-board-views> <stemd>
set -euo pipefail

calibrate="$1"
views="$2"
stemd="$3"
for b in "$calibrate" "$views" "$stemd"; do
  [ -x "$b" ] || { echo "FAIL: $b is not an executable" >&2; exit 1; }
done
. "$(dirname "$0")/../support/script.sh"

"$views" "$tmp/img" || fail "rendering the views failed"

# --- intrinsics
"$calibrate" intrinsics --board 9x6 --square-mm 25 --out "$tmp/camera.yaml" \
  "$tmp"/img/view_*.png "$tmp/img/blank.png" >"$tmp/intr.out" || fail "intrinsics failed: $(cat "$tmp/intr.out")"
grep -q "blank.png: board 9x6 not found, view rejected" "$tmp/intr.out" || fail "blank view not rejected: $(cat "$tmp/intr.out")"
grep -q "^12 of 13 views show the board" "$tmp/intr.out" || fail "view count: $(cat "$tmp/intr.out")"
grep -q "^RMS reprojection error" "$tmp/intr.out" || fail "no RMS: $(cat "$tmp/intr.out")"
[ "$(grep -c "view_.*\.png: [0-9.]* px" "$tmp/intr.out")" -eq 12 ] || fail "per-view errors: $(cat "$tmp/intr.out")"
grep -q "camera_matrix" "$tmp/camera.yaml" || fail "camera.yaml"

# --- ground, with the intrinsics just fitted
"$calibrate" ground --board 11x8 --square-mm 25 --calibration "$tmp/camera.yaml" \
  --board-x-mm 250 --board-y-mm -50 --out "$tmp/camera_fragment.yaml" "$tmp/img/ground.png" >"$tmp/ground.out" ||
  fail "ground failed: $(cat "$tmp/ground.out")"
for what in "^pose: height" "^principal point on the ground" "^  centre " "^  top left " "^ground footprint" \
  "^  bottom right *x "; do
  grep -q "$what" "$tmp/ground.out" || fail "no '$what' in: $(cat "$tmp/ground.out")"
done
"$stemd" --config "$tmp/camera_fragment.yaml" --check-config >"$tmp/check.out" 2>&1 ||
  fail "stemd --check-config rejects the fragment: $(cat "$tmp/check.out")"
# Layered on the site's configuration by a second --config: pasted into
# it, its camera: and source: sections would be duplicates.
src=$(cd "$(dirname "$0")/../.." && pwd)
"$stemd" --config "$src/config/stemd.yaml" --config "$tmp/camera_fragment.yaml" --check-config >"$tmp/check.out" 2>&1 ||
  fail "stemd --check-config rejects the layered fragment: $(cat "$tmp/check.out")"
cat "$src/config/stemd.yaml" "$tmp/camera_fragment.yaml" >"$tmp/pasted.yaml"
rc=0
"$stemd" --config "$tmp/pasted.yaml" --check-config >/dev/null 2>"$tmp/check.err" || rc=$?
[ $rc -eq 2 ] && grep -q ": duplicate section (first on line" "$tmp/check.err" ||
  fail "pasted fragment: exit $rc $(cat "$tmp/check.err")"
# An error in a layer names that file and its line.
{ cat "$tmp/camera_fragment.yaml"; printf '  widht_px: 640\n'; } >"$tmp/bad_fragment.yaml"
line=$(wc -l <"$tmp/bad_fragment.yaml")
rc=0
"$stemd" --config "$src/config/stemd.yaml" --config "$tmp/bad_fragment.yaml" --check-config >/dev/null 2>"$tmp/check.err" ||
  rc=$?
[ $rc -eq 2 ] && grep -q "^stemd: $tmp/bad_fragment.yaml:$line: key 'source.widht_px': unknown key" "$tmp/check.err" ||
  fail "bad layer: exit $rc $(cat "$tmp/check.err")"

# The fragment's camera against the rendering's: height within 1 %, angles
# within 0.3 degrees (intrinsics fitted, not given).
read -r height roll pitch yaw x y <"$tmp/img/truth.txt"
value() { sed -n "s/^  $1: //p" "$tmp/camera_fragment.yaml"; }
awk -v h="$(value height_mm)" -v th="$height" -v r="$(value roll_deg)" -v tr="$roll" \
  -v p="$(value pitch_deg)" -v tp="$pitch" -v w="$(value yaw_deg)" -v tw="$yaw" '
  function abs(v) { return v < 0 ? -v : v }
  BEGIN { exit !(abs(h / th - 1) < 0.01 && abs(r - tr) < 0.3 && abs(p - tp) < 0.3 && abs(w - tw) < 0.3) }' ||
  fail "fragment pose off: $(cat "$tmp/camera_fragment.yaml")"

# --- usage errors: exit 2 with a message
expect_usage() {
  local what="$1" pattern="$2"
  shift 2
  set +e
  "$calibrate" "$@" >"$tmp/u.out" 2>"$tmp/u.err"
  local rc=$?
  set -e
  [ "$rc" -eq 2 ] || fail "$what: exit $rc, not 2"
  grep -q -- "$pattern" "$tmp/u.err" || fail "$what: message '$(cat "$tmp/u.err")' lacks '$pattern'"
}
expect_usage "no subcommand" "subcommand"
expect_usage "bad board" "expected WxH" intrinsics --board 9 --square-mm 25 --out "$tmp/x.yaml" "$tmp/img/view_00.png"
expect_usage "missing --square-mm" "square-mm" intrinsics --board 9x6 --out "$tmp/x.yaml" "$tmp/img/view_00.png"
expect_usage "negative square" "square" intrinsics --board 9x6 --square-mm -2 --out "$tmp/x.yaml" "$tmp/img/view_00.png"
expect_usage "unreadable image" "nope.png: cannot open: No such file or directory" intrinsics --board 9x6 \
  --square-mm 25 --out "$tmp/x.yaml" "$tmp/nope.png"
head -c 2000 "$tmp/img/view_00.png" > "$tmp/cut.png"
expect_usage "cut-off image" "cut.png: cannot decode: PNG cut off" intrinsics --board 9x6 --square-mm 25 \
  --out "$tmp/x.yaml" "$tmp/cut.png"
expect_usage "unknown option" "--frobnicate" ground --board 11x8 --square-mm 25 --calibration "$tmp/camera.yaml" \
  --board-x-mm 0 --board-y-mm 0 --out "$tmp/f.yaml" --frobnicate "$tmp/img/ground.png"
expect_usage "missing calibration" "missing.yaml" ground --board 11x8 --square-mm 25 --calibration "$tmp/missing.yaml" \
  --board-x-mm 0 --board-y-mm 0 --out "$tmp/f.yaml" "$tmp/img/ground.png"
expect_usage "bad forward" "--forward" ground --board 11x8 --square-mm 25 --calibration "$tmp/camera.yaml" \
  --board-x-mm 0 --board-y-mm 0 --forward sideways --out "$tmp/f.yaml" "$tmp/img/ground.png"
"$calibrate" --help >/dev/null || fail "--help"

# Too few views with the board: exit 1, not a usage error.
set +e
"$calibrate" intrinsics --board 9x6 --square-mm 25 --out "$tmp/y.yaml" "$tmp/img/view_00.png" "$tmp/img/blank.png" \
  >/dev/null 2>"$tmp/few.err"
rc=$?
set -e
[ "$rc" -eq 1 ] || fail "two views: exit $rc, not 1"
grep -q "at least 3 views" "$tmp/few.err" || fail "two views: $(cat "$tmp/few.err")"
echo "ok"
