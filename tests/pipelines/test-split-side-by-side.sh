#!/usr/bin/env bash
# pipelines/split-side-by-side.sh on a side-by-side sequence made from the fixture
# tests/fixtures/seq-static (compositor puts the right view beside the left one, lossless PNG):
# the split must give back left and right in their places, so the measurement matches the truth
# as the replay of the separate files does (a swap would find no tree, or a wrong distance).
set -uo pipefail
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
fx=$src/tests/fixtures/seq-static
for e in compositor videocrop pngenc pngdec; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
view() { echo "multifilesrc location=$fx/$1_%04d.jpg caps=image/jpeg,framerate=7/1 ! jpegdec ! videoconvert"; }
# shellcheck disable=SC2046
timeout 60 gst-launch-1.0 -q compositor name=c sink_1::xpos=640 ! video/x-raw,width=1280,height=480 ! \
  videoconvert ! pngenc compression-level=1 ! multifilesink location="$tmp/sbs_%04d.png" \
  $(view left) ! c.sink_0 $(view right) ! c.sink_1 >"$tmp/make.log" 2>&1 ||
  { cat "$tmp/make.log"; echo "FAIL: could not compose the side-by-side sequence"; exit 1; }
[ -f "$tmp/sbs_0007.png" ] && [ ! -f "$tmp/sbs_0008.png" ] || { echo "FAIL: expected 8 frames"; ls "$tmp"; exit 1; }

timeout 100 bash "$src/pipelines/split-side-by-side.sh" \
  "multifilesrc location=$tmp/sbs_%04d.png caps=image/png,framerate=7/1 ! pngdec ! videoconvert" \
  640 "$fx/calibration.yml" >"$tmp/run.log" 2>&1 ||
  { tail -20 "$tmp/run.log"; echo "FAIL: the split pipeline failed"; exit 1; }
python3 "$src/tests/pipelines/check-treemetrics.py" "$tmp/run.log" "$fx/truth.json" 8 ||
  { echo "FAIL: measurements"; exit 1; }
echo "OK: 8 side-by-side frames split and measured"
