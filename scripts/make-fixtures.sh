#!/usr/bin/env bash
# Regenerates tests/fixtures/ byte for byte from the synthetic orchard (treestereo-synth).
#   seq-static: seed 1, trunk at 2.0 m, the rig standing still, nominal light
#   seq-moving: seed 7, trunk at 1.8 m, the sprayer driving at 0.5 m/s (7 fps), light 0.8
#   seq-orchard: the orchard scene (neighbours in the row, a row behind, grass), seed 3, trunk
#     at 2.0 m, driving slowly (0.3 m/s, 7 fps), light 1.0, JPEG quality 80 (under 1 MB)
# Each: 8 frame pairs 640x480 as left_%04d.jpg / right_%04d.jpg, calibration.yml, truth.json.
#   sweep-1296: the accuracy targets' conditions at the size they are for: 5 pairs 1296x972
#     (JPEG quality 90), pair k (0..4) is tree seed k+1 with its trunk at 1.8 + 0.1 k m; one
#     calibration (the rig does not change), truth.json with the frames of the five renders.
#   seq-driveby: a drive-by along the orchard row at 2 m/s (7 fps), seed 4, trunks at 2.0 m, gaps
#     0.15-0.8 m, the canopies of trees 1 and 2 grown into each other; 16 pairs 640x480, JPEG
#     quality 80: five trees pass wholly through the view.
# FIXTURES_OUT=DIR writes elsewhere (the test that checks reproducibility does).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${TREESTEREO_BUILD_DIR:-build}
synth="$build/tools/treestereo-synth"
[ -x "$synth" ] || { echo "make-fixtures: build first (scripts/build.sh)" >&2; exit 1; }
out=${FIXTURES_OUT:-tests/fixtures}
rm -rf "$out/seq-static" "$out/seq-moving" "$out/seq-orchard" "$out/seq-driveby" "$out/sweep-1296"
"$synth" -o "$out/seq-static" --seed 1 --distance 2.0 --size 640x480 --frames 8 --format jpg
"$synth" -o "$out/seq-moving" --seed 7 --distance 1.8 --speed 0.5 --fps 7 --light 0.8 \
  --size 640x480 --frames 8 --format jpg
"$synth" -o "$out/seq-orchard" --scene orchard --seed 3 --distance 2.0 --speed 0.3 --fps 7 \
  --light 1.0 --size 640x480 --frames 8 --format jpg --quality 80
"$synth" -o "$out/seq-driveby" --scene orchard --seed 4 --distance 2.0 --speed 2 --fps 7 \
  --size 640x480 --frames 16 --format jpg --quality 80 --row-gap 0.15:0.8 --touching-pair 1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out/sweep-1296"
for k in 0 1 2 3 4; do
  "$synth" -o "$tmp/$k" --seed $((k + 1)) --distance "$(awk "BEGIN { print 1.8 + 0.1 * $k }")" \
    --size 1296x972 --frames 1 --format jpg --quality 90 >/dev/null
  for v in left right; do cp "$tmp/$k/${v}_0000.jpg" "$out/sweep-1296/${v}_000$k.jpg"; done
done
cp "$tmp/0/calibration.yml" "$out/sweep-1296/"
python3 - "$tmp" "$out/sweep-1296/truth.json" <<'PY'
import json, sys
renders = [json.load(open('%s/%d/truth.json' % (sys.argv[1], k))) for k in range(5)]
truth = {key: renders[0][key] for key in ('width', 'height', 'framerate', 'baseline_mm', 'light')}
truth['frames'] = []
for k, r in enumerate(renders):
    frame = dict(r['frames'][0], frame=k, seed=r['seed'], trunk_distance_m=r['trunk_distance_m'])
    truth['frames'].append(frame)
json.dump(truth, open(sys.argv[2], 'w'))
PY
du -sh "$out"
