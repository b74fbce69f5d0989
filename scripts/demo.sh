#!/usr/bin/env bash
# The README's main command: installs what is missing, configures, builds, and runs the main job
# (treestereo-measure) on the embedded synthetic orchard row (the tree in front among its
# neighbours, the next row behind) - no camera, no files needed. Prints a
# line of measurements per stereo frame and one per tree as it leaves the view, and writes
# out/demo.jsonl (one JSON object per frame), out/demo.mp4 (the annotated side-by-side video),
# out/demo-trees.jsonl (one record per tree), out/demo-row-map.csv + .png (the row's canopy
# map: travel along x, height along y, colour = distance), out/demo-sections.jsonl (the valve
# commands of the nozzle sections, timed for the travel) and out/demo-sections.png (the row map
# with each section's valve timeline under it). Extra arguments go to
# treestereo-measure (see build/tools/treestereo-measure --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
bash scripts/build.sh >/dev/null
build=${TREESTEREO_BUILD_DIR:-build}
export GST_PLUGIN_PATH_1_0="$PWD/$build/gst/elements${GST_PLUGIN_PATH_1_0:+:$GST_PLUGIN_PATH_1_0}"
mkdir -p out
"$build/tools/treestereo-measure" --synthetic --frames 40 --speed 1.0 \
  --json out/demo.jsonl --record out/demo.mp4 \
  --trees out/demo-trees.jsonl --row-map out/demo-row-map.csv \
  --sections out/demo-sections.jsonl "$@"
echo "treestereo: measurements in out/demo.jsonl, annotated video in out/demo.mp4," \
  "tree records in out/demo-trees.jsonl, row map in out/demo-row-map.csv and .png," \
  "nozzle-section commands in out/demo-sections.jsonl, valve timeline in out/demo-sections.png"
