"""The classifier's input for both intensities (p(v,t), seed eq. 7, and the spectrogram, eq. 6) of real images,
as recorded and with the robustness grid's noise floor 5 dB higher (a picture for docs/results.md).

    python scripts/intensity_inputs.py OUT.png [--real FOLDER (default: campaign 1 through the data registry)]

One row per image (a sit-down and a fall of subject P37, repetition 1): the network input [64 x 64] of
`preprocess` with the README's settings (+-6 m/s, a 6 s window), 0 = 40 dB under the input's maximum.
"""
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from processing.classifier.perturb import change_floor  # noqa: E402
from processing.classifier.preprocess import PreprocessConfig, preprocess  # noqa: E402
from processing.realdata.real_images import read_real_image  # noqa: E402

IMAGES = [("sit", "2P37A02R01.png"), ("fall", "6P37A06R01.png")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--real", default=None)
    a = ap.parse_args()
    if a.real is None:
        from rtchannel.data_registry import fetch_folder

        a.real = fetch_folder("realdata/glasgow848/1Dataset")
    base = PreprocessConfig(v_range_mps=6.0, time_mode="window", window_s=6.0)
    cfgs = [("p(v,t)", base), ("spectrogram", base.model_copy(update={"intensity": "power"}))]
    fig, axes = plt.subplots(len(IMAGES), 4, figsize=(12, 3.2 * len(IMAGES)), constrained_layout=True)
    for row, (act, name) in zip(axes, IMAGES):
        sig = read_real_image(Path(a.real) / name)
        versions = [("as recorded", sig), ("floor +5 dB", change_floor(sig, 5.0))]
        col = 0
        for label, cfg in cfgs:
            for when, s in versions:
                x = preprocess(s.p_vt, s.velocity, s.time, cfg, s.valid, s.power)
                im = row[col].imshow(x, origin="lower", aspect="auto", extent=(-3, 3, -6, 6), vmin=0, vmax=1,
                                     cmap="jet")
                row[col].set_title(f"{act} ({name[:-4]}): {label}, {when}", fontsize=8)
                row[col].set_xlabel("time in window [s]")
                col += 1
        row[0].set_ylabel("velocity [m/s]")
    fig.colorbar(im, ax=axes, shrink=0.8, label="input (0: 40 dB under the maximum)")
    fig.savefig(a.out, dpi=110)
    print("wrote", a.out)


if __name__ == "__main__":
    main()
