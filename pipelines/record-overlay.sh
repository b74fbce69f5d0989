#!/usr/bin/env bash
# Records the annotated stream to an MP4: treeoverlay draws what the metas say, x264 encodes it.
# Usage: pipelines/record-overlay.sh [out.mp4] [num-buffers]
# I420 keeps the H.264 stream in the profile every player decodes (RGB would give High 4:4:4).
# The MP4 is fragmented (a fragment a second, written synchronously): killed, or after a power
# cut, it still plays up to its last second or so; ended by EOS it has its duration and a seek
# index (docs/reliability.md). No B-frames: GStreamer 1.22's mp4mux, fragmented, loses the first
# frames of a stream that has them (their decoding times lie before 0; 28 of 30 decode).
# Without a camera rig this records videotestsrc frames marked side by side (nothing to draw but
# the frames themselves); put treeoverlay behind treemetrics in a measuring pipeline to record
# the annotations (see docs/elements/treeoverlay.md).
set -euo pipefail
out=${1:-treeoverlay.mp4}
n=${2:-30}
exec gst-launch-1.0 -e \
  videotestsrc num-buffers="$n" ! video/x-raw,format=RGB,width=640,height=240,framerate=25/1 ! \
  capssetter caps="video/x-raw,multiview-mode=side-by-side" ! \
  treeoverlay ! videoconvert ! video/x-raw,format=I420 ! x264enc bframes=0 ! mp4mux fragment-duration=1000 ! \
  filesink location="$out" buffer-mode=unbuffered o-sync=true
