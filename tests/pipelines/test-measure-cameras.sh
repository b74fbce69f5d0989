#!/usr/bin/env bash
# treestereo-measure --camera-left/--camera-right on two fake GigE Vision cameras (see
# fake-gv-cameras.sh): the tool's live path builds, pairs and measures every frame pair and
# writes one JSON line per pair. The fake images are not trees (tree_present may be false).
# --frames counts measured pairs: the first frames of two free-running cameras come in a burst
# and a few are dropped as unpaired (docs/aravis.md), and the second camera may start streaming
# a second after the first; the tool still measures exactly n pairs, then ends the stream
# itself. Under the sanitizers the fake cameras' frames stop arriving for seconds now and then
# (see test-aravis-live.sh): that only makes the run longer.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
measure=${1:?usage: test-measure-cameras.sh TREESTEREO_MEASURE}
. "$here/fake-gv-cameras.sh"
fake_cameras_enter_netns "$@"
gst-inspect-1.0 bayer2rgb >/dev/null 2>&1 || { echo "SKIP: bayer2rgb is missing"; exit 77; }
fake_cameras_start
tmp=$fake_cameras_tmp
n=20
gst-launch-1.0 -q treetestsrc num-buffers=1 calibration-out="$tmp/rig.yml" ! \
  video/x-raw,width=512,height=512 ! fakesink || { echo "FAIL: no calibration"; exit 1; }
# the right camera stops streaming for a second right after the start, as a camera that comes
# up late does: its partnerless left frames are dropped, and still n pairs are measured
set -- $fake_camera_pids
right_pid=$2
( sleep 0.7; kill -STOP "$right_pid"; sleep 1.2; kill -CONT "$right_pid" ) &
timeout 60 "$measure" --camera-left 127.0.0.1 --camera-right 127.0.0.2 --calibration "$tmp/rig.yml" \
  --camera-caps video/x-bayer,framerate=10/1 --frames $n --latency 250 --max-skew 75 --pair-queue $n \
  --json "$tmp/r.jsonl" --quiet >"$tmp/run.log" 2>&1
rc=$?
[ $rc -eq 0 ] || { cat "$tmp/run.log"; echo "FAIL: treestereo-measure exit status $rc (124: no $n pairs in 60 s)"; exit 1; }
# pair lines only: a camera missing for longer than --camera-timeout (2 s) would add status
# lines ({"status":"camera-lost",...}, tool-measure-camera-loss)
lines=$(grep -c '"frame"' "$tmp/r.jsonl")
[ "$lines" -eq $n ] || { cat "$tmp/run.log"; echo "FAIL: $lines pairs measured, --frames $n asked for"; exit 1; }
python3 -c "
import json, sys
for l in open('$tmp/r.jsonl'):
    o = json.loads(l)
    if 'status' in o:
        continue
    assert 'tree_present' in o and isinstance(o['pts_ns'], int)
" || { echo "FAIL: malformed JSON"; exit 1; }
echo "OK: $lines pairs measured from two live cameras (--frames $n)"
