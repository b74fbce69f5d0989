#!/usr/bin/env bash
# pipelines/replay-sequence.sh on the committed fixture tests/fixtures/seq-static (8 frames,
# 640x480, 7 fps, with its calibration and ground truth): 8 treemetrics messages, each with a tree
# at the true distance (1.5%), size (6%) and thickness (25%), 1/7 s apart (check-treemetrics.py).
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
fx=$src/tests/fixtures/seq-static
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
timeout 100 bash "$src/pipelines/replay-sequence.sh" "$fx" >"$tmp/run.log" 2>&1 ||
  { tail -20 "$tmp/run.log"; echo "FAIL: the replay failed"; exit 1; }
python3 "$src/tests/pipelines/check-treemetrics.py" "$tmp/run.log" "$fx/truth.json" 8 ||
  { echo "FAIL: measurements"; exit 1; }
echo "OK: 8 frames replayed and measured"
