#!/usr/bin/env bash
# Live capture with recording, without hardware: two fake GigE Vision cameras (see
# fake-gv-cameras.sh) through pipelines/aravis-record.sh for N frames per camera. Checks that
# the recording is complete and usable, not the measurement (the fake images are not trees):
#   - EOS without an error,
#   - each camera's raw frames are on disk as JPEG files, one per frame it delivered,
#   - annotated.mp4 plays and holds one frame per measured pair (treemetrics messages),
#   - the raw frames replay through treestereo-measure (the paper's capture-then-measure way).
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
measure=${1:?usage: test-aravis-record.sh TREESTEREO_MEASURE}
. "$here/fake-gv-cameras.sh"
fake_cameras_enter_netns "$@"
for e in bayer2rgb x264enc mp4mux qtdemux h264parse avdec_h264 jpegenc; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
fake_cameras_start
tmp=$fake_cameras_tmp
n=20
fail() { tail -30 "$tmp/run.log"; echo "FAIL: $*"; exit 1; }

gst-launch-1.0 -q treetestsrc num-buffers=1 calibration-out="$tmp/rig.yml" ! \
  video/x-raw,width=512,height=512 ! fakesink || { echo "FAIL: no calibration"; exit 1; }

LEFT_CAMERA=127.0.0.1 RIGHT_CAMERA=127.0.0.2 CALIBRATION="$tmp/rig.yml" FRAMES=$n \
  CAMERA_CAPS=video/x-bayer,framerate=10/1 MAX_SKEW_MS=75 LATENCY_MS=250 PAIR_QUEUE=$n \
  SINK=fakesink GST_LAUNCH_FLAGS="-e -m" \
  timeout 90 bash "$src/pipelines/aravis-record.sh" "$tmp/rec" >"$tmp/run.log" 2>&1
status=$?
[ $status -eq 0 ] || fail "recording pipeline exited with status $status"
grep -q '(eos)' "$tmp/run.log" || fail "no EOS"
! grep -q '^ERROR' "$tmp/run.log" || fail "an error was posted"

left=$(ls "$tmp/rec"/left_*.jpg 2>/dev/null | wc -l)
right=$(ls "$tmp/rec"/right_*.jpg 2>/dev/null | wc -l)
[ "$left" -ge $((n - 2)) ] && [ "$left" -le $n ] || fail "$left raw left frames of $n"
[ "$right" -ge $((n - 2)) ] && [ "$right" -le $n ] || fail "$right raw right frames of $n"

pairs=$(grep -c '(element): treemetrics, ' "$tmp/run.log")
decoded=$(gst-launch-1.0 -v filesrc location="$tmp/rec/annotated.mp4" ! qtdemux ! h264parse ! \
  avdec_h264 ! fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain')
[ "$pairs" -ge $((n - 10)) ] || fail "only $pairs pairs measured"
[ "$decoded" -eq "$pairs" ] || fail "annotated.mp4 decodes to $decoded frames, $pairs pairs were measured"

# the raw frames are a capture treestereo-measure replays
"$measure" --left "$tmp/rec/left_%05d.jpg" --right "$tmp/rec/right_%05d.jpg" \
  --calibration "$tmp/rig.yml" --fps 10 --json "$tmp/replay.jsonl" --quiet >"$tmp/replay.log" 2>&1 ||
  { cat "$tmp/replay.log"; echo "FAIL: the raw frames do not replay"; exit 1; }
replayed=$(wc -l <"$tmp/replay.jsonl")
expect=$(( left < right ? left : right ))
[ "$replayed" -eq "$expect" ] || { cat "$tmp/replay.log"; echo "FAIL: replayed $replayed pairs of $expect"; exit 1; }
echo "OK: $left/$right raw frames, $pairs pairs measured, $decoded frames in annotated.mp4, $replayed replayed"
