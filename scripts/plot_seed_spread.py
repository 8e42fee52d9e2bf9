"""Campaign-1 accuracy of every training seed against its simulated held-out-deployment validation accuracy,
one colour per experiment folder, with the folder's ensembles as horizontal lines (docs/results.md, issue 37).

Usage: python scripts/plot_seed_spread.py OUT.png LABEL=DIR [LABEL=DIR ...]
A DIR holds mS.pt checkpoints with mS_c1/metrics.json beside them (`rtchannel evaluate --out`), and optionally
ensembles E*.pt with E*_c1/metrics.json.
"""
import glob
import json
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import torch  # noqa: E402


def _accuracy(folder: Path) -> float | None:
    p = folder / "metrics.json"
    return 100 * json.loads(p.read_text())["accuracy"] if p.exists() else None


def main(out: str, specs: list[str]) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.2), layout="constrained")
    for k, spec in enumerate(specs):
        label, folder = spec.split("=", 1)
        d, colour = Path(folder), f"C{k}"
        xs, ys = [], []
        for pt in sorted(glob.glob(str(d / "m*.pt"))):
            seed = re.findall(r"m(\d+)\.pt$", pt)[0]
            c1 = _accuracy(d / f"m{seed}_c1")
            if c1 is None:
                continue
            meta = torch.load(pt, map_location="cpu", weights_only=False)["meta"]
            xs.append(100 * meta["val_accuracy"])
            ys.append(c1)
            ax.annotate(seed, (xs[-1], ys[-1]), fontsize=7, xytext=(3, 2), textcoords="offset points")
        ax.scatter(xs, ys, color=colour, label=f"{label}: single seeds")
        ens = [a for e in sorted(glob.glob(str(d / "E*_c1"))) if (a := _accuracy(Path(e))) is not None]
        for j, a in enumerate(ens):
            ax.axhline(a, color=colour, lw=0.8, ls="--", label=f"{label}: ensembles" if j == 0 else None)
    ax.set(xlabel="simulated held-out-deployment validation accuracy [%]",
           ylabel="campaign 1 accuracy (300 real images) [%]",
           title="Sim-only models: seeds, ensembles (dashed)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
