#!/usr/bin/env bash
# Builds what the property stress test needs with ThreadSanitizer in build-tsan/ (the library,
# the meta library, the plugin and tests/elements/test_property_stress.cpp) and runs that test:
# frames stream through the whole chain while another thread changes every property that is
# mutable while PLAYING. Any ThreadSanitizer report fails it (halt_on_error); suppressions are in
# tests/sanitizers/tsan.supp (GLib/GStreamer internals only, each explained).
#   TREESTEREO_TSAN_BUILD_DIR  build directory (default build-tsan)
#   TREESTEREO_STRESS_FRAMES   frames to stream (default 150)
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
build=${TREESTEREO_TSAN_BUILD_DIR:-build-tsan}

start=$(date +%s)
if [ ! -f "$build/build.ninja" ]; then
  # b_lundef=false: the plugin leaves the ThreadSanitizer runtime to the test executable.
  meson setup "$build" -Dwerror=true -Db_sanitize=thread -Db_lundef=false -Dbench=disabled \
    -Daravis=disabled || exit 1
fi
meson compile -C "$build" tests/elements/test-property_stress gst/elements/gsttreestereo || exit 1
built=$(date +%s)

export TSAN_OPTIONS="halt_on_error=1:exitcode=66:second_deadlock_stack=1:print_suppressions=1:suppressions=$root/tests/sanitizers/tsan.supp"
# GSlice's magazines recycle memory behind ThreadSanitizer's back: plain malloc instead.
export G_SLICE=always-malloc
# The instrumented plugin cannot be loaded by the stock (uninstrumented) gst-plugin-scanner:
# the test loads it in-process, and no system plugin is needed.
export GST_REGISTRY_FORK=no
export GST_PLUGIN_SYSTEM_PATH_1_0=
export TREESTEREO_STRESS_FRAMES=${TREESTEREO_STRESS_FRAMES:-150}

meson test -C "$build" --print-errorlogs --timeout-multiplier 4 stress-property-changes
status=$?
end=$(date +%s)
echo "ThreadSanitizer: build $((built - start)) s, test $((end - built)) s, exit status $status"
exit $status
