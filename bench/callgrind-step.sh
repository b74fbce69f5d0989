#!/bin/sh
# Instructions of the siftmatch step (lib's StereoMatcher::run: detection of both views,
# matching, refinement) on bench-match-scene's timing pair (1296x972, canopy mask), counted by
# callgrind: repeatable whatever else the machine runs, unlike wall or CPU time. Prints a table.
#
#   bench/callgrind-step.sh [BUILD_DIR] [SETTING...]
#
# Each SETTING is a bench-match-scene --set list on top of siftmatch's defaults ("" = the
# defaults); without any: OpenCV's contrast threshold without the inset (contrast-threshold=0.04,
# mask-inset=0) and the defaults. The step's count is (runs=N) - (runs=0), over N (RUNS, default 2), so
# rendering the pair is not counted. Takes about a minute per setting.
set -eu
cd "$(dirname "$0")/.."
build=${1:-build}
[ $# -gt 0 ] && shift
[ $# -eq 0 ] && set -- "contrast-threshold=0.04,mask-inset=0" ""
runs=${RUNS:-2}
command -v valgrind >/dev/null || { echo "callgrind-step.sh: valgrind is not installed" >&2; exit 1; }
meson compile -C "$build" bench/bench-match-scene >/dev/null
bench="$build/bench/bench-match-scene"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

count() { # runs, setting -> total instructions of the process
  valgrind --tool=callgrind --callgrind-out-file="$tmp/cg.out" "$bench" --only step \
    --runs "$1" --set "$2" >"$tmp/out.txt" 2>"$tmp/err.txt" ||
    { cat "$tmp/err.txt" >&2; exit 1; }
  sed -n 's/^==[0-9]*== Collected : //p' "$tmp/err.txt"
}

echo "| setting | keypoints L/R | matches | M instructions per step |"
echo "|---|---|---|---|"
for s in "$@"; do
  base=$(count 0 "$s")
  total=$(count "$runs" "$s")
  line=$(cat "$tmp/out.txt")
  kp=$(echo "$line" | sed -n 's/.*keypoints \([0-9]*\/[0-9]*\).*/\1/p')
  m=$(echo "$line" | sed -n 's/.*matches \([0-9]*\).*/\1/p')
  label=$s
  [ -n "$label" ] || label="(siftmatch's defaults)" # not in \${s:-...}: bash would read the ' there
  echo "| $label | $kp | $m | $(( (total - base) / runs / 1000000 )) |"
done
