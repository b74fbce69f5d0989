#!/usr/bin/env python3
"""Checks the treemetrics messages of a gst-launch-1.0 -m log against a fixture's truth.json:
every frame measured (count), a tree found in each, running times one frame period apart,
distance within 5% and canopy height/width within 15% of the truth (the rectified-left values
treestereo-synth wrote). Usage: check-treemetrics.py <log> <truth.json> <frames>"""
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
for i, m in enumerate(msgs[:frames]):
    t = truth['frames'][i]
    if 'tree-present=(boolean)true' not in m:
        errors.append('frame %d: no tree' % i)
        continue
    if abs(field(m, 'running-time') - i * period) > 1e3:
        errors.append('frame %d: running time %d, expected %d' % (i, field(m, 'running-time'), i * period))
    checks = [('distance', t['rectified_left']['distance_m'], 0.05),
              ('height', t['canopy_height_m'], 0.15), ('width', t['canopy_width_m'], 0.15)]
    for name, want, tol in checks:
        got = field(m, name)
        if abs(got - want) > tol * want:
            errors.append('frame %d: %s %.3f m, truth %.3f m' % (i, name, got, want))
    if i == 0:
        print('frame 0: distance %.3f m (truth %.3f), height %.3f m (%.3f), width %.3f m (%.3f)'
              % (field(m, 'distance'), t['rectified_left']['distance_m'], field(m, 'height'),
                 t['canopy_height_m'], field(m, 'width'), t['canopy_width_m']))
for e in errors:
    print('FAIL:', e)
sys.exit(1 if errors else 0)
