#!/usr/bin/env bash
# Makes a recording directory whose frames.csv points at a CWFID copy (the
# data stays where it is; its licence forbids copying it into the repo).
#   tools/cwfid-recording.sh CWFID_DIR OUT_DIR
# CWFID_DIR holds images/NNN_image.png and masks/NNN_mask.png (mask 0 = vegetation),
# and, for the class column, annotations/NNN_annotation.png (green crop, red weed).
# The class maps (0 soil, 1 crop, 2 weed: the annotation's colour on the
# mask's vegetation pixels) are rendered into OUT_DIR/class/ by stemd-classmap,
# taken from $STEMD_CLASSMAP, else build/release/tools/, else PATH.
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 CWFID_DIR OUT_DIR" >&2; exit 2; }
src=$(cd "$1" && pwd)
out=$2
[ -d "$src/images" ] && [ -d "$src/masks" ] || { echo "$0: $src has no images/ and masks/" >&2; exit 2; }
classmap=${STEMD_CLASSMAP:-}
if [ -z "$classmap" ]; then
  here=$(cd "$(dirname "$0")" && pwd)
  if [ -x "$here/../build/release/tools/stemd-classmap" ]; then
    classmap=$here/../build/release/tools/stemd-classmap
  else
    classmap=$(command -v stemd-classmap || true)
  fi
fi
with_class=0
if [ -d "$src/annotations" ]; then
  if [ -n "$classmap" ] && [ -x "$classmap" ]; then
    with_class=1
    mkdir -p "$out/class"
  else
    echo "$0: stemd-classmap not found (build it, or set STEMD_CLASSMAP): no class column" >&2
  fi
fi
mkdir -p "$out"
{
  if [ $with_class -eq 1 ]; then echo "t_ns,rgb,nir,mask,class"; else echo "t_ns,rgb,nir,mask"; fi
  i=0
  for image in "$src"/images/*_image.png; do
    id=$(basename "$image" _image.png)
    mask="$src/masks/${id}_mask.png"
    [ -f "$mask" ] || { echo "$0: no mask for $image" >&2; exit 1; }
    if [ $with_class -eq 1 ]; then
      annotation="$src/annotations/${id}_annotation.png"
      class=
      if [ -f "$annotation" ]; then
        "$classmap" --mask "$mask" --mask-vegetation zero "$annotation" "$out/class/$id.png" >/dev/null
        class=class/$id.png
      fi
      echo "$((i * 100000000)),$image,,$mask,$class"
    else
      echo "$((i * 100000000)),$image,,$mask"
    fi
    i=$((i + 1))
  done
} >"$out/frames.csv"
echo "$out/frames.csv: $(($(wc -l <"$out/frames.csv") - 1)) frames"
