#!/usr/bin/env bash
# Live measurement from two GigE Vision / USB3 Vision cameras (aravissrc) shown on screen:
# each camera is demosaiced, the two are paired and rectified by stereorectify, measured by the
# whole chain, and treeoverlay draws the result on the left view.
#
# Usage: LEFT_CAMERA=<name> RIGHT_CAMERA=<name> CALIBRATION=rig.yml pipelines/aravis-live.sh
# (camera names as arv-tool-0.8 lists them, or the camera's IP address). Optional:
#   CAMERA_CAPS   caps the cameras are asked for      (video/x-bayer: the MER-500's BayerRG8)
#   DEMOSAIC      element turning them into RGB       (bayer2rgb; videoconvert for GRAY8/RGB)
#   FEATURES      aravis features for both cameras, e.g. trigger settings (docs/aravis.md)
#   LATENCY_MS    how long a frame waits for its partner (100; at least one frame period)
#   MAX_SKEW_MS   largest time between paired frames  (20; half a frame period at 25 fps)
#   FRAMES        frames per camera, then EOS         (-1 = until Ctrl-C)
#   PAIR_QUEUE    pairs buffered before the analysis; older pairs are dropped (2)
#   SINK          where the annotated left view goes  (videoconvert ! autovideosink sync=false)
#   GST_LAUNCH_FLAGS                                  (-e; tests add -m)
#   RECORD_DIR    also record into this folder: each camera's raw frames as JPEG
#                 (left_%05d.jpg, right_%05d.jpg: treestereo-measure --left/--right replays
#                 them) and the annotated side-by-side video annotated.mp4, a fragmented
#                 MP4 that plays up to its last second after a kill or a power cut
#                 (pipelines/aravis-record.sh sets it)
#
# Timing (docs/aravis.md): do-timestamp=true stamps each frame with the pipeline clock when
# aravissrc hands it over, so a leaky queue right behind each camera keeps that moment the
# frame's arrival. aravissrc reports no usable latency, so stereorectify's `latency` must cover
# one frame period plus the transfer, or live frames are dropped before their partner arrives.
# When the analysis is slower than the cameras, whole pairs are dropped in the pair queue.
set -euo pipefail
: "${LEFT_CAMERA:?set LEFT_CAMERA (arv-tool-0.8 lists the cameras)}"
: "${RIGHT_CAMERA:?set RIGHT_CAMERA}"
: "${CALIBRATION:?set CALIBRATION to the rig calibration (docs/calibration.md)}"
caps=${CAMERA_CAPS:-video/x-bayer}
demosaic=${DEMOSAIC:-bayer2rgb}
features=${FEATURES:-}
latency_ns=$(( ${LATENCY_MS:-100} * 1000000 ))
skew_ns=$(( ${MAX_SKEW_MS:-20} * 1000000 ))
frames=${FRAMES:--1}
pair_queue=${PAIR_QUEUE:-2}
sink=${SINK:-videoconvert ! autovideosink sync=false}
camera_queue="queue max-size-buffers=8 max-size-bytes=0 max-size-time=0 leaky=downstream"

record=${RECORD_DIR:-}
raw_branch() {  # $1 pad name: the camera's frames as JPEG files
  [ -n "$record" ] || return 0
  echo "! tee name=raw_$1 ! queue max-size-buffers=16 max-size-bytes=0 max-size-time=0 ! r.$1" \
       "raw_$1. ! queue max-size-buffers=16 max-size-bytes=0 max-size-time=0 ! videoconvert !" \
       "jpegenc quality=95 ! multifilesink location=\"$record/$1_%05d.jpg\""
}
camera() {  # $1 camera name, $2 stereorectify pad
  echo "aravissrc camera-name=$1 do-timestamp=true num-buffers=$frames ${features:+features=\"$features\"}" \
       "! $caps ! $camera_queue ! $demosaic"
  if [ -n "$record" ]; then raw_branch "$2"; else echo "! r.$2"; fi
}
if [ -n "$record" ]; then
  mkdir -p "$record"
  # the annotated side-by-side video beside what $SINK shows: a fragmented MP4 (a fragment a
  # second, written synchronously) that plays up to its last second after a kill or a power cut
  output="treeoverlay ! tee name=shown ! queue ! videoconvert ! video/x-raw,format=I420 ! \
    x264enc tune=zerolatency speed-preset=veryfast ! h264parse ! mp4mux fragment-duration=1000 ! \
    filesink location=\"$record/annotated.mp4\" buffer-mode=unbuffered o-sync=true \
    shown. ! queue ! $sink"
else
  output="treeoverlay views=left ! $sink"
fi

# shellcheck disable=SC2086,SC2046
eval exec gst-launch-1.0 ${GST_LAUNCH_FLAGS:--e} \
  stereorectify name=r calibration="\"$CALIBRATION\"" latency=$latency_ns max-skew=$skew_ns ! \
  queue max-size-buffers=$pair_queue max-size-bytes=0 max-size-time=0 leaky=downstream ! \
  exgsegment ! siftmatch ! stereodepth ! treemetrics ! $output \
  $(camera "$LEFT_CAMERA" left) $(camera "$RIGHT_CAMERA" right)
