#!/usr/bin/env bash
# treestereo-measure's recording survives a kill (docs/reliability.md, "Faults of the outputs"):
#  1. ended normally (EOS), the recording (a fragmented MP4) has the right duration, decodes to
#     every measured frame and ends with its seek index (mfra);
#  2. killed with SIGKILL after several fragments (as a power cut stops it), the recording still
#     decodes, to the frames the JSON says were measured less at most one fragment (a second)
#     and 2 frames on their way to the encoder; every JSON line is whole JSON, every CSV row
#     whole, frames numbered without a gap.
# Exit 77 (skipped) when the H.264 encoder/decoder is not installed.
set -uo pipefail
measure=${1:?usage: test-measure-kill.sh TREESTEREO_MEASURE}
for e in x264enc mp4mux qtdemux h264parse avdec_h264; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
command -v gst-discoverer-1.0 >/dev/null || { echo "SKIP: gst-discoverer-1.0 is missing"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
fps=7 # the synthetic default: a fragment (1 s) is 7 frames

decoded_frames() {
  timeout 60 gst-launch-1.0 -v filesrc location="$1" ! qtdemux ! h264parse ! avdec_h264 ! \
    fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain'
}

# The top-level boxes of an MP4, one name a line.
mp4_boxes() {
  python3 - "$1" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
i = 0
while i + 8 <= len(d):
    size, name = struct.unpack(">I4s", d[i:i + 8])
    if size == 1:
        size = struct.unpack(">Q", d[i + 8:i + 16])[0]
    print(name.decode("latin-1"))
    if size < 8:
        break
    i += size
PY
}

# 1. a normal end: 21 frames at 7/s = 3 s
"$measure" --synthetic --frames 21 --size 320x240 --json "$tmp/e.jsonl" --record "$tmp/e.mp4" \
  --quiet >"$tmp/e.out" 2>&1 || { cat "$tmp/e.out"; fail "the EOS run failed"; }
n=$(decoded_frames "$tmp/e.mp4")
[ "$n" -eq 21 ] || fail "the EOS recording decodes to $n frames, expected 21"
info=$(gst-discoverer-1.0 "$tmp/e.mp4" 2>&1)
duration=$(printf '%s\n' "$info" | sed -n 's/^ *Duration: \([0-9:.]*\).*/\1/p' | head -1)
ms=$(printf '%s\n' "$duration" | awk -F: '{ printf "%d", ($1 * 3600 + $2 * 60 + $3) * 1000 + 0.5 }')
[ -n "$duration" ] && [ "$ms" -ge 2950 ] && [ "$ms" -le 3050 ] || { printf '%s\n' "$info"; fail "EOS recording: duration '$duration', expected 3 s"; }
printf '%s\n' "$info" | grep -q 'Seekable: yes' || { printf '%s\n' "$info"; fail "EOS recording not seekable"; }
boxes=$(mp4_boxes "$tmp/e.mp4" | tr '\n' ' ')
[ "$(mp4_boxes "$tmp/e.mp4" | grep -c '^moof$')" -ge 3 ] || fail "not a fragmented MP4 of 3 fragments: $boxes"
[ "$(mp4_boxes "$tmp/e.mp4" | tail -1)" = mfra ] || fail "the EOS recording does not end with its seek index (mfra): $boxes"

# 2. SIGKILL after at least 5 fragments (35 frames); killed, it cannot remove its temporary
#    calibration: TMPDIR puts that under $tmp, which the trap removes
TMPDIR="$tmp" "$measure" --synthetic --frames 100000 --size 320x240 --json "$tmp/k.jsonl" --csv "$tmp/k.csv" \
  --record "$tmp/k.mp4" --quiet >"$tmp/k.out" 2>&1 &
pid=$!
for _ in $(seq 1 2400); do
  [ -f "$tmp/k.jsonl" ] && [ "$(wc -l <"$tmp/k.jsonl")" -ge 40 ] && break
  kill -0 $pid 2>/dev/null || { cat "$tmp/k.out"; fail "treestereo-measure ended before the kill"; }
  sleep 0.1
done
kill -KILL $pid
wait $pid
rc=$?
[ $rc -eq 137 ] || { cat "$tmp/k.out"; fail "exit status $rc after SIGKILL, expected 137"; }
python3 - "$tmp/k.jsonl" "$tmp/k.csv" <<'PY' || fail "JSON lines or CSV rows cut by the kill"
import json, sys
text = open(sys.argv[1]).read()
assert text.endswith("\n"), "the JSON file ends inside a line"
frames = [json.loads(l)["frame"] for l in text.splitlines()]
assert frames == list(range(len(frames))), "JSON frames not numbered 0..n-1"
csv = open(sys.argv[2]).read()
assert csv.endswith("\n"), "the CSV file ends inside a row"
rows = csv.splitlines()
header = rows[0].split(",")
assert header[0] == "frame", "CSV header"
for i, r in enumerate(rows[1:]):
    cells = r.split(",")
    assert len(cells) == len(header), f"CSV row {i}: {len(cells)} cells, {len(header)} expected"
    assert int(cells[0]) == i, f"CSV row {i} is frame {cells[0]}"
# the kill may fall between a frame's JSON line and its CSV row
assert len(frames) - 1 <= len(rows) - 1 <= len(frames), f"{len(rows) - 1} CSV rows, {len(frames)} JSON lines"
print(f"{len(frames)} JSON lines, {len(rows) - 1} CSV rows, all whole")
PY
lines=$(wc -l <"$tmp/k.jsonl")
n=$(decoded_frames "$tmp/k.mp4")
# lost: the fragment being filled (a second: fps frames; mp4mux writes it out when the next
# frame would make it longer) and a frame or two between the JSON writer and the muxer (the
# recording branch's queue, the encoder)
slack=$((fps + 2))
[ "$n" -le "$lines" ] && [ "$n" -ge $((lines - slack)) ] || {
  mp4_boxes "$tmp/k.mp4" | uniq -c
  fail "after SIGKILL the recording decodes to $n frames, $lines were measured (at most $slack may be missing)"
}
echo "OK: EOS recording $duration, 21 frames, seek index; SIGKILL after $lines measured frames: $n frames decode, $((lines - n)) lost, $(($(wc -l <"$tmp/k.csv") - 1)) whole CSV rows"
