#!/usr/bin/env bash
# The application example (tests/app/treestereo-app.c, docs/application.md) built against the
# installed header and pkg-config file alone (scratch-install.sh), run with the installed plugin
# only: it embeds the whole chain, reads the metrics meta in a pad probe and the treemetrics
# messages on the bus, and fails unless every frame has a tree and both agree.
. "$(dirname "$0")/scratch-install.sh"
[ -f "$installed_libdir/gstreamer-1.0/libgsttreestereo.so" ] ||
  { echo "SKIP: the plugin is not built"; exit 77; }
flags=$(pkg-config --cflags --libs gsttreestereo-1.0) || fail "pkg-config gsttreestereo-1.0 failed"
# shellcheck disable=SC2086
cc -Wall -Wextra -Werror -o "$dest/treestereo-app" "$src/tests/app/treestereo-app.c" $flags ||
  fail "the application did not compile"
export GST_REGISTRY_1_0="$dest/registry.bin" GST_PLUGIN_PATH_1_0="$installed_libdir/gstreamer-1.0"
LD_LIBRARY_PATH="$installed_libdir" timeout 150 "$dest/treestereo-app" 3 || fail "the application failed"
# The valve timeline example (spraycontrol's section commands, docs/spraying.md), likewise.
# shellcheck disable=SC2086
cc -Wall -Wextra -Werror -o "$dest/valve-timeline" "$src/tests/app/valve-timeline.c" $flags ||
  fail "the valve timeline example did not compile"
LD_LIBRARY_PATH="$installed_libdir" timeout 150 "$dest/valve-timeline" 8 >/dev/null ||
  fail "the valve timeline example failed"
