"""Feet-to-torso two-way antenna weighting over a plan's items (a standing person at the origin, both antennas).

Usage: python scripts/feet_torso_weighting.py rtchannel/dataset/presets/glasgow.yaml
Prints the spread of (feet - torso) [dB] and how often the torso is >10 / >20 dB below the strongest of
feet (5 % of stature), torso (55 %) and chest (72 %): deployments nobody would set up (issue 37).
"""
import sys

import numpy as np

from rtchannel.dataset.plan import load_plan, expand
from rtchannel.radar import RadarConfig
plan = load_plan(sys.argv[1])
items = expand(plan, fetch=False)
vals, torso_down = [], []
for it in items:
    r = RadarConfig.model_validate(it.radar)
    link = r.links[0]
    h = it.motion["height"] or 1.75
    pts = np.array([[0, 0, 0.05 * h], [0, 0, 0.55 * h], [0, 0, 0.72 * h]])
    g = r.link_gain(link, pts)  # amplitude sqrt(Gt Gr)
    two_way = 20 * np.log10(g)  # power, both antennas: |a|^2 scales as Gt Gr
    vals.append(two_way[0] - two_way[1])
    torso_down.append(max(two_way) - two_way[1])
vals = np.array(vals)
td = np.array(torso_down)
print(f"{sys.argv[1]}: feet - torso [dB]: min {vals.min():.1f} p5 {np.percentile(vals, 5):.1f} "
      f"median {np.median(vals):.1f} "
      f"p95 {np.percentile(vals,95):.1f} max {vals.max():.1f}; torso >10 dB below the strongest of feet/torso/chest: "
      f"{np.mean(td > 10)*100:.1f} %, >20 dB: {np.mean(td > 20)*100:.1f} %")
