#!/usr/bin/env bash
# Regenerates docs/images/dense_vs_38_a_yn_question.png (docs/quality.md, "Dense control sets"):
# one row of frames of a real recording on the 38-FDP rig (`ict-face`, top) and the same frames on
# the dense kinect121 rig (`ict-face.kinect121`, bottom).
#
#   tools/dense_sheets.sh [MIMIC]
#
# MIMIC defaults to target/release/mimic. Needs a Vulkan driver (lavapipe will do) and
# ImageMagick's `convert` (CONVERT=/usr/bin/convert if another `convert` comes first on the PATH).
# Run from the repository root.
set -euo pipefail
bin=${1:-target/release/mimic}
convert=${CONVERT:-convert}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rec=recordings/a_yn_question.kinect121.jsonl
frames=0,110,300,450,660,900,1200
for rig in ict-face ict-face.kinect121; do
  "$bin" render "$rec" --rig "$rig" --frames "$frames" --size 512x512 --out "$tmp/$rig" >/dev/null
  # The face of each 512x512 render: a 240x280 crop.
  for f in "$tmp/$rig"/frame_*.png; do
    "$convert" "$f" -crop 240x280+150+90 +repage "${f%.png}_face.png"
  done
  "$convert" "$tmp/$rig"/frame_*_face.png +append "$tmp/$rig.png"
done
"$convert" "$tmp/ict-face.png" "$tmp/ict-face.kinect121.png" -append docs/images/dense_vs_38_a_yn_question.png
echo "wrote docs/images/dense_vs_38_a_yn_question.png (frames $frames)"
