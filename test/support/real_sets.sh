# shellcheck shell=bash
# Sourced after script.sh by the tests of the real-data scripts
# (eval-real.sh, bench-real.sh, eval-robust.sh), which find sets by layout.

# check_absent_and_missing_tools SCRIPT: an absent data folder skips (77)
# with a message; tools that are not there exit 2, naming stemd-detect.
check_absent_and_missing_tools() {
  local code code2
  set +e
  "$1" "$tmp/absent" "$tmp/out" 2>"$tmp/err"
  code=$?
  STEMD_TOOLS=$tmp "$1" "$tmp" "$tmp/out" 2>"$tmp/err2"
  code2=$?
  set -e
  [ "$code" = 77 ] || fail "an absent data folder exited $code, not 77"
  grep -q "absent" "$tmp/err" || fail "an absent data folder without a message: $(cat "$tmp/err")"
  [ "$code2" = 2 ] || fail "missing tools exited $code2, not 2"
  grep -q "no $tmp/stemd-detect" "$tmp/err2" || fail "missing tools without naming them: $(cat "$tmp/err2")"
}

# cwfid_layout RECORDING DIR FRAME...: CWFID's layout under another name,
# from frames of a generated recording: images/NNN_image.png, and
# masks/NNN_mask.png with 0 for vegetation and 255 for soil (CWFID's way
# round). Frame k of the list becomes NNN = k.
cwfid_layout() {
  local recording=$1 dir=$2 k=0 frame
  shift 2
  mkdir -p "$dir/images" "$dir/masks"
  for frame in "$@"; do
    cp "$recording/rgb/$frame.png" "$dir/images/$(printf %03d "$k")_image.png"
    /usr/bin/python3 - "$recording/mask/$frame.png" "$dir/masks/$(printf %03d "$k")_mask.png" <<'PY'
import sys, cv2
mask = cv2.imread(sys.argv[1], cv2.IMREAD_GRAYSCALE)
cv2.imwrite(sys.argv[2], 255 - (mask > 0).astype("uint8") * 255)
PY
    k=$((k + 1))
  done
}

# folders_of_no_set DIR: junk (an empty folder, of neither layout), and two
# sets of no frames: empty-e (CWFID's layout) and empty-f (a recording).
folders_of_no_set() {
  mkdir -p "$1/junk" "$1/empty-e/images" "$1/empty-e/masks" "$1/empty-f"
  echo "t_ns,rgb,nir,mask" >"$1/empty-f/frames.csv"
}

# unseen_sets DIR: sets under names no script knows: field-a (a recording
# of two 320 x 240 frames with NIR, masks and stems.csv), unknown-c (the
# same frames, for a set whose GSD is not known), cwfid-d (field-a's first
# frame in CWFID's layout), and the folders_of_no_set.
unseen_sets() {
  folders_of_no_set "$1"
  "$tools/stemd-synth" --out "$1/field-a" --preset late --frames 2 --width 320 --height 240 --seed 3 >/dev/null
  cp -r "$1/field-a" "$1/unknown-c"
  cwfid_layout "$1/field-a" "$1/cwfid-d" 000000
}

# check_skipped ERR_FILE: the folders_of_no_set were each named on stderr
# with the reason.
check_skipped() {
  grep -q "junk: neither CWFID's layout" "$1" || fail "the folder of no layout was not named: $(cat "$1")"
  grep -q "empty-e: no frames in it: skipped" "$1" || fail "the empty CWFID set was not named: $(cat "$1")"
  grep -q "empty-f: no frames in it: skipped" "$1" || fail "the empty recording was not named: $(cat "$1")"
}
