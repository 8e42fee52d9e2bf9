"""The transfer study's figure: test accuracy against the real recordings per class, one line per arm with a band."""
from __future__ import annotations

from pathlib import Path

import numpy as np

_STYLE = {"real": ("C0", "o", "real only"), "finetune": ("C1", "s", "sim-pretrained, fine-tuned"),
          "mixed": ("C2", "^", "sim-pretrained, sim + real mixed")}


def plot_transfer(summary: list[dict], path: str | Path | None = None, ax=None, title: str | None = None,
                  band: str = "std"):
    """Accuracy [%] against real images per class (symmetric-log axis, so 0 = simulation only sits at the left).

    Args:
        summary: rows of `processing.classifier.transfer_report.summarise` (arm, shots_per_class,
            accuracy_pct_mean, accuracy_pct_std, accuracy_pct_min, accuracy_pct_max).
        path: PNG to write (atomically); None: only draw.
        ax: matplotlib Axes to draw onto (default: a new figure).
        title: figure title.
        band: 'std' (mean +- one standard deviation over folds and seeds) or 'range' (minimum to maximum).

    Returns:
        The figure.
    """
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = ax.figure if ax is not None else plt.subplots(figsize=(7.5, 4.5))[0]
    ax = ax if ax is not None else fig.axes[0]

    def lo_hi(rows):
        m = np.array([r["accuracy_pct_mean"] for r in rows])
        if band == "range":
            return np.array([r["accuracy_pct_min"] for r in rows]), np.array([r["accuracy_pct_max"] for r in rows])
        s = np.array([r["accuracy_pct_std"] for r in rows])
        return m - s, m + s

    sim = [r for r in summary if r["arm"] == "sim"]
    if sim:
        lo, hi = lo_hi(sim)
        ax.axhline(sim[0]["accuracy_pct_mean"], color="k", ls="--", lw=1.2,
                   label=f"simulation only ({sim[0]['accuracy_pct_mean']:.1f} %)")
        ax.axhspan(lo[0], hi[0], color="k", alpha=0.08)
    for arm, (color, marker, label) in _STYLE.items():
        rows = sorted((r for r in summary if r["arm"] == arm), key=lambda r: r["shots_per_class"])
        if arm != "real" and sim:  # at 0 shots the pretrained arms are the simulation-only network
            rows = [dict(sim[0], arm=arm)] + rows
        if not rows:
            continue
        x = np.array([r["shots_per_class"] for r in rows])
        m = np.array([r["accuracy_pct_mean"] for r in rows])
        lo, hi = lo_hi(rows)
        ax.plot(x, m, marker=marker, color=color, label=label)
        ax.fill_between(x, lo, hi, color=color, alpha=0.15)
    ax.set_xscale("symlog", linthresh=1.0)
    ticks = sorted({round(r["shots_per_class"], 1) for r in summary})
    ax.set_xticks(ticks)
    ax.set_xticklabels([f"{t:g}" for t in ticks])
    ax.set_xlabel("real recordings per class in training")
    ax.set_ylabel("accuracy on held-out people [%]")
    ax.set_ylim(top=100)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    if path is not None:
        from processing.plots.classifier import save_figure

        save_figure(fig, path)
    return fig


__all__ = ["plot_transfer"]
