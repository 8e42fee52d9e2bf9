"""Real Glasgow spectrograms next to simulated ones, one row per activity (a picture for the README).

    python scripts/glasgow_montage.py DATASET OUT.png [--real FOLDER (default: campaign 1 through the data registry)]

Three real recordings (subjects P37, P40, P43, repetition 1) and two simulated items of the same class
drawn at random (fixed seed) from DATASET (a `rtchannel dataset --config glasgow` folder), each on its own
40 dB scale below its maximum, velocity +-6 m/s as the Glasgow images.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from processing.io.dataset_reader import DatasetReader  # noqa: E402
from processing.realdata.spectrogram_image import read_glasgow_image  # noqa: E402

CLASSES = [("walk", 1), ("sit", 2), ("stand", 3), ("pick", 4), ("fall", 6)]  # Glasgow activity digits
SUBJECTS = ["P37", "P40", "P43"]


def _panel(ax, time, velocity, p, title):
    db = 10 * np.log10(np.maximum(p, 1e-30))
    ax.pcolormesh(time, velocity, db, vmin=db.max() - 40, vmax=db.max(), cmap="jet", shading="auto")
    ax.set_ylim(-6, 6)
    ax.set_title(title, fontsize=9)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset")
    ap.add_argument("out")
    ap.add_argument("--real", default=None)
    a = ap.parse_args()
    if a.real is None:  # campaign 1 through the data registry (mirror, cache or download)
        from rtchannel.data_registry import fetch_folder

        a.real = fetch_folder("realdata/glasgow848/1Dataset")
    ds = DatasetReader(a.dataset)
    rng = np.random.default_rng(0)
    fig, ax = plt.subplots(len(CLASSES), 5, figsize=(16, 12), sharey=True)
    for r, (name, digit) in enumerate(CLASSES):
        for k, subject in enumerate(SUBJECTS):
            sig = read_glasgow_image(f"{a.real}/{digit}{subject}A{digit:02d}R01.png").signature
            _panel(ax[r, k], sig.time, sig.velocity, sig.p_vt, f"real {name} {subject}")
        for k, i in enumerate(rng.choice(ds.select(activity=name), 2, replace=False)):
            x = ds.load(int(i))["radar1"]
            _panel(ax[r, 3 + k], x["time"], x["velocity"], x["p_vt"], f"sim {name} {ds.entries[int(i)]['group']}"[:40])
        ax[r, 0].set_ylabel("velocity [m/s]")
    for c in range(5):
        ax[-1, c].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(a.out, dpi=60)


if __name__ == "__main__":
    main()
