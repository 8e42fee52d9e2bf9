"""PNG figures of signatures: micro-Doppler spectrograms, mean-velocity curves, range-time maps and
range-Doppler maps.

Spectrograms and maps are drawn as a radar display shows them: power on one colour scale for the whole
recording (the strongest cell at 0 dB, `DYNAMIC_RANGE_DB` below it black-blue), i.e. p(v,t) times each
window's power. The per-window normalisation of p(v,t) (eq. 7) is what the classifier sees, but drawn as
it is a window with only receiver noise would look as bright as one with a person in it.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from processing.atomic import savefig_atomic  # noqa: E402
from processing.dsp import Signature  # noqa: E402

DYNAMIC_RANGE_DB = 40.0
RD_PANELS = 6  # range-Doppler maps shown per link


def _db(p: np.ndarray) -> np.ndarray:
    peak = p.max() if p.size and p.max() > 0 else 1.0
    return 10 * np.log10(np.maximum(p / peak, 10 ** (-DYNAMIC_RANGE_DB / 10)))


def _edges(axis: np.ndarray) -> tuple[float, float]:
    step = axis[1] - axis[0] if axis.size > 1 else 1.0
    return float(axis[0] - step / 2), float(axis[-1] + step / 2)


def _weighted(dist: np.ndarray, power: np.ndarray) -> np.ndarray:
    """Column-normalised distribution [X, T] back to power on one scale (unweighted if power is missing)."""
    return dist * power[None, :] if power.shape == (dist.shape[1],) and power.max(initial=0) > 0 else dist


def _save(fig, path: Path, title: str) -> Path:
    if title:
        fig.suptitle(title)
    path = savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_pvt(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Micro-Doppler spectrogram p(v,t) x window power of every link (dB re the recording's strongest cell,
    40 dB range) with the mean radial velocity (eq. 8) over the windows that carry signal."""
    fig, axes = plt.subplots(1, len(sigs), figsize=(5.5 * len(sigs), 4), squeeze=False, constrained_layout=True)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.velocity))
        im = ax.imshow(_db(_weighted(s.p_vt, s.power)), origin="lower", aspect="auto", extent=extent, cmap="jet",
                       vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        mv = np.where(s.valid, s.mean_velocity, np.nan)
        ax.plot(s.time, mv, "w-", lw=1.2, label="mean velocity")
        ax.set(title=f"{name}: micro-Doppler p(v,t)", xlabel="time [s]",
               ylabel="radial velocity [m/s] (+ = approaching)")
        ax.legend(loc="upper right", fontsize=8)
        fig.colorbar(im, ax=ax, label="dB re max")
    return _save(fig, path, title)


def plot_mean_velocity(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Mean radial velocity (seed eq. 8) of every link against time."""
    fig, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
    for (name, s), style in zip(sigs.items(), ("-", ":", "--", "-.") * 8):
        ax.plot(s.time, s.mean_velocity, style, lw=1.5, label=name)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set(xlabel="time [s]", ylabel="mean radial velocity [m/s]", title=title or "mean radial velocity")
    ax.grid(alpha=0.3)
    ax.legend()
    return _save(fig, path, "")


def plot_range(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Range-time map: the range distribution p'(r,t) (seed eq. 10) x window power, dB re max, 40 dB."""
    fig, axes = plt.subplots(1, len(sigs), figsize=(5.5 * len(sigs), 4), squeeze=False, constrained_layout=True)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.range))
        im = ax.imshow(_db(_weighted(s.range_distribution, s.power)), origin="lower", aspect="auto", extent=extent,
                       cmap="viridis", vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        ax.set(title=f"{name}: range-time map", xlabel="time [s]", ylabel="range [m]")
        fig.colorbar(im, ax=ax, label="dB re max")
    return _save(fig, path, title)


def plot_range_doppler(sigs: dict[str, Signature], path: Path, title: str = "", panels: int = RD_PANELS) -> Path | None:
    """Range-Doppler maps (range x radial velocity) of `panels` evenly spaced windows per link, one colour
    scale per link (dB re its strongest cell, 40 dB). None if no link carries maps."""
    have = {n: s for n, s in sigs.items() if s.range_doppler is not None and s.range_doppler.size}
    if not have:
        return None
    fig, axes = plt.subplots(len(have), panels, figsize=(2.4 * panels, 2.6 * len(have)), squeeze=False,
                             constrained_layout=True, sharex=True, sharey=True)
    for row, (name, s) in zip(axes, have.items()):
        rd = s.range_doppler
        db = _db(rd)
        pick = np.unique(np.linspace(0, rd.shape[2] - 1, panels).round().astype(int))
        extent = (*_edges(s.range_doppler_velocity), *_edges(s.range))
        for ax, k in zip(row, pick):
            im = ax.imshow(db[:, :, k], origin="lower", aspect="auto", extent=extent, cmap="jet",
                           vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
            ax.set_title(f"{name}, t = {s.range_doppler_time[k]:.2f} s", fontsize=8)
        for ax in row[len(pick):]:
            ax.axis("off")
        row[0].set_ylabel("range [m]")
    for ax in axes[-1]:
        ax.set_xlabel("velocity [m/s]")
    fig.colorbar(im, ax=axes, label="dB re max", shrink=0.8)
    return _save(fig, path, title)


def plot_all(sigs: dict[str, Signature], out_dir: Path, title: str = "") -> list[Path]:
    """All figures into `out_dir`: pvt.png, mean_velocity.png, range.png and (when the signatures carry
    range-Doppler maps) range_doppler.png."""
    out_dir = Path(out_dir)
    out = [plot_pvt(sigs, out_dir / "pvt.png", title), plot_mean_velocity(sigs, out_dir / "mean_velocity.png", title),
           plot_range(sigs, out_dir / "range.png", title)]
    rd = plot_range_doppler(sigs, out_dir / "range_doppler.png", title)
    return out + ([rd] if rd is not None else [])
