#!/bin/sh
# The stock gst-plugin-scanner with the sanitizer runtimes preloaded, so it can load the
# instrumented treestereo plugin while building a test's registry. Leak checking is off here:
# this process loads every system plugin once and exits; leaks are checked in the tests.
LD_PRELOAD="${TREESTEREO_SANITIZER_PRELOAD}${LD_PRELOAD:+:$LD_PRELOAD}" \
ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0" \
  exec "$TREESTEREO_REAL_PLUGIN_SCANNER" "$@"
