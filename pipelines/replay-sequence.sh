#!/usr/bin/env bash
# Replays a recorded image-sequence pair (left_0000.jpg, right_0000.jpg, ... as
# treestereo-synth, pipelines/aravis-record.sh or tests/fixtures/ write them) through the whole
# chain and prints every message: the measurement of a recording, without cameras.
#
# Usage: pipelines/replay-sequence.sh <dir> [calibration]   (default <dir>/calibration.yml)
# Optional: FRAMERATE (7/1, the rate the frames were taken at: it sets the timestamps that
# stereorectify pairs by), EXT (jpg; png works too), SINK (fakesink: nothing is shown;
# e.g. "treeoverlay views=left ! videoconvert ! autovideosink" to watch), STEREODEPTH (extra
# stereodepth properties, e.g. "canopy=off" to measure the colour mask instead of the tree in
# front decided in 3D).
# imagesequencesrc numbers from index 0 and stops at the first missing file; unlike multifilesrc
# it knows the sequence's duration and can seek (an application can scrub through a replay).
set -euo pipefail
dir=${1:?usage: replay-sequence.sh <dir> [calibration]}
calibration=${2:-$dir/calibration.yml}
rate=${FRAMERATE:-7/1}
ext=${EXT:-jpg}
case "$ext" in jpg | jpeg) dec=jpegdec ;; png) dec=pngdec ;;
  *) echo "replay-sequence.sh: EXT must be jpg or png" >&2; exit 2 ;; esac
sink=${SINK:-fakesink}
depth_props=${STEREODEPTH:-}

view() {  # $1 left|right
  echo "imagesequencesrc location=\"$dir/$1_%04d.$ext\" framerate=$rate ! $dec !" \
       "videoconvert ! video/x-raw,format=RGB ! r.$1"
}
# shellcheck disable=SC2046
eval exec gst-launch-1.0 ${GST_LAUNCH_FLAGS:--m} \
  stereorectify name=r calibration="\"$calibration\"" ! exgsegment ! siftmatch ! stereodepth $depth_props ! \
  treemetrics ! $sink $(view left) $(view right)
