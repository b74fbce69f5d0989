#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/) with clang, ASan and UBSan in build-fuzz/ and runs
# each for N seconds (default 60) starting from the corpus in tests/fuzz/corpus/<target>/.
# New inputs the fuzzer finds go to build-fuzz/corpus/<target>/ (not into the repository);
# a crash, leak or UB stops the run, leaves crash-* / leak-* in build-fuzz/ and fails.
#   scripts/fuzz.sh [seconds] [target...]      targets: calibration messages sections (default all)
#   TREESTEREO_FUZZ_BUILD_DIR  build directory (default build-fuzz)
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(calibration messages sections)
build=${TREESTEREO_FUZZ_BUILD_DIR:-build-fuzz}

bash scripts/deps.sh || exit 1
t0=$(date +%s)
if [ ! -f "$build/build.ninja" ]; then
  # fuzzer-no-link on every file: coverage feedback from lib/ and gst/meta/, not only from the
  # targets; the targets alone link libFuzzer's main (tests/fuzz/meson.build).
  CC=clang CXX=clang++ CFLAGS=-fsanitize=fuzzer-no-link CXXFLAGS=-fsanitize=fuzzer-no-link \
    meson setup "$build" -Dfuzzing=enabled -Dtests=enabled -Dbench=disabled -Daravis=disabled \
    -Db_sanitize=address,undefined -Db_lundef=false || exit 1
fi
ninja_targets=()
for t in "${targets[@]}"; do ninja_targets+=("tests/fuzz/fuzz-$t"); done
meson compile -C "$build" "${ninja_targets[@]}" || exit 1
echo "fuzz build: $(( $(date +%s) - t0 )) s"

export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:detect_odr_violation=0:fast_unwind_on_malloc=0:malloc_context_size=128"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$root/tests/sanitizers/lsan.supp:print_suppressions=0"
status=0
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t"
  echo "== fuzz-$t for $seconds s"
  # -max_len: calibration files are a few kB; -timeout: one input may not take a second.
  (cd "$build" && "./tests/fuzz/fuzz-$t" "corpus/$t" "$root/tests/fuzz/corpus/$t" \
      -max_total_time="$seconds" -max_len=16384 -timeout=10 -rss_limit_mb=2048 \
      -print_final_stats=1 -artifact_prefix="$root/$build/") 2>&1 | \
    grep -v -E '^#[0-9]+\s+(NEW|REDUCE|pulse)' | tail -40
  rc=${PIPESTATUS[0]}
  echo "fuzz-$t: exit status $rc"
  [ "$rc" -ne 0 ] && status=1
done
exit $status
