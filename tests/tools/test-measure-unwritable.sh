#!/usr/bin/env bash
# treestereo-measure with an output it cannot write (docs/reliability.md, "Faults of the
# outputs"): for each of --json, --csv, --trees, --sections, --row-map and --record, a path in a
# missing folder and a path under a regular file fail before the pipeline starts, with exit
# status 1 and an error naming the file and the reason; nothing is left behind. As a user other
# than root, a read-only folder too ("Permission denied"; root writes there regardless).
set -uo pipefail
measure=${1:?usage: test-measure-unwritable.sh TREESTEREO_MEASURE}
tmp=$(mktemp -d)
trap 'chmod -R u+w "$tmp"; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
echo "a file, not a folder" >"$tmp/file"
mkdir "$tmp/ro"
chmod 555 "$tmp/ro"
cases=("$tmp/missing/out:No such file or directory" "$tmp/file/out:Not a directory")
[ "$(id -u)" -ne 0 ] && cases+=("$tmp/ro/out:Permission denied")
checked=0
for c in "${cases[@]}"; do
  base=${c%%:*} reason=${c#*:}
  for opt in json csv trees sections row-map record; do
    case $opt in json | trees | sections) path=$base.jsonl ;; csv | row-map) path=$base.csv ;; record) path=$base.mp4 ;; esac
    timeout 60 "$measure" --synthetic --frames 3 --size 320x240 --quiet "--$opt" "$path" \
      >"$tmp/out" 2>&1
    rc=$?
    [ $rc -eq 1 ] || { cat "$tmp/out"; fail "--$opt $path: exit status $rc, expected 1"; }
    grep -qF "treestereo-measure: cannot write $path: $reason" "$tmp/out" || {
      cat "$tmp/out"; fail "--$opt $path: no error naming the file and '$reason'"; }
    # the pipeline did not start: no frame measured, no closing summary
    ! grep -q ' frames (' "$tmp/out" || { cat "$tmp/out"; fail "--$opt $path: the pipeline ran"; }
    checked=$((checked + 1))
  done
done
# nothing created beside the test's own files
left=$(find "$tmp" -mindepth 1 -not -name out -not -name file -not -name ro)
[ -z "$left" ] || fail "files left behind: $left"
# an output that can be written is left as it was until written: --record and --row-map are
# checked without being changed
echo keep >"$tmp/keep.mp4"
timeout 60 "$measure" --synthetic --frames 1 --size 320x240 --quiet --record "$tmp/keep.mp4" \
  --row-map "$tmp/missing/map.csv" >"$tmp/out" 2>&1
grep -qF "cannot write $tmp/missing/map.csv" "$tmp/out" || { cat "$tmp/out"; fail "--row-map in a missing folder"; }
[ "$(cat "$tmp/keep.mp4")" = keep ] || fail "a failed start changed the recording file"
echo "OK: $checked unwritable outputs refused before the start, each named with its reason"
