# Sourced by the install tests: installs the build into a scratch prefix (meson install
# --destdir) and points pkg-config at the installed gsttreestereo-1.0.pc, so a program can be
# built against what is installed and nothing else. Sets:
#   dest     the scratch directory (removed on exit)
#   prefix   the configured prefix; root = "$dest$prefix"
#   libdir   the configured libdir (absolute); installed_libdir = "$dest$libdir"
#   PKG_CONFIG_PATH (exported)
# and defines fail().
set -euo pipefail
build=${TREESTEREO_BUILD_DIR:?}
src=${TREESTEREO_SOURCE_DIR:?}
dest=$(mktemp -d)
trap 'rm -rf "$dest"' EXIT
fail() { echo "$(basename "$0"): $*" >&2; exit 1; }

meson install -C "$build" --destdir "$dest" --no-rebuild --quiet >/dev/null

build_option() {
  meson introspect "$build" --buildoptions | python3 -c \
    'import json,sys; print(next(o["value"] for o in json.load(sys.stdin) if o["name"]==sys.argv[1]))' "$1"
}
prefix=$(build_option prefix)
libdir=$(build_option libdir)
case "$libdir" in /*) ;; *) libdir="$prefix/$libdir" ;; esac
root="$dest$prefix"
installed_libdir="$dest$libdir"

[ -f "$installed_libdir/pkgconfig/gsttreestereo-1.0.pc" ] ||
  fail "no gsttreestereo-1.0.pc in $libdir/pkgconfig"
# The .pc file names its install prefix; point that one file at the scratch copy.
sed -i "s|^prefix=.*|prefix=$root|" "$installed_libdir/pkgconfig/gsttreestereo-1.0.pc"
export PKG_CONFIG_PATH="$installed_libdir/pkgconfig"
