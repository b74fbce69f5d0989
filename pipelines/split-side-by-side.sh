#!/usr/bin/env bash
# A stereo camera that delivers both views in one side-by-side frame (one USB device, or a
# side-by-side video/image file) split into the two streams stereorectify pairs: a tee, then
# videocrop keeps the left half for the left pad and the right half for the right pad. Both
# halves carry the frame's timestamp, so they pair with zero skew.
#
# Usage: pipelines/split-side-by-side.sh "<source ending in raw video>" <view width> <calibration>
#   e.g.  "v4l2src device=/dev/video0 ! videoconvert"  1280  rig.yml
#         "multifilesrc location=sbs_%04d.png caps=image/png,framerate=7/1 ! pngdec ! videoconvert"  640  rig.yml
# The calibration is that of one view (image_width = the view width). SINK as in
# pipelines/replay-sequence.sh (default fakesink; GST_LAUNCH_FLAGS default -m prints messages).
set -euo pipefail
source_desc=${1:?usage: split-side-by-side.sh "<source>" <view width> <calibration>}
w=${2:?view width missing}
calibration=${3:?calibration missing}
sink=${SINK:-fakesink}
# shellcheck disable=SC2086
eval exec gst-launch-1.0 ${GST_LAUNCH_FLAGS:--m} \
  $source_desc ! video/x-raw,format=RGB ! tee name=t \
  t. ! queue ! videocrop right=$w ! r.left \
  t. ! queue ! videocrop left=$w ! r.right \
  stereorectify name=r calibration="\"$calibration\"" ! exgsegment ! siftmatch ! stereodepth ! \
  treemetrics ! $sink
