"""A simulated walk through the Glasgow radar and DSP, in the Glasgow image layout, next to a real walk.

    python examples/glasgow_side_by_side.py [REAL_IMAGE] [OUT_PNG]

Defaults: the real walk 1P36A01R01.png of the Glasgow dataset (through the data registry: mirror, cache or
download) and glasgow_side_by_side.png in a new temporary folder (never the checkout; the documentation's
figure was made by passing its path).
The simulated walk is built as the `glasgow` dataset preset builds its walks: a procedural walk of
2.4 m at 1.1 m/s, three legs (toward, away from, toward the radar) joined by 0.7 s turns, in a 10 s
clip; Radar.glasgow at 3 m distance and 1 m height, points backend, the kit's receiver noise.
"""
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from processing.realdata.spectrogram_image import glasgow_layout
from processing.realdata.spectrogram_image_writer import render_image
from rtchannel import Motion, simulate
from rtchannel.data_registry import fetch
from rtchannel.motion.compose import back_and_forth, fit_clip
from rtchannel.radar import Radar

real = Path(sys.argv[1]) if len(sys.argv) > 1 else fetch("realdata/glasgow848/1Dataset/1P36A01R01.png")
out = (Path(sys.argv[2]) if len(sys.argv) > 2
       else Path(tempfile.mkdtemp(prefix="rtchannel-")) / "glasgow_side_by_side.png")

leg = Motion.procedural("walk", height=1.74, speed=1.1, distance=2.4, pad_before=0.1, pad_after=0.1, seed=3)
walk = back_and_forth(leg, legs=3, turn_s=0.7)
mid = 0.5 * (walk.positions[0, 0, :2] + walk.positions[-1, 0, :2])
walk = fit_clip(walk.transformed(0.0, (-mid[0], -mid[1], 0.0)), 10.0, lead=0.5)
result = simulate(walk, Radar.glasgow(height_m=1.0, distance_m=3.0), "points", noise_seed=1)
sig = result.links["radar1"].signature
power = sig.p_vt * sig.power[None, :]  # 10 log10 of it is the script's 20 log10(sum_r |S_r|)
sim = render_image(sig.velocity, sig.time, glasgow_layout(10.0), power=power, title="simulated walk (points)")
real_rgb = np.asarray(Image.open(real).convert("RGB"))
out.parent.mkdir(parents=True, exist_ok=True)
Image.fromarray(np.concatenate([sim, real_rgb], axis=1)).save(out)
print(f"wrote {out}")
