#!/usr/bin/env bash
# treestereo-measure on the committed drive-by fixture tests/fixtures/seq-driveby (16 pairs
# 640x480 JPEG at 2 m/s, seed 4, gaps 0.15-0.8 m, the canopies of trees 1 and 2 grown into each
# other), against its truth.json: the travel from stereo alone (files carry no speed), one
# complete tree record per tree that passed wholly through the view (the touching pair two
# records, each as wide as its crown), each at its tree's place with its height and width, and
# the row map's gaps.
set -uo pipefail
measure=${1:?usage: test-driveby-fixture.sh TREESTEREO_MEASURE}
src=${TREESTEREO_SOURCE_DIR:?TREESTEREO_SOURCE_DIR not set}
fx=$src/tests/fixtures/seq-driveby
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
timeout 250 "$measure" --left "$fx/left_%04d.jpg" --right "$fx/right_%04d.jpg" \
  --calibration "$fx/calibration.yml" --json "$tmp/r.jsonl" --trees "$tmp/t.jsonl" \
  --row-map "$tmp/m.csv" --quiet >"$tmp/run.log" 2>&1 || { cat "$tmp/run.log"; fail "treestereo-measure on seq-driveby"; }
python3 - "$tmp/r.jsonl" "$tmp/t.jsonl" "$fx/truth.json" "$fx/calibration.yml" "$tmp/m.csv" <<'PY' || fail "seq-driveby against its truth"
import csv, json, re, sys
frames = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
records = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
truth = json.load(open(sys.argv[3]))
calib = open(sys.argv[4]).read()
m1 = [float(v) for v in re.search(r"M1:.*?data: \[([^\]]*)\]", calib, re.S).group(1).split(",")]
fx, cx, width = m1[0], m1[2], truth["width"]
step = truth["speed_m_s"] / truth["framerate"]
n = len(truth["frames"])
assert len(frames) == n, f"{len(frames)} frames measured of {n}"
# The position since the start: stereo alone, within 3 % at the end (640x480 reads short).
pos, want = frames[-1]["position_m"], (n - 1) * step
print(f"position at the end {pos:.3f} m, truth {want:.3f} m ({100 * (pos - want) / want:+.2f} %)")
assert abs(pos - want) <= 0.03 * want, "position at the end"
# The trees that passed wholly through the view: at some frame both canopy ends lie inside the
# view at the canopy's front (distance minus half its depth).
row = {t["index"]: t for f in truth["frames"] for t in f["row_trees"]}
whole = []
for t in row.values():
    z = t["distance_m"] - 0.5 * t["depth_m"]
    lo, hi = (0 - cx) / fx * z, (width - cx) / fx * z
    if any(t["start_m"] >= k * step + lo and t["end_m"] <= k * step + hi for k in range(n)):
        whole.append(t)
complete = [r for r in records if r["complete"]]
print(f"{len(complete)} complete records, {len(whole)} trees wholly in view: " +
      ", ".join(str(t["index"]) for t in sorted(whole, key=lambda t: t["x_m"])))
assert len(complete) == len(whole), "one complete record per tree wholly in view"
used = set()
width_error = {}
for t in sorted(whole, key=lambda t: t["x_m"]):
    centre = 0.5 * (t["start_m"] + t["end_m"])
    r = min(complete, key=lambda r: abs(r["position_m"] - centre))
    assert r["id"] not in used, f"tree {t['index']}: record {r['id']} already stands for another tree"
    used.add(r["id"])
    dpos, dh, dw = r["position_m"] - centre, r["height_m"] / t["height_m"] - 1, r["width_m"] / t["width_m"] - 1
    print(f"tree {t['index']}: record {r['id']} at {r['position_m']:.3f} m ({100 * dpos:+.1f} cm), "
          f"height {100 * dh:+.1f} %, width {100 * dw:+.1f} %")
    # 5 cm plus the position's drift up to there (the 3 % above)
    assert abs(dpos) <= 0.05 + 0.03 * abs(centre), f"tree {t['index']} placed {100 * dpos:+.1f} cm off"
    assert abs(dh) <= 0.05, f"tree {t['index']} height {100 * dh:+.1f} %"
    assert abs(dw) <= 0.10, f"tree {t['index']} width {100 * dw:+.1f} %"
    width_error[r["id"]] = dw
# The touching pair: two records that meet (their canopies overlap or nearly touch).
pair = sorted((r for r in complete if r["id"] in used), key=lambda r: r["position_m"])
meet = [(a, b) for a, b in zip(pair, pair[1:]) if abs(b["start_m"] - a["end_m"]) <= 0.1]
assert meet, "no two records meet: the touching pair is not split"
# Each crown of the pair reaches beyond the cut between them: as far from its trunk as on its
# free side (cut at the outline's dip, tree 2 read 6 % narrow). Within 4 %: the mirror doubles
# the free edge's and the trunk's errors, a few pixels each at 640x480 (2 mm a pixel at the
# crowns' depth); with the travel right they read +3.1 and -2.8 % (docs/results.md, "The travel
# on the whole view").
for r in meet[0]:
    assert abs(width_error[r["id"]]) <= 0.04, f"record {r['id']} of the touching pair: width {100 * width_error[r['id']]:+.1f} %"
# Row map: every gap of 10 cm and more between trees wholly in view holds an empty bin.
cells = list(csv.DictReader(open(sys.argv[5])))
bins = {}
for c in cells:
    p = float(c["position_m"])
    bins[p] = bins.get(p, False) or c["present"] == "1"
ws = sorted(whole, key=lambda t: t["x_m"])
for a, b in zip(ws, ws[1:]):
    if b["start_m"] - a["end_m"] < 0.10:
        continue
    assert any(a["end_m"] <= p - 0.025 and p + 0.025 <= b["start_m"] and not v for p, v in bins.items()), \
        f"the gap between trees {a['index']} and {b['index']} is not in the map"
PY
echo "OK: seq-driveby measured against its truth"
