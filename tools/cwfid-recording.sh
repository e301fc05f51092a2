#!/usr/bin/env bash
# Makes a recording directory whose frames.csv points at a CWFID copy (the
# data stays where it is; its licence forbids copying it into the repo).
#   tools/cwfid-recording.sh CWFID_DIR OUT_DIR
# CWFID_DIR holds images/NNN_image.png and masks/NNN_mask.png (mask 0 = vegetation).
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 CWFID_DIR OUT_DIR" >&2; exit 2; }
src=$(cd "$1" && pwd)
out=$2
[ -d "$src/images" ] && [ -d "$src/masks" ] || { echo "$0: $src has no images/ and masks/" >&2; exit 2; }
mkdir -p "$out"
{
  echo "t_ns,rgb,nir,mask"
  i=0
  for image in "$src"/images/*_image.png; do
    id=$(basename "$image" _image.png)
    mask="$src/masks/${id}_mask.png"
    [ -f "$mask" ] || { echo "$0: no mask for $image" >&2; exit 1; }
    echo "$((i * 100000000)),$image,,$mask"
    i=$((i + 1))
  done
} >"$out/frames.csv"
echo "$out/frames.csv: $(($(wc -l <"$out/frames.csv") - 1)) frames"
