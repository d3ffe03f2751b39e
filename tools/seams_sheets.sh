#!/usr/bin/env bash
# Regenerates the contact sheets of docs/quality.md's "Seams and the frozen border" section:
# the RBF's frozen border and the lower lip before / after the border fade (issue 14).
#
#   tools/seams_sheets.sh BEFORE_MIMIC AFTER_MIMIC
#
# BEFORE_MIMIC is a `mimic` built from the commit before the fade (mimic_solve::border), AFTER_MIMIC
# one built with it (e.g. target/debug/mimic). Needs a Vulkan driver (lavapipe will do) and
# ImageMagick's `convert` to tile (CONVERT=/usr/bin/convert if another `convert` comes first on the
# PATH). Run from the repository root.
set -euo pipefail
before=${1:?usage: $0 BEFORE_MIMIC AFTER_MIMIC}
after=${2:?usage: $0 BEFORE_MIMIC AFTER_MIMIC}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

convert=${CONVERT:-convert}

# row NAME BIN RECORDING FRAMES SIZE CROP [render options...]: one row of 192x192 tiles, each
# cropped at CROP (+x+y) from a SIZE render.
row() {
  local name=$1 bin=$2 rec=$3 frames=$4 size=$5 crop=$6
  shift 6
  "$bin" render "$rec" --rig ict-face --frames "$frames" --size "$size" --out "$tmp/$name" "$@" >/dev/null
  for f in "$tmp/$name"/frame_*.png; do
    "$convert" "$f" -crop "192x192$crop" +repage "${f%.png}_crop.png"
  done
  "$convert" "$tmp/$name"/frame_*_crop.png +append "$tmp/$name.png"
}
# The lower face (mouth, chin, jaw line, neck) of a 384x384 render; the mouth of a 768x768 one.
face="384x384 +96+150"
mouth="768x768 +236+360"

# The frozen border on the largest jaw motion of a_yn_question: lit, then |u| as heat (full
# scale 1 cm), where a step at the neck shows as a hard colour edge.
rec=recordings/a_yn_question.kinect121.jsonl
row lit_before "$before" $rec 109,110,111 $face
row lit_after "$after" $rec 109,110,111 $face
row heat_before "$before" $rec 109,110,111 $face --heat displacement --heat-scale 1
row heat_after "$after" $rec 109,110,111 $face --heat displacement --heat-scale 1
"$convert" "$tmp"/lit_before.png "$tmp"/lit_after.png "$tmp"/heat_before.png \
  "$tmp"/heat_after.png -append -strip -colors 256 PNG8:docs/images/rbf_border_a_yn_question_109_111.png

# The lower lip on the same frames, the largest opening of the recordings: the RBF before and
# after, then the Laplacian.
row mouth_before "$before" $rec 109,110,111 $mouth
row mouth_after "$after" $rec 109,110,111 $mouth
row mouth_laplacian "$after" $rec 109,110,111 $mouth --solver laplacian
"$convert" "$tmp"/mouth_before.png "$tmp"/mouth_after.png "$tmp"/mouth_laplacian.png -append \
  -strip -colors 256 PNG8:docs/images/rbf_lower_lip_a_yn_question_109_111.png
