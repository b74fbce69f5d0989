#!/usr/bin/env bash
# The README's main command: installs what is missing, configures, builds, and runs the main job
# on the embedded synthetic orchard (no camera, no files needed).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
bash scripts/build.sh
build=${TREESTEREO_BUILD_DIR:-build}
echo "treestereo: built in $build"
