#!/usr/bin/env bash
# pipelines/replay-sequence.sh on the committed fixtures (check-treemetrics.py says what is
# checked and why):
#   seq-static, seq-moving: 8 frames each, 640x480 JPEG, 7 fps; in seq-moving the tree drives out
#     of the view's left border from frame 4 on. Per frame: a tree at the true distance (1.5%),
#     size (6%; a clipped extent only as a lower bound) and thickness (25%), 1/7 s apart.
#   sweep-1296: the accuracy targets' conditions, 5 pairs 1296x972 JPEG, trunk at 1.8-2.2 m, seeds 1-5:
#     distance bias <= 0.5% and error std <= 0.5 cm over the frames (the targets), thickness
#     within 20% (the target), height and width 1.5% root mean square error over the frames (the
#     target) and within 3% per frame.
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for run in seq-static:8:jpeg640 seq-moving:8:jpeg640 sweep-1296:5:sweep1296; do
  IFS=: read -r seq frames profile <<<"$run"
  fx=$src/tests/fixtures/$seq
  timeout 100 bash "$src/pipelines/replay-sequence.sh" "$fx" >"$tmp/$seq.log" 2>&1 ||
    { tail -20 "$tmp/$seq.log"; echo "FAIL: the replay of $seq failed"; exit 1; }
  echo "$seq:"
  python3 "$src/tests/pipelines/check-treemetrics.py" "$tmp/$seq.log" "$fx/truth.json" "$frames" \
    --profile "$profile" || { echo "FAIL: measurements of $seq"; exit 1; }
done
echo "OK: 3 sequences (8 + 8 + 5 frames) replayed and measured"
