"""Motion statistics of real Glasgow images against a simulated dataset stored in the Glasgow image layout.

The glasgow preset's motion ranges (walk legs, walking speed) were set from these numbers on subjects P36-P45
only (README, sim-to-real). Per activity, medians over recordings of:
  v95   95th percentile of |mean velocity| over the valid columns [m/s] (how fast the body moves),
  ext20 velocity extent of p(v,t) within 20 dB of each column's peak [m/s] (torso plus limbs),
the active time [s] from the first to the last moment the 0.5 s-smoothed mean velocity exceeds 0.15 m/s,
the onset [s], the first of these moments (where in the recording the activity starts),
and for walks: direction changes per 10 s (sign changes of the 0.5 s-smoothed mean velocity beyond
+-0.3 m/s), the share of time slower than 0.3 m/s and the median |mean velocity| [m/s]; the lobes of the
0.3 s-smoothed mean velocity: fwd (its maximum, toward the radar) and back (minus its minimum) [m/s] and
gap, the time from the forward to the backward peak [s] (a pick's stoop and rise, a sit-down's lean and drop).

Run: python scripts/glasgow_motion_stats.py DATASET [--images DIR] [--people P36-P45]
"""
from __future__ import annotations

import argparse

import numpy as np

from processing.io.dataset_reader import DatasetReader
from processing.realdata.real_images import load_real_images, parse_people

ACTIVITIES = ("walk", "sit", "stand", "pick", "fall")


def clip_stats(p_vt: np.ndarray, velocity: np.ndarray, mean_velocity: np.ndarray, valid: np.ndarray,
               time: np.ndarray) -> dict:
    """Statistics of one signature (p(v,t) [V, T], velocity [V] m/s, mean velocity [T] m/s, valid [T], time [T] s)."""
    valid = valid.astype(bool)
    cols = p_vt[:, valid] if valid.any() else p_vt
    ext = [np.ptp(velocity[c >= 0.01 * c.max()]) if c.max() > 0 else 0.0 for c in cols.T]
    speed = np.abs(mean_velocity[valid]) if valid.any() else np.zeros(1)
    k = max(1, int(round(0.5 / np.median(np.diff(time)))))
    smooth = np.convolve(mean_velocity, np.ones(k) / k, mode="same")
    signs = np.sign(smooth[np.abs(smooth) > 0.3])
    moving = np.flatnonzero(np.abs(smooth) > 0.15)
    active = float(time[moving[-1]] - time[moving[0]]) if moving.size else 0.0
    onset = float(time[moving[0]]) if moving.size else float("nan")
    k3 = max(1, int(round(0.3 / np.median(np.diff(time)))))
    lobes = np.convolve(mean_velocity, np.ones(k3) / k3, mode="same")
    return {"fwd": float(lobes.max()), "back": float(-lobes.min()),
            "gap": float(time[np.argmin(lobes)] - time[np.argmax(lobes)]),
            "active_s": active, "onset_s": onset,
            "v95": float(np.percentile(speed, 95)), "ext20": float(np.median(ext)),
            "turns_per_10s": float(np.sum(signs[1:] != signs[:-1]) / np.ptp(time) * 10),
            "slow_share": float(np.mean(np.abs(mean_velocity) < 0.3)),
            "median_speed": float(np.median(np.abs(mean_velocity)))}


def summary(rows: list[dict]) -> str:
    keys = ("onset_s", "active_s", "v95", "ext20", "turns_per_10s", "slow_share", "median_speed", "fwd", "back",
            "gap")
    return "  ".join(f"{k} {np.nanmedian([r[k] for r in rows]):.2f}" for k in keys) + f"  (n = {len(rows)})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="simulated dataset folder (glasgow preset, image layout)")
    ap.add_argument("--images", default=None)
    ap.add_argument("--people", default="P36-P45")
    args = ap.parse_args()
    if args.images is None:  # campaign 1 through the data registry (mirror, cache or download)
        from rtchannel.data_registry import fetch_folder

        args.images = fetch_folder("realdata/glasgow848/1Dataset")
    real, _ = load_real_images(args.images, people=parse_people(args.people))
    ds = DatasetReader(args.dataset)
    for act in ACTIVITIES:
        r = [clip_stats(im.signature.p_vt, im.signature.velocity, im.signature.mean_velocity, im.signature.valid,
                        im.signature.time) for im in real if im.activity == act]
        s = []
        for i in ds.select(activity=act):
            a = next(iter(ds.load(i).values()))
            s.append(clip_stats(a["p_vt"], a["velocity"], a["mean_velocity"], a["valid"], a["time"]))
        print(f"{act:5s} real {args.people}: {summary(r)}\n{'':5s} simulated: {summary(s)}")


if __name__ == "__main__":
    main()
