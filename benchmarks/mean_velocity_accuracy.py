"""Eq.-8 mean velocity against the pelvis's true radial velocity, per activity and clutter-removal setting.

Not a speed benchmark: the accuracy figure of issue 10 (local MTI against the whole-recording mean).
For each procedural activity (Radar 1 at direction 1, receiver noise on) it prints the least-squares slope
through the origin and the RMSE [m/s] of the eq.-8 mean velocity against the true one over the windows
where the body moves (|true| >= 0.2 m/s), and the share of p(v,t) in the zero-velocity bin there. The
truth is what eq. 8 estimates: the power-weighted mean radial velocity (approaching > 0) of the 21 point
scatterers' paths, -(c/2) d(tau)/dt weighted by |a|^2 (range loss and antenna patterns included), averaged
over each window; for a walk it is the pelvis's within a few cm/s, for sit/pick the torso and arms move
differently from the pelvis.

    .venv/bin/python benchmarks/mean_velocity_accuracy.py [--backend facets]
"""
from __future__ import annotations

import argparse

import numpy as np

from processing.radar.waveform import C0
from rtchannel.backends.points import point_paths
from rtchannel.motion.procedural import generate
from rtchannel.pipeline import simulate
from rtchannel.radar import RadarConfig

ACTIVITIES = ("walk", "fall", "sit", "stand", "pick")
SETTINGS = ("mean", "moving_average", "butterworth")
MOVING_MPS = 0.2


def figures(activity: str, static_removal: str, backend: str) -> tuple[float, float, float]:
    """(slope, RMSE [m/s], zero-bin share) of Radar 1's mean velocity against the pelvis."""
    start = (-2.0, 0.0) if activity == "walk" else (0.0, 0.0)
    motion = generate(activity, start=start, **({"distance": 4.0} if activity == "walk" else {}))
    radar = RadarConfig.seed(direction=1)
    radar = radar.model_copy(update={"dsp": radar.dsp.model_copy(update={"static_removal": static_removal})})
    sig = simulate(motion, radar, backend=backend).signatures["radar1"]
    paths = point_paths(motion, radar)["radar1"]
    v = -0.5 * C0 * np.gradient(paths.delays, motion.times, axis=0)  # [F, M] approaching > 0
    pw = np.abs(paths.gains) ** 2
    w = radar.dsp.window_chirps * radar.waveform.pri_s
    vt = np.empty(len(sig.time))
    for i, t in enumerate(sig.time):
        sel = np.abs(motion.times - t) <= w / 2
        vt[i] = np.sum(pw[sel] * v[sel]) / np.sum(pw[sel])
    act = np.abs(vt) >= MOVING_MPS
    ve = sig.mean_velocity[act]
    slope = float(ve @ vt[act] / (vt[act] @ vt[act]))
    rmse = float(np.sqrt(np.mean((ve - vt[act]) ** 2)))
    k0 = int(np.argmin(np.abs(sig.velocity)))
    zero = float(sig.p_vt[k0][act].sum() / sig.p_vt[:, act].sum())
    return slope, rmse, zero


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="points")
    args = ap.parse_args()
    print(f"| activity | {' | '.join(f'{s}: slope / RMSE [m/s] / zero bin' for s in SETTINGS)} |")
    print("|---|" + "---|" * len(SETTINGS))
    for a in ACTIVITIES:
        cells = [figures(a, s, args.backend) for s in SETTINGS]
        print(f"| {a} | " + " | ".join(f"{x:.2f} / {y:.3f} / {z * 100:.0f} %" for x, y, z in cells) + " |")


if __name__ == "__main__":
    main()
