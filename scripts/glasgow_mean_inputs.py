"""What the classifier sees: the mean network input per activity, real Glasgow images against a simulated set.

    python scripts/glasgow_mean_inputs.py DATASET OUT.png [--images DIR] [--people P36-P45] [--window-s 6]

Each panel averages the preprocessed inputs ([0, 1] = 40 dB below each sample's maximum .. its maximum) of one
class, with the preprocessing of the README's Glasgow training command (`--v-range 6 --time-mode window`:
6 s centred on each clip's motion centroid). Differences in the mean show what the simulation does not
reproduce on average (timing, velocity spread, the 0 m/s line), not what decides single images.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from processing.classifier.preprocess import PreprocessConfig, preprocess  # noqa: E402
from processing.io.dataset_reader import DatasetReader  # noqa: E402
from processing.realdata.real_images import load_real_images, parse_people  # noqa: E402

ACTIVITIES = ("walk", "sit", "stand", "pick", "fall")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="simulated dataset folder (glasgow preset)")
    ap.add_argument("out", help="PNG to write")
    ap.add_argument("--images", default=None)
    ap.add_argument("--people", default="P36-P45")
    ap.add_argument("--window-s", type=float, default=6.0, help="time window of the preprocessing [s]")
    args = ap.parse_args()
    cfg = PreprocessConfig(v_range_mps=6.0, time_mode="window", window_s=args.window_s)
    if args.images is None:  # campaign 1 through the data registry (mirror, cache or download)
        from rtchannel.data_registry import fetch_folder

        args.images = fetch_folder("realdata/glasgow848/1Dataset")
    real, _ = load_real_images(args.images, people=parse_people(args.people))
    ds = DatasetReader(args.dataset)
    half, extent = args.window_s / 2, [-args.window_s / 2, args.window_s / 2, -6, 6]
    fig, axes = plt.subplots(2, len(ACTIVITIES), figsize=(3.2 * len(ACTIVITIES), 6), sharex=True, sharey=True)
    for k, act in enumerate(ACTIVITIES):
        r = [preprocess(im.signature.p_vt, im.signature.velocity, im.signature.time, cfg)
             for im in real if im.activity == act]
        s = [preprocess(a["p_vt"], a["velocity"], a["time"], cfg)
             for a in (next(iter(ds.load(i).values())) for i in ds.select(activity=act))]
        for row, (name, imgs) in enumerate(((f"real {args.people}", r), ("simulated", s))):
            ax = axes[row, k]
            if imgs:
                ax.imshow(np.mean(imgs, axis=0), origin="lower", aspect="auto", cmap="jet", vmin=0, vmax=1,
                          extent=extent)
            ax.set_title(f"{name} {act} (n = {len(imgs)})", fontsize=9)
            ax.set_ylim(-3, 3)
            ax.set_xlim(-half, half)
    for ax in axes[:, 0]:
        ax.set_ylabel("velocity [m/s]")
    for ax in axes[-1]:
        ax.set_xlabel("time from the motion centroid [s]")
    fig.suptitle("mean classifier input per activity (0 = 40 dB below each sample's maximum, 1 = maximum)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
