#!/usr/bin/env python3
"""Checks the treemetrics messages of a gst-launch-1.0 -m log against a fixture's truth.json:
every frame measured (count), a tree found in each, running times one frame period apart,
distance, canopy height/width and thickness against the truth (the rectified-left values
treestereo-synth wrote) within tolerances for 640x480 JPEG fixtures:
  distance 1.5%: issue 7's 0.5% bias is for 1296x972; at 640x480 one pixel of disparity is
    twice as much depth and JPEG blurs the texture SIFT matches on (measured: +0.2%);
  height, width 6%: the 1296x972 target is 1.5%; at 640x480 the tree is ~250 px wide, one
    pixel of its silhouette is 0.4% of it, and JPEG blurs its edges (measured worst over the
    8 frames: seq-static height 2.1%, width 1.3%; seq-moving height 5.3%, width 4.5% on the
    unclipped frames): NOT the target;
  thickness 25%: issue 7's 20% plus the JPEG margin (measured worst: seq-static 11.2%,
    seq-moving 6.1%).
A frame whose canopy touches the image's left or right border (clipped) has a width that is only
a lower bound, and one touching the top or bottom a height that is: those are checked to stay
below truth * (1 + tolerance) and above zero, not to reach the truth.
Usage: check-treemetrics.py <log> <truth.json> <frames>"""
import json
import re
import sys

log, truth_path, frames = sys.argv[1], sys.argv[2], int(sys.argv[3])
truth = json.load(open(truth_path))
msgs = [l for l in open(log) if '(element): treemetrics, ' in l]
field = lambda m, k: float(re.search(r'[ ,]%s=\([a-z0-9]+\)([-0-9.e]+)' % k, m).group(1))
errors = []
if len(msgs) != frames:
    errors.append('%d treemetrics messages, expected %d' % (len(msgs), frames))
period = 1e9 / truth['framerate']
worst = {}
for i, m in enumerate(msgs[:frames]):
    t = truth['frames'][i]
    if 'tree-present=(boolean)true' not in m:
        errors.append('frame %d: no tree' % i)
        continue
    if abs(field(m, 'running-time') - i * period) > 1e3:
        errors.append('frame %d: running time %d, expected %d' % (i, field(m, 'running-time'), i * period))
    clipped = int(field(m, 'clipped'))
    lower_bound = {'height': bool(clipped & 3), 'width': bool(clipped & 12)}
    checks = [('distance', t['rectified_left']['distance_m'], 0.015),
              ('height', t['canopy_height_m'], 0.06), ('width', t['canopy_width_m'], 0.06),
              ('thickness', t['rectified_left']['thickness_m'], 0.25)]
    for name, want, tol in checks:
        got = field(m, name)
        if lower_bound.get(name):
            if not 0 < got <= (1 + tol) * want:
                errors.append('frame %d: %s %.3f m (clipped: a lower bound), truth %.3f m'
                              % (i, name, got, want))
            continue
        worst[name] = max(worst.get(name, 0.0), abs(got - want) / want)
        if abs(got - want) > tol * want:
            errors.append('frame %d: %s %.3f m, truth %.3f m' % (i, name, got, want))
    if i == 0:
        print('frame 0: distance %.3f m (truth %.3f), height %.3f m (%.3f), width %.3f m (%.3f)'
              % (field(m, 'distance'), t['rectified_left']['distance_m'], field(m, 'height'),
                 t['canopy_height_m'], field(m, 'width'), t['canopy_width_m']))
print('worst relative errors: ' + ', '.join('%s %.1f%%' % (k, 100 * v) for k, v in worst.items()))
for e in errors:
    print('FAIL:', e)
sys.exit(1 if errors else 0)
