#!/usr/bin/env bash
# Regenerates docs/gate.md's before/after contact sheet of frames 99-109 of a_yn_question.kinect121
# (a CANDIDE-3 fit failure, issue 14): each solver with the plausibility gate off (`--no-gate`, the
# frames pass through) and on (the default: held, then eased).
#
#   tools/gate_sheet.sh [MIMIC]      (default target/debug/mimic)
#
# Needs a Vulkan driver (lavapipe will do) and ImageMagick's `convert` (CONVERT=… to choose one).
# Run from the repository root.
set -euo pipefail
bin=${1:-target/debug/mimic}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
convert=${CONVERT:-convert}
rec=recordings/a_yn_question.kinect121.jsonl
frames=99,101,103,105,107,109

# row NAME [render options...]: the face of 384x384 renders, cropped to 256x256 tiles.
row() {
  local name=$1
  shift
  "$bin" render "$rec" --rig ict-face --frames "$frames" --size 384x384 --out "$tmp/$name" "$@" >/dev/null
  for f in "$tmp/$name"/frame_*.png; do
    "$convert" "$f" -crop "256x256+64+70" +repage "${f%.png}_crop.png"
  done
  "$convert" "$tmp/$name"/frame_*_crop.png +append "$tmp/$name.png"
}
row rbf_off --no-gate
row rbf_on
row laplacian_off --no-gate --solver laplacian
row laplacian_on --solver laplacian
"$convert" "$tmp"/rbf_off.png "$tmp"/rbf_on.png "$tmp"/laplacian_off.png "$tmp"/laplacian_on.png \
  -append -strip -colors 256 PNG8:docs/images/gate_a_yn_question_99_109.png
