#!/usr/bin/env bash
# The example crop/weed model for CWFID's camera (JAI AD-130GE, false
# colour, 0.11 mm/px, carrot seedlings), built from a CWFID copy: its class
# recording (cwfid-recording.sh) and stemd-train on all of its frames, which
# also prints the cross-validated figures. CWFID's licence (non-commercial
# research, no copies) keeps the model out of the repository, so each
# machine builds its own (about a minute). It holds for that camera and
# crop only: a field needs its own model (README, Crop or weed).
#   tools/cwfid-model.sh [CWFID_DIR [MODEL]]
#     defaults: ../shared/data/cwfid-train and out/models/cwfid.yaml; the
#     recording goes next to the model (cwfid-recording/).
# The tools come from $STEMD_TOOLS, else build/release/tools (built here).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
data=${1:-$here/../shared/data/cwfid-train}
model=${2:-$here/out/models/cwfid.yaml}
[ $# -le 2 ] || { echo "usage: $0 [CWFID_DIR [MODEL]]" >&2; exit 2; }
[ -d "$data/annotations" ] && [ -d "$data/images" ] ||
  { echo "$0: $data is no CWFID copy (images/, masks/, annotations/)" >&2; exit 2; }
tools=${STEMD_TOOLS:-}
if [ -z "$tools" ]; then
  cmake -S "$here" -B "$here/build/release" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$here/build/release" -j "$(nproc)" --target stemd-train stemd-classmap >/dev/null
  tools=$here/build/release/tools
fi
mkdir -p "$(dirname "$model")"
recording=$(dirname "$model")/cwfid-recording
STEMD_CLASSMAP="$tools/stemd-classmap" "$here/tools/cwfid-recording.sh" "$data" "$recording"
"$tools/stemd-train" --out "$model" --set camera.gsd_mm_per_px=0.11 "$recording"
echo "model: $model (classify.model, with camera.gsd_mm_per_px 0.11; frames: $recording)"
