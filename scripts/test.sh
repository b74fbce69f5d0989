#!/usr/bin/env bash
# The README's test command: installs what is missing, configures, builds and runs every test.
# Ends with the line "N passed, N failed, N skipped". Exit status 0 only when nothing failed.
#
# Stages (each counts its tests in the last line):
#   1. the suite in build/ (meson test; includes a 1500-frame soak of the whole chain)
#   2. the suite again with AddressSanitizer + UndefinedBehaviorSanitizer (scripts/test-sanitizers.sh)
#   3. ThreadSanitizer on the property-change stress test (scripts/test-tsan.sh)
#   4. each libFuzzer target for $TREESTEREO_FUZZ_SECONDS (default 60) s (scripts/fuzz.sh)
#   5. valgrind memcheck of a $TREESTEREO_VALGRIND_FRAMES-frame (default 30) run of the whole chain
#      (tests/valgrind/test-valgrind.sh; 100 frames take 10-17 min on 2 cores, see docs/reliability.md)
#
#   scripts/test.sh                 everything (what .ci/run does)
#   scripts/test.sh --quick [args]  stage 1 only; args go to `meson test` (a test name, --suite lib)
set -uo pipefail
cd "$(dirname "$0")/.."
quick=0
if [ "${1:-}" = "--quick" ]; then
  quick=1
  shift
fi
[ $# -gt 0 ] && quick=1
bash scripts/deps.sh || exit 1
bash scripts/build.sh || exit 1
build=${TREESTEREO_BUILD_DIR:-build}
t0=$(date +%s)

passed=0 failed=0 skipped=0
# Adds the results of a meson testlog.json (a missing log is one failure).
count_testlog() {
  read -r p f s < <(python3 - "$1" <<'PY'
import json, sys
p = f = s = 0
try:
    with open(sys.argv[1]) as log:
        for line in log:
            if line.strip():
                r = json.loads(line).get("result")
                if r in ("OK", "EXPECTEDFAIL"):
                    p += 1
                elif r == "SKIP":
                    s += 1
                else:
                    f += 1
except FileNotFoundError:
    f = 1
print(p, f, s)
PY
)
  passed=$((passed + p)) failed=$((failed + f)) skipped=$((skipped + s))
}
# Counts one stage run as a single test from its exit status (77 = skipped).
count_status() {
  case $1 in
    0) passed=$((passed + 1)) ;;
    77) skipped=$((skipped + 1)) ;;
    *) failed=$((failed + 1)); echo "FAILED: $2" ;;
  esac
}
stage() { echo; echo "=== $* ($(( $(date +%s) - t0 )) s so far)"; }

stage "1/5 test suite ($build)"
rm -f "$build/meson-logs/testlog.json"
meson test -C "$build" --print-errorlogs --num-processes 2 "$@"
count_testlog "$build/meson-logs/testlog.json"

if [ $quick -eq 0 ]; then
  asan=${TREESTEREO_ASAN_BUILD_DIR:-build-asan}
  stage "2/5 test suite with AddressSanitizer + UBSan ($asan)"
  rm -f "$asan/meson-logs/testlog.json"
  bash scripts/test-sanitizers.sh
  count_testlog "$asan/meson-logs/testlog.json"

  stage "3/5 ThreadSanitizer: property changes while PLAYING"
  bash scripts/test-tsan.sh
  count_status $? "ThreadSanitizer stress test"

  for target in calibration messages sections; do
    stage "4/5 fuzzing $target for ${TREESTEREO_FUZZ_SECONDS:-60} s"
    bash scripts/fuzz.sh "${TREESTEREO_FUZZ_SECONDS:-60}" "$target"
    count_status $? "fuzz-$target"
  done

  stage "5/5 valgrind memcheck, ${TREESTEREO_VALGRIND_FRAMES:-30} frames"
  GST_PLUGIN_PATH_1_0="$PWD/$build/gst/elements" GST_REGISTRY_1_0="$PWD/$build/valgrind.registry" \
    bash tests/valgrind/test-valgrind.sh "${TREESTEREO_VALGRIND_FRAMES:-30}"
  count_status $? "valgrind memcheck"
fi

echo
echo "test run: $(( $(date +%s) - t0 )) s after the build"
echo "$passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
