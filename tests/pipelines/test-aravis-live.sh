#!/usr/bin/env bash
# The live Aravis path without hardware: two fake GigE Vision cameras (arv-fake-gv-camera-0.8 on
# 127.0.0.1 and 127.0.0.2, see fake-gv-cameras.sh) stream 512x512 Bayer frames at 10 fps through
# pipelines/aravis-live.sh: aravissrc do-timestamp=true ! bayer2rgb ! stereorectify ! exgsegment !
# siftmatch ! stereodepth ! treemetrics ! treeoverlay, for N frames per camera. The fake images
# are not trees: this checks the live plumbing, pairing and timing, not the measurement:
#   - the pipeline reaches EOS without an error or a warning,
#   - from the 5th pair on stereorectify drops a frame only when the other camera lost its
#     partner: each such drop leaves exactly one missing pair in the running times, and there
#     are at most 2 (a frame dropped for a pairing fault would take its partner along: two
#     drops per missing pair); start-up drops are counted and reported,
#   - every pair reaches siftmatch and treemetrics (the pair queue is made deep enough not to
#     drop) and at least N-10 pairs are made,
#   - from the 5th pair on the pairs' running times step by one frame period (100 ms), no gap.
# The fake cameras run free, not triggered: their frames are up to half a period (50 ms) apart
# plus the jitter of a loaded machine, hence max-skew 75 ms (docs/aravis.md). 10 fps, not the
# fake camera's 25: on a loaded 2-core machine a fake camera process that misses its slot loses
# a frame, whose partner is then rightly dropped; at 25 fps with the whole chain that happened
# in about 1 run of 5, at 10 fps in about 1 of 8.
# Under the sanitizers (scripts/test-sanitizers.sh sets TREESTEREO_SANITIZER_PRELOAD) the timing
# checks (at least N-10 pairs; one frame period apart; each missing pair explained by one drop)
# are not made: there the cameras' frames stopped arriving for 0.4-3.8 s in about 1 run in 5
# (no drop anywhere in the pipeline: the frames never reached it), also at 5 fps and with ASan's
# fast unwinding, while the normal build passes them (they run there in every suite run). The
# sanitizer run still checks the live path for invalid accesses, leaks and undefined behaviour,
# EOS without an error, and every pair reaching siftmatch and treemetrics.
# Skipped (77) only when neither a network namespace nor the loopback address can be set up.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
. "$here/fake-gv-cameras.sh"
fake_cameras_enter_netns "$@"
for e in bayer2rgb treeoverlay exgsegment; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
fake_cameras_start
tmp=$fake_cameras_tmp
n=30

# A rig calibration at the fake camera's size (512x512): treetestsrc writes its true one.
gst-launch-1.0 -q treetestsrc num-buffers=1 calibration-out="$tmp/rig.yml" ! \
  video/x-raw,width=512,height=512 ! fakesink || { echo "FAIL: no calibration"; exit 1; }

# One run of the live pipeline into "$tmp/run.log", then its checks. Returns 0 when every check
# holds; exits on a fault of the chain itself (an error, a warning, no EOS, a pair lost between
# elements); returns 2 when only the timing checks fail.
timing_fault=
run_once() {
  LEFT_CAMERA=127.0.0.1 RIGHT_CAMERA=127.0.0.2 CALIBRATION="$tmp/rig.yml" FRAMES=$n \
    CAMERA_CAPS=video/x-bayer,framerate=10/1 MAX_SKEW_MS=75 LATENCY_MS=250 PAIR_QUEUE=$n SINK=fakesink GST_LAUNCH_FLAGS="-e -m" \
    timeout 60 bash "$src/pipelines/aravis-live.sh" >"$tmp/run.log" 2>&1
  status=$?
  [ $status -eq 0 ] || fail "pipeline exited with status $status"
  grep -q '(eos)' "$tmp/run.log" || fail "no EOS"
  ! grep -q '^ERROR' "$tmp/run.log" || fail "an error was posted"
  # Warnings other than stereorectify's start-up drops (checked below) fail the test.
  ! grep '^WARNING' "$tmp/run.log" | grep -vq 'GstStereoRectify:r: Dropping unpaired' ||
    fail "a warning was posted"
  # Start-up: acquisition begins before the pipeline clock runs, so the first frames come in a
  # burst with nearly equal timestamps and a few are dropped as unpaired. From the 5th pair on (the
  # steady state) nothing may be dropped.
  rts=$(sed -n 's/.*(element): treemetrics, .*running-time=(guint64)\([0-9]*\).*/\1/p' "$tmp/run.log")
  metrics=$(printf '%s\n' "$rts" | grep -c .)
  matches=$(grep -c '(element): siftmatch, ' "$tmp/run.log")
  [ "$matches" -eq "$metrics" ] || fail "$matches siftmatch messages but $metrics treemetrics messages"
  if [ -n "${TREESTEREO_SANITIZER_PRELOAD:-}" ]; then
    [ "$metrics" -ge 5 ] || fail "only $metrics pairs measured of $n frames per camera"
    echo "OK (sanitizers: timing not checked): $n frames per camera, $metrics pairs measured"
    exit 0
  fi
  timing() { tail -20 "$tmp/run.log"; echo "timing: $*"; timing_fault=$*; return 2; }
  [ "$metrics" -ge $((n - 10)) ] || { timing "only $metrics pairs measured of $n frames per camera"; return 2; }
  steady=$(printf '%s\n' "$rts" | sed -n 5p)
  drop_rts=$(sed -n 's/.*from element "r" (qos): .*running-time=(guint64)\([0-9]*\).*/\1/p' "$tmp/run.log")
  startup_drops=$(printf '%s\n' "$drop_rts" | awk -v s="$steady" 'NF && $1 <= s' | grep -c .)
  drops=$(printf '%s\n' "$drop_rts" | awk -v s="$steady" 'NF && $1 > s' | grep -c .)
  [ "$drops" -le 2 ] || { timing "stereorectify dropped $drops frames after the 5th pair"; return 2; }

  # Running times of the pairs from the 5th on: one frame period apart, no gap (a dropped pair
  # would leave 200 ms). The time a frame is handed over jitters by some ms on a loaded machine.
  printf '%s\n' "$rts" | tail -n +5 | awk -v drops="$drops" '
      NR > 1 {
        d = ($1 - prev) / 1e6
        if (d > 150) { missing += int(d / 100 + 0.5) - 1; prev = $1; next }
        if (n == 0 || d < min) min = d
        if (d > max) max = d
        sum += d; n++
      }
      { prev = $1 }
      END {
        mean = sum / n
        printf "steady state: %d pairs, interval mean %.1f ms, min %.1f ms, max %.1f ms; %d pairs missing, %d frames dropped\n", NR, mean, min, max, missing, drops
        if (mean < 95 || mean > 105 || min < 50 || missing != drops) exit 1
      }' || { echo "pair running times (ns):" $rts; echo "drop running times (ns):" $drop_rts
              timing "pairs are not one frame period apart, or a drop is not a lost partner"; return 2; }
  return 0
}

fail() { tail -40 "$tmp/run.log"; echo "FAIL: $*"; exit 1; }
# The fake cameras are two processes on a shared 2-core host: when the host stalls them, frames
# are lost before they reach the pipeline (seen once in some dozens of suite runs: 5 drops in a
# row). A fault of the chain's pairing or timing shows in every run, so a timing failure is run
# once more, and the test fails when the second run fails too.
run_once || {
  echo "timing checks failed once ($timing_fault); running the live pipeline again"
  run_once || fail "$timing_fault (in two runs)"
}
echo "OK: $n frames per camera, $metrics pairs measured, $startup_drops frames dropped at start-up, $drops after"
