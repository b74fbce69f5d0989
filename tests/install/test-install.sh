#!/usr/bin/env bash
# Installs the build into a scratch prefix (scratch-install.sh), checks that everything
# promised is there, then builds tests/install/consumer.c with pkg-config gsttreestereo-1.0
# alone and runs it.
. "$(dirname "$0")/scratch-install.sh"

[ -f "$root/include/gstreamer-1.0/gst/treestereo/treestereo-meta.h" ] || fail "header not installed"
ls "$installed_libdir"/libgsttreestereo-1.0.so* >/dev/null || fail "meta library not installed"
if [ -d "$build/gst/elements" ] && ls "$build"/gst/elements/libgsttreestereo.so >/dev/null 2>&1; then
  [ -f "$installed_libdir/gstreamer-1.0/libgsttreestereo.so" ] || fail "plugin not installed"
fi
for t in "$build"/tools/treestereo-*; do
  [ -x "$t" ] && [ -f "$t" ] || continue
  [ -x "$root/bin/$(basename "$t")" ] || fail "tool $(basename "$t") not installed"
done

flags=$(pkg-config --cflags --libs gsttreestereo-1.0) \
  || fail "pkg-config gsttreestereo-1.0 failed"
case "$flags" in *"$dest"*) ;; *) fail "pkg-config flags do not point into the installed copy: $flags" ;; esac
# shellcheck disable=SC2086
cc -Wall -Werror -o "$dest/consumer" "$src/tests/install/consumer.c" $flags || fail "consumer did not compile"
LD_LIBRARY_PATH="$installed_libdir" "$dest/consumer"
