#!/usr/bin/env bash
# pipelines/replay-sequence.sh on the committed orchard fixture seq-orchard (8 pairs 640x480
# JPEG, seed 3, the tree in front at 2.0 m among its neighbours, grass, the next row behind),
# checked against its truth.json by check-orchard.py (it says what and why):
#   the default chain (exgsegment keep=all, stereodepth canopy=tree): a tree in every frame, its
#     width and height those of the tree in front within 8 % (all but one frame; medians 3 %);
#   stereodepth canopy=off: the colour mask of all the vegetation, the width off by more than
#     30 %: what deciding the canopy in depth buys.
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
fx=$src/tests/fixtures/seq-orchard
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for canopy in tree off; do
  STEREODEPTH="canopy=$canopy" timeout 100 bash "$src/pipelines/replay-sequence.sh" "$fx" \
    >"$tmp/$canopy.log" 2>&1 ||
    { tail -20 "$tmp/$canopy.log"; echo "FAIL: the replay of seq-orchard (canopy=$canopy) failed"; exit 1; }
  python3 "$src/tests/pipelines/check-orchard.py" "$tmp/$canopy.log" "$fx/truth.json" 8 \
    --canopy "$canopy" || { echo "FAIL: measurements of seq-orchard with canopy=$canopy"; exit 1; }
done
echo "OK: seq-orchard replayed with canopy=tree (the tree in front) and canopy=off (the colour mask)"
