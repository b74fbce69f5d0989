#!/usr/bin/env bash
# The README's two commands are run as "./scripts/<name>.sh" from a fresh clone: each must be a
# file that git records as executable (mode 100755; a checkout gives 100644 files no x bit, and
# "./scripts/demo.sh" then fails with "Permission denied").
set -euo pipefail
src=${TREESTEREO_SOURCE_DIR:?}
cd "$src"
cmds=$(sed -n '/^## The two commands/,/^```$/p' README.md | sed -n 's|^\(\./[^ ]*\).*|\1|p')
[ "$(printf '%s\n' "$cmds" | grep -c .)" -eq 2 ] ||
  { echo "FAIL: expected two ./ commands in README's 'The two commands', found: $cmds"; exit 1; }
status=0
for c in $cmds; do
  f=${c#./}
  if git rev-parse --git-dir >/dev/null 2>&1; then
    mode=$(git ls-files -s -- "$f" | awk '{print $1}')
    [ "$mode" = 100755 ] || { echo "FAIL: $f is recorded with mode ${mode:-none}, not 100755"; status=1; }
  fi
  [ -x "$f" ] || { echo "FAIL: $f is not executable in this checkout"; status=1; }
done
[ $status -eq 0 ] && echo "OK: README commands executable: $(echo $cmds)"
exit $status
