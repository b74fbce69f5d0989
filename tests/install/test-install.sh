#!/usr/bin/env bash
# Installs the build into a scratch prefix (meson install --destdir), checks that everything
# promised is there, then builds tests/install/consumer.c with pkg-config gsttreestereo-1.0
# alone and runs it.
set -euo pipefail
build=${TREESTEREO_BUILD_DIR:?}
src=${TREESTEREO_SOURCE_DIR:?}
dest=$(mktemp -d)
trap 'rm -rf "$dest"' EXIT

meson install -C "$build" --destdir "$dest" --no-rebuild --quiet >/dev/null

prefix=$(meson introspect "$build" --buildoptions | python3 -c \
  'import json,sys; print(next(o["value"] for o in json.load(sys.stdin) if o["name"]=="prefix"))')
libdir=$(meson introspect "$build" --buildoptions | python3 -c \
  'import json,sys; print(next(o["value"] for o in json.load(sys.stdin) if o["name"]=="libdir"))')
case "$libdir" in /*) ;; *) libdir="$prefix/$libdir" ;; esac
root="$dest$prefix"

fail() { echo "test-install: $*" >&2; exit 1; }
[ -f "$dest$libdir/pkgconfig/gsttreestereo-1.0.pc" ] || fail "no gsttreestereo-1.0.pc in $libdir/pkgconfig"
[ -f "$root/include/gstreamer-1.0/gst/treestereo/treestereo-meta.h" ] || fail "header not installed"
ls "$dest$libdir"/libgsttreestereo-1.0.so* >/dev/null || fail "meta library not installed"
if [ -d "$build/gst/elements" ] && ls "$build"/gst/elements/libgsttreestereo.so >/dev/null 2>&1; then
  [ -f "$dest$libdir/gstreamer-1.0/libgsttreestereo.so" ] || fail "plugin not installed"
fi
for t in "$build"/tools/treestereo-*; do
  [ -x "$t" ] && [ -f "$t" ] || continue
  [ -x "$root/bin/$(basename "$t")" ] || fail "tool $(basename "$t") not installed"
done

# The .pc file names its install prefix; point that one file at the scratch copy.
sed -i "s|^prefix=.*|prefix=$root|" "$dest$libdir/pkgconfig/gsttreestereo-1.0.pc"
export PKG_CONFIG_PATH="$dest$libdir/pkgconfig"
flags=$(pkg-config --cflags --libs gsttreestereo-1.0) \
  || fail "pkg-config gsttreestereo-1.0 failed"
case "$flags" in *"$dest"*) ;; *) fail "pkg-config flags do not point into the installed copy: $flags" ;; esac
# shellcheck disable=SC2086
cc -Wall -Werror -o "$dest/consumer" "$src/tests/install/consumer.c" $flags || fail "consumer did not compile"
LD_LIBRARY_PATH="$dest$libdir" "$dest/consumer"
