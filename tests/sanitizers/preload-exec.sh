#!/bin/sh
# Runs the stock GStreamer tool this link is named after (gst-launch-1.0, gst-inspect-1.0,
# gst-discoverer-1.0) with the sanitizer runtimes preloaded: the tools are not instrumented but
# load the instrumented treestereo plugin, whose ASan runtime must come first. Put
# tests/sanitizers/bin first in PATH (scripts/test-sanitizers.sh does) and the script tests
# run their usual commands.
name=$(basename "$0")
here=$(cd "$(dirname "$0")" && pwd)
real=
IFS=:
for d in $PATH; do
  [ "$d" = "$here" ] && continue
  if [ -x "$d/$name" ]; then real="$d/$name"; break; fi
done
unset IFS
[ -n "$real" ] || { echo "preload-exec: no $name in PATH" >&2; exit 127; }
LD_PRELOAD="${TREESTEREO_SANITIZER_PRELOAD}${LD_PRELOAD:+:$LD_PRELOAD}" exec "$real" "$@"
