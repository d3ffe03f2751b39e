#!/usr/bin/env bash
# Regenerates the contact sheets of docs/quality.md's "Seams and the frozen border" section:
# the RBF's frozen border and the lower lip before / after the border fade (issue 14).
#
#   tools/seams_sheets.sh BEFORE_MIMIC AFTER_MIMIC
#
# BEFORE_MIMIC is a `mimic` built from the commit before the fade (mimic_solve::border), AFTER_MIMIC
# one built with it (e.g. target/debug/mimic). Needs a Vulkan driver (lavapipe will do) and
# ImageMagick's `convert` to tile. Run from the repository root.
set -euo pipefail
before=${1:?usage: $0 BEFORE_MIMIC AFTER_MIMIC}
after=${2:?usage: $0 BEFORE_MIMIC AFTER_MIMIC}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# row NAME BIN RECORDING FRAMES [render options...]: one row of 192x192 tiles.
row() {
  local name=$1 bin=$2 rec=$3 frames=$4
  shift 4
  "$bin" render "$rec" --rig ict-face --frames "$frames" --size 192x192 --out "$tmp/$name" "$@" >/dev/null
  convert "$tmp/$name"/frame_*.png +append "$tmp/$name.png"
}

# The frozen border on the largest jaw motion of a_yn_question: lit, then |u| as heat, where a
# step at the neck shows as a hard colour edge.
rec=recordings/a_yn_question.kinect121.jsonl
row border_before "$before" $rec 109,110,111
row border_after "$after" $rec 109,110,111
row heat_before "$before" $rec 109,110,111 --heat displacement --heat-scale 2
row heat_after "$after" $rec 109,110,111 --heat displacement --heat-scale 2
convert "$tmp"/border_before.png "$tmp"/border_after.png "$tmp"/heat_before.png \
  "$tmp"/heat_after.png -append docs/images/rbf_border_a_yn_question_109_111.png

# The lower lip on the largest opening of a_doubt_question (the frame
# tests/integration/seams.rs picks), with the RBF before and after, then the Laplacian.
rec=recordings/a_doubt_question.kinect121.jsonl
frames=${LIP_FRAMES:-}
if [ -n "$frames" ]; then
  row lip_before "$before" $rec "$frames"
  row lip_after "$after" $rec "$frames"
  row lip_laplacian "$after" $rec "$frames" --solver laplacian
  convert "$tmp"/lip_before.png "$tmp"/lip_after.png "$tmp"/lip_laplacian.png -append \
    docs/images/rbf_lower_lip_a_doubt_question.png
fi
