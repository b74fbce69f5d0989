#!/usr/bin/env bash
# Runs treestereo-calibrate end to end: usage errors, a calibration of OpenCV's sample pairs
# and --check on the result. Usage: test-calibrate.sh TOOL DATA_DIR (TREESTEREO_DATA_DIR wins).
set -uo pipefail
tool=$1
data=${TREESTEREO_DATA_DIR:-$2}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$tool" --help | grep -q -- "--board WxH" || fail "--help does not describe --board"
"$tool" --board 9x6 a.png >"$tmp/out" 2>&1; [ $? -eq 2 ] || fail "missing --square is not a usage error"
grep -q "square" "$tmp/out" || fail "usage error does not name --square"
"$tool" --board 9 --square 1 a b >/dev/null 2>&1; [ $? -eq 2 ] || fail "bad --board accepted"
"$tool" --board 9x6 --square 1 "$tmp/no-left.png" "$tmp/no-right.png" >"$tmp/out" 2>&1
[ $? -eq 1 ] || fail "missing images did not fail"
grep -q "no-left.png: missing or not an image" "$tmp/out" || fail "missing image not named: $(cat "$tmp/out")"

list=$data/opencv-samples/stereo_calib.xml
if [ ! -f "$list" ]; then
  echo "SKIP: no OpenCV sample images at $list (set TREESTEREO_DATA_DIR)"
  exit 77
fi
"$tool" --board 9x6 --square 1.0 --list "$list" -o "$tmp/calib.yml" >"$tmp/cal" 2>&1 || fail "calibration failed: $(cat "$tmp/cal")"
cat "$tmp/cal"
python3 - "$tmp/cal" <<'PY' || exit 1
import re, sys
text = open(sys.argv[1]).read()
stereo = float(re.search(r"stereo ([0-9.]+) px", text).group(1))
base = float(re.search(r"baseline \|T\|: ([0-9.]+)", text).group(1))
used = re.search(r"pairs used: (\d+) of (\d+)", text).groups()
assert used == ("13", "13"), used
assert stereo < 1.0, stereo
assert abs(base - 3.34) < 0.02 * 3.34, base
PY
[ -s "$tmp/calib.yml" ] || fail "no calibration written"

"$tool" --board 9x6 --check "$tmp/calib.yml" --list "$list" >"$tmp/chk" 2>&1 || fail "--check failed: $(cat "$tmp/chk")"
cat "$tmp/chk"
python3 - "$tmp/chk" <<'PY' || exit 1
import re, sys
m = re.search(r"\|dy\|: mean ([0-9.]+) px", open(sys.argv[1]).read())
assert m and float(m.group(1)) < 0.25, m and m.group(1)
PY
# A calibration file that is not one: a clear error and status 1.
"$tool" --board 9x6 --check "$data/opencv-samples/left01.jpg" --list "$list" >"$tmp/bad" 2>&1
[ $? -eq 1 ] || fail "an image as calibration did not fail"
grep -q "left01.jpg: this is an image" "$tmp/bad" || fail "bad calibration not explained: $(cat "$tmp/bad")"
echo "all good"
