#!/usr/bin/env bash
# Regenerates tests/fixtures/ byte for byte from the synthetic orchard (treestereo-synth).
#   seq-static: seed 1, trunk at 2.0 m, the rig standing still, nominal light
#   seq-moving: seed 7, trunk at 1.8 m, the sprayer driving at 0.5 m/s (7 fps), light 0.8
# Each: 8 frame pairs 640x480 as left_%04d.jpg / right_%04d.jpg, calibration.yml, truth.json.
# FIXTURES_OUT=DIR writes elsewhere (the test that checks reproducibility does).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${TREESTEREO_BUILD_DIR:-build}
synth="$build/tools/treestereo-synth"
[ -x "$synth" ] || { echo "make-fixtures: build first (scripts/build.sh)" >&2; exit 1; }
out=${FIXTURES_OUT:-tests/fixtures}
rm -rf "$out/seq-static" "$out/seq-moving"
"$synth" -o "$out/seq-static" --seed 1 --distance 2.0 --size 640x480 --frames 8 --format jpg
"$synth" -o "$out/seq-moving" --seed 7 --distance 1.8 --speed 0.5 --fps 7 --light 0.8 \
  --size 640x480 --frames 8 --format jpg
du -sh "$out"
