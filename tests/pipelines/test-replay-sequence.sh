#!/usr/bin/env bash
# pipelines/replay-sequence.sh on the committed fixtures tests/fixtures/seq-static and seq-moving
# (8 frames each, 640x480, 7 fps, with calibration and ground truth; in seq-moving the tree
# drives out of the view's left border from frame 4 on): 8 treemetrics messages each, with a
# tree at the true distance (1.5%), size (6%; a clipped extent only as a lower bound) and
# thickness (25%), 1/7 s apart (check-treemetrics.py).
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for seq in seq-static seq-moving; do
  fx=$src/tests/fixtures/$seq
  timeout 100 bash "$src/pipelines/replay-sequence.sh" "$fx" >"$tmp/$seq.log" 2>&1 ||
    { tail -20 "$tmp/$seq.log"; echo "FAIL: the replay of $seq failed"; exit 1; }
  echo "$seq:"
  python3 "$src/tests/pipelines/check-treemetrics.py" "$tmp/$seq.log" "$fx/truth.json" 8 ||
    { echo "FAIL: measurements of $seq"; exit 1; }
done
echo "OK: 2 x 8 frames replayed and measured"
