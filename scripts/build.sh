#!/usr/bin/env bash
# Configures (once) and builds treestereo in ./build (or $TREESTEREO_BUILD_DIR).
# Extra arguments go to `meson setup` on the first configuration.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${TREESTEREO_BUILD_DIR:-build}
if [ ! -f "$build/build.ninja" ]; then
  meson setup "$build" -Dwerror=true "$@"
fi
meson compile -C "$build"
