#!/usr/bin/env bash
# Records 30 side-by-side frames through treeoverlay to an MP4 (pipelines/record-overlay.sh),
# then checks the file plays: gst-discoverer-1.0 reports a duration of 30 frames at 25/s and a
# decode pipeline delivers 30 frames. Then kills a long recording with SIGKILL after several
# fragments: it still decodes without error, every whole fragment (25 frames) of it.
# Exit 77 (skipped) when an encoder/decoder is missing.
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
for e in x264enc mp4mux qtdemux h264parse avdec_h264 capssetter treeoverlay; do
  if ! gst-inspect-1.0 "$e" >/dev/null 2>&1; then
    echo "SKIP: GStreamer element $e is missing (gstreamer1.0-plugins-ugly/-libav/-good, see scripts/deps.sh)"
    exit 77
  fi
done
for t in gst-launch-1.0 gst-discoverer-1.0; do
  if ! command -v "$t" >/dev/null; then
    echo "SKIP: $t is missing (gstreamer1.0-tools / gstreamer1.0-plugins-base-apps)"
    exit 77
  fi
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

bash "$src/pipelines/record-overlay.sh" "$tmp/out.mp4" 30 >"$tmp/record.log" 2>&1 || {
  cat "$tmp/record.log"; echo "FAIL: recording pipeline failed"; exit 1; }
[ -s "$tmp/out.mp4" ] || { echo "FAIL: no output file"; exit 1; }

# Duration: 30 frames at 25/s = 1.2 s (discoverer prints H:MM:SS.nnnnnnnnn).
info=$(gst-discoverer-1.0 "$tmp/out.mp4" 2>&1)
duration=$(printf '%s\n' "$info" | sed -n 's/^ *Duration: \([0-9:.]*\).*/\1/p' | head -1)
[ -n "$duration" ] || { printf '%s\n' "$info"; echo "FAIL: no duration"; exit 1; }
ms=$(printf '%s\n' "$duration" | awk -F: '{ printf "%d", ($1 * 3600 + $2 * 60 + $3) * 1000 + 0.5 }')
if [ "$ms" -lt 1150 ] || [ "$ms" -gt 1250 ]; then
  printf '%s\n' "$info"; echo "FAIL: duration $duration, expected 1.2 s"; exit 1
fi
printf '%s\n' "$info" | grep -q "video #[0-9]*: H.264 (\(Constrained \)\?\(Baseline\|Main\|High\) Profile)" || { printf '%s\n' "$info"; echo "FAIL: not H.264"; exit 1; }

# Decode every frame: fakesink's last-message reports each buffer it receives.
frames=$(gst-launch-1.0 -v filesrc location="$tmp/out.mp4" ! qtdemux ! h264parse ! avdec_h264 ! \
  fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain')
if [ "$frames" -ne 30 ]; then
  echo "FAIL: decoded $frames frames, expected 30"; exit 1
fi

# SIGKILL mid-recording (fragments of 1 s = 25 frames): wait for 4 fragments, kill
bash "$src/pipelines/record-overlay.sh" "$tmp/killed.mp4" 100000 >"$tmp/killed.log" 2>&1 &
pid=$!
fragments() { grep -c moof < <(python3 - "$1" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
i = 0
while i + 8 <= len(d):
    size, name = struct.unpack(">I4s", d[i:i + 8])
    print(name.decode("latin-1"))
    if size < 8:
        break
    i += size
PY
); }
for _ in $(seq 1 600); do
  [ -f "$tmp/killed.mp4" ] && [ "$(fragments "$tmp/killed.mp4")" -ge 4 ] && break
  kill -0 $pid 2>/dev/null || { cat "$tmp/killed.log"; echo "FAIL: the recording ended before the kill"; exit 1; }
  sleep 0.1
done
kill -KILL $pid
wait $pid 2>/dev/null
whole=$(fragments "$tmp/killed.mp4")
[ "$whole" -ge 4 ] || { echo "FAIL: $whole fragments before the kill"; exit 1; }
killed=$(timeout 60 gst-launch-1.0 -v filesrc location="$tmp/killed.mp4" ! qtdemux ! h264parse ! avdec_h264 ! \
  fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain')
# the last fragment counted may be cut; every one before it is whole
if [ "$killed" -lt $(((whole - 1) * 25)) ]; then
  echo "FAIL: after SIGKILL with $whole fragments written the recording decodes to $killed frames"; exit 1
fi
timeout 60 gst-launch-1.0 -q filesrc location="$tmp/killed.mp4" ! qtdemux ! h264parse ! avdec_h264 ! fakesink \
  >"$tmp/decode.log" 2>&1 || { cat "$tmp/decode.log"; echo "FAIL: the killed recording does not decode without error"; exit 1; }
echo "OK: $duration, $frames frames decoded; killed after $whole fragments: $killed frames decoded"
