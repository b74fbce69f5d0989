#!/usr/bin/env bash
# treestereo-measure end to end, as the README's main command runs it:
#  1. the synthetic default (an orchard row, the tree in front decided in 3D): one JSON object
#     per frame with DESIGN.md's fields, a CSV row per frame, a summary line per frame with the
#     confidence, and an MP4 that decodes to exactly as many frames; distances near the truth;
#     --scene and --canopy reach treetestsrc and stereodepth (canopy_mode in the JSON);
#     a drive-by: the position since the start, tree records and the row map against the truth;
#  2. the committed image sequences with their calibration, as files and as MP4 videos;
#  3. usage errors exit 2 (also an unknown --scene or --canopy, --scene without --synthetic,
#     --camera-timeout or --reconnect out of range) and leave no temporary file behind,
#     pipeline errors exit 1 with a message naming the problem;
#  4. Ctrl-C finishes the files: the recording plays and holds every measured frame.
# Exit 77 (skipped) when the H.264 encoder/decoder is not installed.
set -uo pipefail
measure=${1:?usage: test-measure.sh TREESTEREO_MEASURE}
src=${TREESTEREO_SOURCE_DIR:?}
for e in x264enc mp4mux qtdemux h264parse avdec_h264; do
  gst-inspect-1.0 "$e" >/dev/null 2>&1 || { echo "SKIP: GStreamer element $e is missing"; exit 77; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

# Every line of a JSON-lines file has this canopy_mode.
canopy_mode_is() { # file mode
  python3 - "$@" <<'PY'
import json, sys
modes = {json.loads(l)["canopy_mode"] for l in open(sys.argv[1]) if l.strip()}
assert modes == {sys.argv[2]}, f"canopy_mode {sorted(modes)}, expected {sys.argv[2]}"
PY
}

decoded_frames() {
  gst-launch-1.0 -v filesrc location="$1" ! qtdemux ! h264parse ! avdec_h264 ! \
    fakesink sync=false silent=false 2>&1 | grep -c 'last-message = chain'
}

# Checks a JSON-lines file: N lines, frames 0..N-1, every DESIGN.md field, finite numbers, and
# (with a truth in the line) the distance within TOL of the truth.
check_json() { # file n tol extra-fields
  python3 - "$@" <<'PY'
import json, math, sys
path, n, tol, extra = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4].split(",") if len(sys.argv) > 4 and sys.argv[4] else []
lines = [l for l in open(path) if l.strip()]
assert len(lines) == n, f"{len(lines)} JSON lines, expected {n}"
fields = ["distance_m", "height_m", "width_m", "thickness_m", "area_m2", "perimeter_m",
          "complexity", "centroid_m", "bands", "clipped", "n_points", "n_matches", "confidence",
          "canopy_mode"] + extra
def finite(v):
    if isinstance(v, float): return math.isfinite(v)
    if isinstance(v, list): return all(finite(x) for x in v)
    if isinstance(v, dict): return all(finite(x) for x in v.values())
    return True
for i, l in enumerate(lines):
    o = json.loads(l)
    assert o["frame"] == i, f"frame {o['frame']} at line {i}"
    assert isinstance(o["pts_ns"], int), "pts_ns"
    assert finite(o), f"non-finite value in frame {i}"
    assert o["tree_present"] is True, f"no tree in frame {i}"
    for f in fields:
        assert f in o, f"field {f} missing in frame {i}"
    assert len(o["centroid_m"]) == 3 and len(o["bands"]) == 4
    assert 0 <= o["confidence"] <= 1, f"confidence {o['confidence']} in frame {i}"
    assert o["canopy_mode"] in ("colour", "tree", "row"), f"canopy_mode {o['canopy_mode']}"
    for b in o["bands"]:
        if b["present"]:
            assert 0 < b["fill"] <= 1, f"band fill {b['fill']} in frame {i}"
    if "truth" in o:
        t = o["truth"]["distance_m"]
        assert abs(o["distance_m"] - t) <= tol * t, f"frame {i}: distance {o['distance_m']} vs truth {t}"
print(f"{n} JSON lines OK")
PY
}

# 1. the synthetic default
"$measure" --synthetic --frames 6 --size 640x480 --json "$tmp/s.jsonl" --csv "$tmp/s.csv" \
  --record "$tmp/s.mp4" --points --matches >"$tmp/s.out" 2>&1 || { cat "$tmp/s.out"; fail "synthetic run"; }
check_json "$tmp/s.jsonl" 6 0.02 points_mm,matches || fail "synthetic JSON"
[ "$(grep -c '^frame ' "$tmp/s.out")" -eq 6 ] || { cat "$tmp/s.out"; fail "not one summary line per frame"; }
[ "$(grep -cE '^frame .* confidence [01]\.[0-9]{2}$' "$tmp/s.out")" -eq 6 ] || { cat "$tmp/s.out"; fail "the summary lines do not show the confidence"; }
canopy_mode_is "$tmp/s.jsonl" tree || fail "the synthetic default is not the tree in front"
[ "$(wc -l <"$tmp/s.csv")" -eq 7 ] || fail "CSV should hold a header and 6 rows"
head -1 "$tmp/s.csv" | grep -q '^frame,pts_ns,tree_present,distance_m.*,confidence$' || fail "CSV header"
n=$(decoded_frames "$tmp/s.mp4")
[ "$n" -eq 6 ] || fail "the recording decodes to $n frames, expected 6"

# 1b. --scene and --canopy
"$measure" --synthetic --scene lab --canopy off --frames 2 --size 640x480 --json "$tmp/l.jsonl" \
  --quiet >"$tmp/l.out" 2>&1 || { cat "$tmp/l.out"; fail "--scene lab --canopy off run"; }
check_json "$tmp/l.jsonl" 2 0.02 "" || fail "lab JSON"
canopy_mode_is "$tmp/l.jsonl" colour || fail "--canopy off"
"$measure" --synthetic --scene hedgerow --canopy row --frames 2 --size 640x480 \
  --json "$tmp/h.jsonl" --quiet >"$tmp/h.out" 2>&1 || { cat "$tmp/h.out"; fail "--scene hedgerow --canopy row run"; }
canopy_mode_is "$tmp/h.jsonl" row || fail "--canopy row"

# 1c. along the row: a drive-by at 2 m/s; tree records (--trees) against the renderer's row
# (treestereo-synth's truth.json of the same scene), the position since the start in the JSON,
# the row map's CSV and PNG (--row-map), the nozzle-section commands (--sections)
synth="$(dirname "$measure")/treestereo-synth"
"$measure" --synthetic --speed 2 --frames 24 --size 640x480 --json "$tmp/d.jsonl" \
  --trees "$tmp/d-trees.jsonl" --row-map "$tmp/d-map.csv" --sections "$tmp/d-sections.jsonl" \
  --record "$tmp/d.mp4" \
  >"$tmp/d.out" 2>&1 || { cat "$tmp/d.out"; fail "drive-by run"; }
"$synth" --scene orchard --speed 2 --frames 24 --size 640x480 --format jpg -o "$tmp/d-truth" \
  >/dev/null 2>&1 || fail "treestereo-synth for the drive-by's truth"
grep -q '^tree [0-9]* at ' "$tmp/d.out" || { cat "$tmp/d.out"; fail "no tree line in the summary"; }
python3 - "$tmp/d.jsonl" "$tmp/d-trees.jsonl" "$tmp/d-truth/truth.json" "$tmp/d-map.csv" "$tmp/d-sections.jsonl" <<'PY' || fail "drive-by records"
import csv, json, sys
frames = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
records = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
truth = json.load(open(sys.argv[3]))
row = {t["index"]: t for f in truth["frames"] for t in f["row_trees"]}
# the position since the start: 23 frames of 2/7 m
pos, want = frames[-1]["position_m"], 23 * 2.0 / 7.0
assert abs(pos - want) <= 0.03 * want, f"position {pos:.3f} m after 23 frames, truth {want:.3f}"
assert all("travel_m" in f and f["travel_source"] in ("none", "stereo", "predicted") for f in frames)
for r in records:
    for k in ("id", "position_m", "start_m", "end_m", "frames", "complete"):
        assert k in r, f"record without {k}: {r}"
complete = [r for r in records if r["complete"]]
assert len(complete) >= 2, f"{len(complete)} complete tree records of {len(records)}"
for r in complete:
    for k in ("distance_m", "height_m", "width_m", "thickness_m", "bands", "confidence"):
        assert k in r, f"complete record without {k}: {r}"
    t = min(row.values(), key=lambda t: abs(t["x_m"] - r["position_m"]))
    centre = 0.5 * (t["start_m"] + t["end_m"])
    # the record's place: 5 cm, plus the position's drift since the start (3 %, as above)
    assert abs(r["position_m"] - centre) <= 0.05 + 0.03 * abs(centre), f"tree {r['id']} at {r['position_m']:.3f} m, truth {centre:.3f}"
    assert abs(r["height_m"] - t["height_m"]) <= 0.08 * t["height_m"], f"tree {r['id']} height {r['height_m']:.3f}, truth {t['height_m']:.3f}"
rows = list(csv.DictReader(open(sys.argv[4])))
assert rows and list(rows[0].keys()) == ["position_m", "band", "present", "distance_m", "fill", "seen"], "row map CSV header"
assert any(r["present"] == "1" for r in rows) and any(r["present"] == "0" and r["seen"] == "1" for r in rows), "row map without canopy or without gaps"
assert all(r["seen"] == "1" for r in rows if r["present"] == "1"), "a cell with canopy that no frame saw"
# section commands: DESIGN.md's fields; per section on and off alternate, in time order; each
# opening is for canopy of a tree record (10 cm: two map bins)
commands = [json.loads(l) for l in open(sys.argv[5]) if l.strip()]
assert commands, "no section command"
for c in commands:
    assert set(c) >= {"section", "on", "rate", "at_ns", "position_m"}, f"section command {c}"
    assert "fallback" not in c, f"a fail-safe command in an offline run: {c}"
for k in sorted({c["section"] for c in commands}):
    mine = [c for c in commands if c["section"] == k]
    assert [c["on"] for c in mine] == [i % 2 == 0 for i in range(len(mine))], f"section {k}: {mine}"
    assert all(a["at_ns"] < b["at_ns"] for a, b in zip(mine, mine[1:])), f"section {k} out of time order"
    for c in mine:
        if c["on"]:
            assert any(r["start_m"] - 0.1 <= c["position_m"] <= r["end_m"] + 0.1 for r in records), f"section {k} opens at {c['position_m']} m, no tree there"
# against the renderer's trees: section 1 (0.7-1.0 m, where the canopies are widest) opens and
# closes within one frame's travel (2/7 m, plus the position's 3 % drift) of each tree's start and
# end, for the trees whose end the rig passed (bins are final once behind the camera)
s1 = [c for c in commands if c["section"] == 1]
for t in row.values():
    if t["end_m"] > pos - 0.3:
        continue
    for edge, on in ((t["start_m"], True), (t["end_m"], False)):
        tol = 2.0 / 7.0 + 0.03 * abs(edge)
        near = min((c for c in s1 if c["on"] == on), key=lambda c: abs(c["position_m"] - edge))
        assert abs(near["position_m"] - edge) <= tol, f"section 1 {'on' if on else 'off'} at {near['position_m']} m, tree edge {edge:.3f} m"
PY
[ -s "$tmp/d-map.png" ] || fail "the row map's PNG was not written beside the CSV"
[ -s "$tmp/d-sections.png" ] || fail "the valve timeline's PNG was not written beside --sections"
# the recording's map strip (treeoverlay draw-map): across the bottom sixth of the left view of
# the last frame, the row map's cells coloured by distance and the camera's white line
timeout 60 gst-launch-1.0 -q filesrc location="$tmp/d.mp4" ! qtdemux ! decodebin ! videoconvert ! \
  video/x-raw,format=RGB,width=1280,height=480 ! multifilesink location="$tmp/d-frame-%03d.rgb" ||
  fail "could not decode the drive-by's recording"
python3 - "$(ls "$tmp"/d-frame-*.rgb | tail -1)" <<'PY' || fail "no row map strip in the recording"
import sys
w, h = 1280, 480
data = open(sys.argv[1], "rb").read()
assert len(data) == w * h * 3, len(data)
strip = range(h - h // 6 + 4, h - 4)
def px(x, y):
    i = 3 * (y * w + x)
    return data[i], data[i + 1], data[i + 2]
# distance colours (turbo: strongly saturated), and a nearly white column (the camera)
coloured = sum(1 for y in strip for x in range(0, 640, 2) if max(px(x, y)) - min(px(x, y)) > 120)
white_cols = [x for x in range(640) if sum(sum(px(x, y)) > 3 * 190 for y in strip) > 0.8 * len(strip)]
total = len(strip) * 320
print(f"map strip: {100 * coloured / total:.0f} % coloured, camera line at x {white_cols[:3]}")
assert coloured > 0.1 * total and white_cols
PY

# 2. image sequences (the committed fixtures) with their calibration
fx="$src/tests/fixtures/seq-static"
"$measure" --left "$fx/left_%04d.jpg" --right "$fx/right_%04d.jpg" --calibration \
  "$fx/calibration.yml" --json "$tmp/f.jsonl" --quiet >"$tmp/f.out" 2>&1 || { cat "$tmp/f.out"; fail "fixture run"; }
check_json "$tmp/f.jsonl" 8 1 "" || fail "fixture JSON"

# 2b. the same captures as video files (H.264 MP4), decoded by decodebin
for v in left right; do
  gst-launch-1.0 -q multifilesrc location="$fx/${v}_%04d.jpg" caps="image/jpeg,framerate=7/1" ! \
    jpegdec ! videoconvert ! video/x-raw,format=I420 ! x264enc tune=zerolatency qp-max=20 ! \
    h264parse ! mp4mux ! filesink location="$tmp/$v.mp4" || fail "could not encode $v.mp4"
done
"$measure" --left "$tmp/left.mp4" --right "$tmp/right.mp4" --calibration "$fx/calibration.yml" \
  --json "$tmp/v.jsonl" --quiet >"$tmp/v.out" 2>&1 || { cat "$tmp/v.out"; fail "video file run"; }
check_json "$tmp/v.jsonl" 8 1 "" || fail "video file JSON"

# 3. errors
"$measure" --left "$fx/left_%04d.jpg" >"$tmp/e.out" 2>&1
[ $? -eq 2 ] || fail "--left without --right should be a usage error (2)"
"$measure" --left "$fx/left_%04d.jpg" --right "$fx/right_%04d.jpg" >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--calibration" "$tmp/e.out" || fail "files without --calibration: $(cat "$tmp/e.out")"
"$measure" --synthetic --scene forest --frames 1 >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q "orchard" "$tmp/e.out" || fail "--scene forest: $(cat "$tmp/e.out")"
"$measure" --synthetic --canopy bush --frames 1 >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--canopy" "$tmp/e.out" || fail "--canopy bush: $(cat "$tmp/e.out")"
"$measure" --left "$fx/left_%04d.jpg" --right "$fx/right_%04d.jpg" --calibration \
  "$fx/calibration.yml" --scene lab >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--scene" "$tmp/e.out" || fail "--scene with files: $(cat "$tmp/e.out")"
"$measure" --camera-left 127.0.0.9 --camera-right 127.0.0.10 --calibration "$fx/calibration.yml" \
  --camera-timeout 50 >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--camera-timeout" "$tmp/e.out" || fail "--camera-timeout 50: $(cat "$tmp/e.out")"
"$measure" --camera-left 127.0.0.9 --camera-right 127.0.0.10 --calibration "$fx/calibration.yml" \
  --reconnect -5 >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--reconnect" "$tmp/e.out" || fail "--reconnect -5: $(cat "$tmp/e.out")"
# a usage error found after the synthetic rig's calibration is written leaves no temporary file
mkdir "$tmp/tmpdir"
TMPDIR="$tmp/tmpdir" "$measure" --synthetic --rig-speed -1 --frames 1 >"$tmp/e.out" 2>&1
[ $? -eq 2 ] && grep -q -- "--rig-speed" "$tmp/e.out" || fail "--rig-speed -1: $(cat "$tmp/e.out")"
[ -z "$(ls -A "$tmp/tmpdir")" ] || fail "a usage error left $(ls -A "$tmp/tmpdir") in TMPDIR"
echo "not a calibration" >"$tmp/bad.yml"
"$measure" --left "$fx/left_%04d.jpg" --right "$fx/right_%04d.jpg" --calibration "$tmp/bad.yml" \
  --quiet >"$tmp/e.out" 2>&1
[ $? -eq 1 ] && grep -q "bad.yml" "$tmp/e.out" || fail "bad calibration: $(cat "$tmp/e.out")"

# 4. Ctrl-C: stop a long run after a few frames; the files are finished, not cut
"$measure" --synthetic --frames 500 --size 640x480 --json "$tmp/c.jsonl" --record "$tmp/c.mp4" \
  --quiet >"$tmp/c.out" 2>&1 &
pid=$!
for _ in $(seq 1 600); do
  [ -f "$tmp/c.jsonl" ] && [ "$(wc -l <"$tmp/c.jsonl")" -ge 4 ] && break
  sleep 0.1
done
kill -INT $pid
wait $pid
rc=$?
[ $rc -eq 0 ] || { cat "$tmp/c.out"; fail "Ctrl-C exit status $rc, expected 0"; }
lines=$(wc -l <"$tmp/c.jsonl")
[ "$lines" -ge 4 ] && [ "$lines" -lt 500 ] || fail "$lines frames measured before Ctrl-C"
n=$(decoded_frames "$tmp/c.mp4")
[ "$n" -eq "$lines" ] || fail "after Ctrl-C the recording decodes to $n frames, $lines were measured"
echo "OK: synthetic 6 frames (orchard, lab, hedgerow), fixtures 8 frames as images and as MP4, errors, Ctrl-C after $lines frames"
