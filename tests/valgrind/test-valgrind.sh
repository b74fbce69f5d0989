#!/usr/bin/env bash
# valgrind memcheck on a 100-frame run of the whole chain at 320x240:
#   treetestsrc (left, right) -> stereorectify -> exgsegment -> siftmatch -> stereodepth ->
#   treemetrics -> treeoverlay -> fakesink
# Fails when valgrind reports an invalid read/write or use of uninitialised memory anywhere, or
# a "definitely lost" block (after the GLib/GStreamer one-time suppressions in gst.supp) whose
# stack holds treestereo code. Exit 77 (skipped) when valgrind or gst-launch-1.0 is missing.
#   $1  number of frames (default 100)
set -uo pipefail
frames=${1:-100}
here=$(cd "$(dirname "$0")" && pwd)
for t in valgrind gst-launch-1.0; do
  command -v "$t" >/dev/null 2>&1 || { echo "SKIP: $t not installed"; exit 77; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
caps=video/x-raw,format=RGB,width=320,height=240,framerate=7/1

gst-launch-1.0 -q treetestsrc num-buffers=1 calibration-out="$tmp/rig.yml" ! "$caps" ! fakesink \
  || { echo "FAIL: could not write the rig's calibration"; exit 1; }

# GLib's allocator caches and GStreamer's registry fork only hide or split what memcheck sees.
export G_SLICE=always-malloc G_DEBUG=gc-friendly GST_REGISTRY_FORK=no
start=$(date +%s)
valgrind --tool=memcheck --leak-check=full --show-leak-kinds=definite --errors-for-leak-kinds=none \
  --num-callers=40 --suppressions="$here/gst.supp" --log-file="$tmp/memcheck.log" \
  gst-launch-1.0 -q stereorectify name=r calibration="$tmp/rig.yml" ! exgsegment ! siftmatch ! \
    stereodepth ! treemetrics ! treeoverlay ! fakesink \
    treetestsrc view=left num-buffers="$frames" ! "$caps" ! r.left \
    treetestsrc view=right num-buffers="$frames" ! "$caps" ! r.right
status=$?
echo "valgrind run: $frames frames in $(( $(date +%s) - start )) s, gst-launch exit status $status"
grep -E "definitely lost:|indirectly lost:|possibly lost:|ERROR SUMMARY" "$tmp/memcheck.log" | sed 's/^==[0-9]*== *//'
[ "$status" -eq 0 ] || { echo "FAIL: the pipeline did not run to the end"; tail -40 "$tmp/memcheck.log"; exit 1; }

# Memory errors (invalid access, uninitialised values) anywhere are failures.
errors=$(grep -E "^==[0-9]+== (Invalid|Conditional jump|Use of uninitialised|Syscall param|Mismatched|Source and destination)" "$tmp/memcheck.log" | wc -l)
# A definitely lost record is one block of lines from "definitely lost in loss record" to the
# blank line after it; it is ours when a frame names treestereo code.
ours=$(awk '/definitely lost in loss record/ {rec=1; buf=""} rec {buf=buf $0 "\n"} rec && /^==[0-9]+== $/ {if (buf ~ /treestereo|gst_tree_|libgsttreestereo|gst_stereo_|gst_sift|gst_exg/) {printf "%s", buf; n++} rec=0} END {exit n > 0}' "$tmp/memcheck.log" > "$tmp/ours.txt"; echo $?)
if [ "$errors" -gt 0 ]; then
  echo "FAIL: $errors memory errors"; grep -A20 -E "^==[0-9]+== (Invalid|Conditional|Use of)" "$tmp/memcheck.log" | head -80; exit 1
fi
if [ "$ours" -ne 0 ]; then
  echo "FAIL: definitely lost blocks allocated by treestereo code:"; cat "$tmp/ours.txt"; exit 1
fi
echo "PASS: no memory errors, no definitely lost block from treestereo code"
