#!/usr/bin/env bash
# The committed fixtures are what scripts/make-fixtures.sh makes, byte for byte.
set -euo pipefail
src=${TREESTEREO_SOURCE_DIR:?}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
FIXTURES_OUT="$tmp" TREESTEREO_BUILD_DIR="${TREESTEREO_BUILD_DIR:?}" \
  bash "$src/scripts/make-fixtures.sh" >/dev/null
for seq in seq-static seq-moving seq-orchard seq-driveby sweep-1296; do
  diff -r "$src/tests/fixtures/$seq" "$tmp/$seq" || {
    echo "test-fixtures: tests/fixtures/$seq differs from a fresh scripts/make-fixtures.sh" >&2
    exit 1
  }
done
echo "test-fixtures: the five sequences regenerate byte for byte"
