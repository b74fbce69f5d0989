#!/usr/bin/env bash
# Live measurement from two Aravis cameras with recording: what pipelines/aravis-live.sh does,
# plus each camera's raw frames as JPEG files (left_%05d.jpg, right_%05d.jpg, replayable with
# `treestereo-measure --left DIR/left_%05d.jpg --right DIR/right_%05d.jpg --calibration ...`) and
# the annotated side-by-side video DIR/annotated.mp4. Ctrl-C ends the recording cleanly (-e);
# after a kill or a power cut annotated.mp4 (fragmented MP4) still plays up to its last second
# or so (after a kill, every JPEG but the one being written is whole).
#
# Usage: LEFT_CAMERA=<name> RIGHT_CAMERA=<name> CALIBRATION=rig.yml \
#          pipelines/aravis-record.sh OUTPUT_DIR
# Every other setting as in pipelines/aravis-live.sh.
set -euo pipefail
: "${1:?usage: pipelines/aravis-record.sh OUTPUT_DIR}"
RECORD_DIR="$1" exec bash "$(dirname "$0")/aravis-live.sh"
