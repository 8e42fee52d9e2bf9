"""PNG figures of signatures: p(v,t) spectrograms, mean-velocity curves, range-time maps."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from processing.atomic import savefig_atomic  # noqa: E402
from processing.dsp import Signature  # noqa: E402

DYNAMIC_RANGE_DB = 40.0


def _db(p: np.ndarray) -> np.ndarray:
    peak = p.max() if p.size and p.max() > 0 else 1.0
    return 10 * np.log10(np.maximum(p / peak, 10 ** (-DYNAMIC_RANGE_DB / 10)))


def _edges(axis: np.ndarray) -> tuple[float, float]:
    step = axis[1] - axis[0] if axis.size > 1 else 1.0
    return float(axis[0] - step / 2), float(axis[-1] + step / 2)


def plot_pvt(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """p(v,t) of every link (dB, 40 dB range) with the mean radial velocity overlaid."""
    fig, axes = plt.subplots(1, len(sigs), figsize=(5.5 * len(sigs), 4), squeeze=False, constrained_layout=True)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.velocity))
        im = ax.imshow(_db(s.p_vt), origin="lower", aspect="auto", extent=extent, cmap="jet",
                       vmin=-DYNAMIC_RANGE_DB, vmax=0)
        ax.plot(s.time, s.mean_velocity, "w-", lw=1.2, label="mean velocity")
        ax.set(title=f"{name}: p(v,t)", xlabel="time [s]", ylabel="radial velocity [m/s] (+ = approaching)")
        ax.legend(loc="upper right", fontsize=8)
        fig.colorbar(im, ax=ax, label="dB")
    if title:
        fig.suptitle(title)
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_mean_velocity(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Mean radial velocity (seed eq. 8) of every link against time."""
    fig, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
    for (name, s), style in zip(sigs.items(), ("-", ":", "--", "-.") * 8):
        ax.plot(s.time, s.mean_velocity, style, lw=1.5, label=name)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set(xlabel="time [s]", ylabel="mean radial velocity [m/s]", title=title or "mean radial velocity")
    ax.grid(alpha=0.3)
    ax.legend()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_range(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Range distribution p'(r,t) (seed eq. 10) of every link as a range-time map."""
    fig, axes = plt.subplots(1, len(sigs), figsize=(5.5 * len(sigs), 4), squeeze=False, constrained_layout=True)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.range))
        im = ax.imshow(s.range_distribution, origin="lower", aspect="auto", extent=extent, cmap="viridis")
        ax.set(title=f"{name}: range distribution", xlabel="time [s]", ylabel="range [m]")
        fig.colorbar(im, ax=ax, label="p'(r,t)")
    if title:
        fig.suptitle(title)
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_all(sigs: dict[str, Signature], out_dir: Path, title: str = "") -> list[Path]:
    """All three figures into `out_dir`: pvt.png, mean_velocity.png, range.png."""
    out_dir = Path(out_dir)
    return [plot_pvt(sigs, out_dir / "pvt.png", title), plot_mean_velocity(sigs, out_dir / "mean_velocity.png", title),
            plot_range(sigs, out_dir / "range.png", title)]
