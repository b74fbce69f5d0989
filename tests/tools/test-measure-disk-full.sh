#!/usr/bin/env bash
# treestereo-measure on a disk that fills up (docs/reliability.md, "Faults of the outputs"): a
# 300 KB tmpfs mounted in a user and mount namespace (unshare -rm) stands for the disk.
#  1. recording, JSON and CSV there until full: an error "cannot write FILE: No space left on
#     device" naming one of them, exit status 1 (no signal, no hang: 240 s timeout), every
#     JSON line and CSV row written is whole, the recording decodes up to where the disk ended;
#  2. large JSON lines (--points) alone: the error names the JSON file, the file ends with the
#     last whole line (a line cut by the full disk is taken back);
#  3. a disk already full: tree records (--trees) and nozzle-section commands (--sections),
#     written from the main loop, each stop the job with the error naming their file; the JSON
#     lines on a disk with room stay whole;
#  4. the CSV header on a full disk: refused before the pipeline starts;
#  5. the row map (--row-map, written at the end by treemetrics) on a full disk: exit status 1,
#     the error names the file and the full disk.
# Exit 77 (skipped) where a tmpfs cannot be mounted (no user namespaces) or H.264 is missing.
set -uo pipefail
measure=${1:?usage: test-measure-disk-full.sh TREESTEREO_MEASURE}
for e in x264enc mp4mux qtdemux h264parse avdec_h264; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
mkdir "$tmp/disk" "$tmp/saved"
disk=$tmp/disk
if ! unshare -rm sh -c 'mount -t tmpfs -o size=300k tmpfs "$1"' sh "$disk" 2>"$tmp/unshare.err"; then
  echo "SKIP: cannot mount a tmpfs in a user namespace here ($(head -1 "$tmp/unshare.err"))"
  exit 77
fi

# Runs treestereo-measure with a fresh 300 KB tmpfs on $disk (full first when PREFILL=1), then
# copies what it wrote there to $tmp/saved/NAME/ (the tmpfs goes with the namespace). Prints
# the exit status.
on_small_disk() { # name args...
  local name=$1
  shift
  rm -rf "${tmp:?}/saved/$name"
  mkdir -p "$tmp/saved/$name"
  unshare -rm sh -c '
    disk=$1 saved=$2; shift 2
    mount -t tmpfs -o size=300k tmpfs "$disk" || exit 90
    if [ "${PREFILL:-0}" = 1 ]; then dd if=/dev/zero of="$disk/fill" bs=4096 2>/dev/null; fi
    timeout 240 "$@"
    rc=$?
    for f in "$disk"/*; do [ "$f" = "$disk/fill" ] || cp "$f" "$saved/" 2>/dev/null; done
    exit $rc' sh "$disk" "$tmp/saved/$name" "$measure" "$@" >"$tmp/saved/$name.out" 2>&1
  echo $?
}

# Every line of a JSON-lines file is whole JSON, frames (when numbered) 0..n-1; prints the count.
whole_json() { # file
  python3 - "$1" <<'PY'
import json, sys
text = open(sys.argv[1]).read()
assert text == "" or text.endswith("\n"), f"{sys.argv[1]} ends inside a line"
objs = [json.loads(l) for l in text.splitlines()]
frames = [o["frame"] for o in objs if "frame" in o]
assert frames == list(range(len(frames))), "frames not numbered 0..n-1"
print(len(objs))
PY
}

expect_stop() { # name rc file-pattern: exit status 1 and the error naming the file
  local name=$1 rc=$2 pattern=$3
  [ "$rc" -eq 1 ] || { cat "$tmp/saved/$name.out"; fail "$name: exit status $rc, expected 1 (124: hung; >128: a signal)"; }
  grep -qE "^treestereo-measure: cannot write $pattern: No space left on device$" "$tmp/saved/$name.out" || {
    cat "$tmp/saved/$name.out"; fail "$name: no error 'cannot write $pattern: No space left on device'"; }
}

# 1. recording, JSON and CSV until the disk is full (at 400 kbit/s, a few fragments fit)
rc=$(on_small_disk rec --synthetic --frames 100000 --size 320x240 --bitrate 400 --quiet \
  --json "$disk/r.jsonl" --csv "$disk/r.csv" --record "$disk/r.mp4")
expect_stop rec "$rc" "$disk/r\.(mp4|jsonl|csv)"
lines=$(whole_json "$tmp/saved/rec/r.jsonl") || fail "rec: JSON lines cut by the full disk"
python3 - "$tmp/saved/rec/r.csv" <<'PY' || fail "rec: CSV rows cut by the full disk"
import sys
text = open(sys.argv[1]).read()
assert text.endswith("\n"), "the CSV ends inside a row"
rows = text.splitlines()
n = len(rows[0].split(","))
assert all(len(r.split(",")) == n for r in rows), "a CSV row without all its cells"
PY
frames=$(timeout 60 gst-launch-1.0 -v filesrc location="$tmp/saved/rec/r.mp4" ! qtdemux ! h264parse ! avdec_h264 ! \
  fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain')
[ "$frames" -ge 1 ] && [ "$frames" -le "$lines" ] || fail "rec: the recording on the full disk decodes to $frames frames ($lines measured)"
err1=$(grep '^treestereo-measure: cannot write' "$tmp/saved/rec.out" | head -1)

# 2. large JSON lines alone
rc=$(on_small_disk points --synthetic --frames 100000 --size 320x240 --quiet --points \
  --json "$disk/p.jsonl")
expect_stop points "$rc" "$disk/p\.jsonl"
plines=$(whole_json "$tmp/saved/points/p.jsonl") || fail "points: JSON lines cut by the full disk"
[ "$plines" -ge 1 ] || fail "points: no JSON line before the disk was full"

# 3. a full disk for the tree records and the section commands; JSON lines on a disk with room
for what in trees sections; do
  rc=$(PREFILL=1 on_small_disk "$what" --synthetic --speed 2 --frames 100 --size 320x240 --quiet \
    --json "$tmp/saved/$what.jsonl" "--$what" "$disk/$what.jsonl")
  expect_stop "$what" "$rc" "$disk/$what\.jsonl"
  whole_json "$tmp/saved/$what.jsonl" >/dev/null || fail "$what: JSON lines on the other disk cut"
  [ ! -s "$tmp/saved/$what/$what.jsonl" ] || fail "$what: a line on the full disk"
done

# 4. the CSV header on a full disk: before the pipeline starts
rc=$(PREFILL=1 on_small_disk csv --synthetic --frames 5 --size 320x240 --quiet --csv "$disk/c.csv")
expect_stop csv "$rc" "$disk/c\.csv"
! grep -q ' frames (' "$tmp/saved/csv.out" || fail "csv: the pipeline ran"

# 5. the row map at the end
rc=$(PREFILL=1 on_small_disk map --synthetic --frames 5 --size 320x240 --quiet --row-map "$disk/map.csv")
[ "$rc" -eq 1 ] || { cat "$tmp/saved/map.out"; fail "map: exit status $rc, expected 1"; }
grep -qF "Could not write the row map to \"$disk/map.csv\"" "$tmp/saved/map.out" &&
  grep -q "No space left on device" "$tmp/saved/map.out" || { cat "$tmp/saved/map.out"; fail "map: no error naming the file and the full disk"; }

echo "OK: full disk: '$err1' after $lines frames ($frames in the recording); --points: $plines whole lines; --trees, --sections, the CSV header, the row map"
