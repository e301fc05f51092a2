# Sourced by the real-data scripts (eval-real.sh, bench-real.sh,
# eval-robust.sh): how a folder of DATA_DIR is recognised and read, so that
# other frames of the same sources (CWFID's test split, BoniRob frames kept
# aside) are found whatever their folder names, and every script finds the
# same sets.

# A folder's layout: "cwfid" (images/NNN_image.png and masks/NNN_mask.png, 0
# marking vegetation), "recording" (frames.csv), "empty" (either layout, but
# no frame in it), or nothing.
real_set_layout() {
  if [ -d "$1/images" ] && [ -d "$1/masks" ]; then
    if compgen -G "$1/images/*_image.png" >/dev/null; then echo cwfid; else echo empty; fi
  elif [ -f "$1/frames.csv" ]; then
    if [ "$(recording_frames "$1")" -gt 0 ]; then echo recording; else echo empty; fi
  fi
}

# Why a folder of DATA_DIR is not scored, on stderr: SCRIPT NAME LAYOUT.
real_set_skipped() {
  if [ "$3" = empty ]; then
    echo "$1: $2: no frames in it: skipped" >&2
  else
    echo "$1: $2: neither CWFID's layout (images/, masks/) nor a recording (frames.csv): skipped" >&2
  fi
}

# A set's ground sampling distance in mm per pixel, empty when unknown: from
# STEMD_EVAL_GSD ("name=MM name=MM"), else by the source its folder name
# starts with (the data README's figures: a camera and its height above the
# ground, so other frames of the same source share them), else CWFID's for
# CWFID's layout.
real_set_gsd() {  # name layout
  local kv
  for kv in ${STEMD_EVAL_GSD:-}; do
    if [ "${kv%%=*}" = "$1" ]; then echo "${kv#*=}"; return; fi
  done
  case $1 in
    bonirob*) echo 0.395; return ;;  # measured from plants seen in two frames 265 mm apart
    cwfid*) echo 0.11; return ;;     # the JAI camera about 450 mm above the ground
  esac
  if [ "${2:-}" = cwfid ]; then echo 0.11; fi
}

# Whether a recording's frames.csv has a non-empty value in a column.
recording_has_column() {  # dir column
  awk -F, -v want="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == want) c = i; next }
                        c && $c != "" { found = 1; exit } END { exit !found }' "$1/frames.csv"
}

# How many frames a recording's frames.csv lists.
recording_frames() {
  awk 'END { print NR - 1 }' "$1/frames.csv"
}

# A recording's frame size, "WIDTH HEIGHT", from its first frame.
recording_frame_size() {  # dir
  /usr/bin/python3 - "$1" <<'PY'
import csv, os, sys, cv2
row = next(csv.DictReader(open(os.path.join(sys.argv[1], "frames.csv"))))
image = cv2.imread(os.path.join(sys.argv[1], row["rgb"]), cv2.IMREAD_UNCHANGED)
print(image.shape[1], image.shape[0])
PY
}
