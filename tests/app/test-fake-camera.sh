#!/usr/bin/env bash
# Runs fake-camera-app: aravis's in-process Fake camera (Fake_1, 512x512) through the whole
# chain from an application, with a rig calibration at that size written by treetestsrc.
set -uo pipefail
app=${1:?usage: test-fake-camera.sh FAKE_CAMERA_APP}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
gst-launch-1.0 -q treetestsrc num-buffers=1 calibration-out="$tmp/rig.yml" ! \
  video/x-raw,width=512,height=512 ! fakesink || { echo "FAIL: no calibration"; exit 1; }
timeout 90 "$app" "$tmp/rig.yml" 20
