"""PNG figures of signatures: micro-Doppler spectrograms, mean-velocity curves, range-time maps and
range-Doppler maps.

Spectrograms and maps are drawn as a radar display shows them: power on one colour scale for the whole
recording (the strongest cell at 0 dB, `DYNAMIC_RANGE_DB` below it black-blue), i.e. p(v,t) times each
window's power. The per-window normalisation of p(v,t) (eq. 7) is what the classifier sees, but drawn as
it is a window with only receiver noise would look as bright as one with a person in it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from processing.atomic import savefig_atomic
from processing.dsp.signatures import Signature

DYNAMIC_RANGE_DB = 40.0
RD_PANELS = 6  # range-Doppler maps shown per link
# Cheap on purpose (`rtchannel simulate` draws these by default): figures are plain `Figure`s on the Agg
# canvas (no pyplot: no backend selection, 0.1-0.2 s less to import), margins are fixed in inches instead of a
# layout engine (constrained layout measured every tick label again: about half of the drawing time), and
# PNGs are deflated at zlib level 1 (1.4x faster to encode than the default 6, files ~15% larger).
_PNG = {"dpi": 110, "pil_kwargs": {"compress_level": 1}}


def _db(p: np.ndarray) -> np.ndarray:
    peak = p.max() if p.size and p.max() > 0 else 1.0
    return 10 * np.log10(np.maximum(p / peak, 10 ** (-DYNAMIC_RANGE_DB / 10)))


def _edges(axis: np.ndarray) -> tuple[float, float]:
    step = axis[1] - axis[0] if axis.size > 1 else 1.0
    return float(axis[0] - step / 2), float(axis[-1] + step / 2)


def _weighted(dist: np.ndarray, power: np.ndarray) -> np.ndarray:
    """Column-normalised distribution [X, T] back to power on one scale (unweighted if power is missing)."""
    return dist * power[None, :] if power.shape == (dist.shape[1],) and power.max(initial=0) > 0 else dist


def _figure(width_in: float, height_in: float) -> Figure:
    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)  # Agg, whatever backend pyplot may have chosen in this process
    return fig


def _margins(fig: Figure, left: float, right: float, bottom: float, top: float, wspace: float = 0.0,
             hspace: float = 0.0, ncols: int = 1, nrows: int = 1) -> None:
    """Subplot margins and gaps given in inches (so they hold for any number of panels)."""
    w, h = fig.get_size_inches()
    cell_w = (w - left - right - (ncols - 1) * wspace) / ncols
    cell_h = (h - bottom - top - (nrows - 1) * hspace) / nrows
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wspace / cell_w, hspace=hspace / cell_h)


def _colorbar_right(fig: Figure, im) -> None:
    """One colour bar in the figure's right margin (1.2 in) for every map: all share the -40..0 dB scale
    (each map re its own strongest cell), and one bar is one Axes fewer to draw per map."""
    w = fig.get_figwidth()
    fig.colorbar(im, cax=fig.add_axes((1 - 0.95 / w, 0.15, 0.15 / w, 0.7)), label="dB re max")


def _save(fig, path: Path, title: str) -> Path:
    if title:
        fig.suptitle(title, y=0.99, va="top")
    return savefig_atomic(fig, path, **_PNG)


def plot_pvt(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Micro-Doppler spectrogram p(v,t) x window power of every link (dB re the recording's strongest cell,
    40 dB range) with the mean radial velocity (eq. 8) over the windows that carry signal.

    Args:
        sigs: {link name: Signature} to draw, one panel per link.
        path: PNG file to write.
        title: figure title (default none).

    Returns:
        `path`.
    """
    fig = _figure(5.2 * len(sigs) + 0.9, 4)
    _margins(fig, left=0.75, right=1.2, bottom=0.5, top=0.6, wspace=0.8, ncols=len(sigs))
    axes = fig.subplots(1, len(sigs), squeeze=False)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.velocity))
        im = ax.imshow(_db(_weighted(s.p_vt, s.power)), origin="lower", aspect="auto", extent=extent, cmap="jet",
                       vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        mv = np.where(s.valid, s.mean_velocity, np.nan)
        ax.plot(s.time, mv, "w-", lw=1.2, label="mean velocity")
        ax.set(title=f"{name}: micro-Doppler p(v,t)", xlabel="time [s]",
               ylabel="radial velocity [m/s] (+ = approaching)")
        ax.legend(loc="upper right", fontsize=8)
    _colorbar_right(fig, im)
    return _save(fig, path, title)


def plot_mean_velocity(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Mean radial velocity [m/s] (seed eq. 8) of every link against time [s].

    Args:
        sigs: {link name: Signature} to draw, one curve per link.
        path: PNG file to write.
        title: figure title (default none).

    Returns:
        `path`.
    """
    fig = _figure(7, 3.5)
    _margins(fig, left=0.7, right=0.15, bottom=0.5, top=0.35)
    ax = fig.subplots()
    for (name, s), style in zip(sigs.items(), ("-", ":", "--", "-.") * 8):
        ax.plot(s.time, s.mean_velocity, style, lw=1.5, label=name)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set(xlabel="time [s]", ylabel="mean radial velocity [m/s]", title=title or "mean radial velocity")
    ax.grid(alpha=0.3)
    ax.legend()
    return _save(fig, path, "")


def plot_range(sigs: dict[str, Signature], path: Path, title: str = "") -> Path:
    """Range-time map: the range distribution p'(r,t) (seed eq. 10) x window power, dB re max, 40 dB.

    Args:
        sigs: {link name: Signature} to draw, one panel per link.
        path: PNG file to write.
        title: figure title (default none).

    Returns:
        `path`.
    """
    fig = _figure(5.2 * len(sigs) + 0.9, 4)
    _margins(fig, left=0.6, right=1.2, bottom=0.5, top=0.6, wspace=0.6, ncols=len(sigs))
    axes = fig.subplots(1, len(sigs), squeeze=False)
    for ax, (name, s) in zip(axes[0], sigs.items()):
        extent = (*_edges(s.time), *_edges(s.range))
        im = ax.imshow(_db(_weighted(s.range_distribution, s.power)), origin="lower", aspect="auto", extent=extent,
                       cmap="viridis", vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        ax.set(title=f"{name}: range-time map", xlabel="time [s]", ylabel="range [m]")
    _colorbar_right(fig, im)
    return _save(fig, path, title)


def plot_range_doppler(sigs: dict[str, Signature], path: Path, title: str = "", panels: int = RD_PANELS) -> Path | None:
    """Range-Doppler maps (range x radial velocity) of `panels` evenly spaced windows per link, one colour
    scale per link (dB re its strongest cell, 40 dB). None if no link carries maps.

    Each link is one row: its maps side by side in one Axes, separated by gaps, each with its own velocity
    ticks (one Axes per row instead of one per map: creating and ticking Axes is most of the drawing time)."""
    have = {n: s for n, s in sigs.items() if s.range_doppler is not None and s.range_doppler.size}
    if not have:
        return None
    from matplotlib.ticker import MaxNLocator

    fig = _figure(2.4 * panels + 0.9, 2.6 * len(have))
    _margins(fig, left=0.6, right=1.2, bottom=0.5, top=0.55, hspace=0.6, nrows=len(have))
    axes = fig.subplots(len(have), 1, squeeze=False)[:, 0]
    for ax, (name, s) in zip(axes, have.items()):
        rd = s.range_doppler
        db = _db(rd)
        pick = np.unique(np.linspace(0, rd.shape[2] - 1, panels).round().astype(int))
        (v0, v1), (r0, r1) = _edges(s.range_doppler_velocity), _edges(s.range)
        width = v1 - v0
        step = 1.08 * width  # map width plus a gap
        v_ticks = [v for v in MaxNLocator(4).tick_values(v0, v1) if v0 <= v <= v1]
        ticks, labels = [], []
        for j, k in enumerate(pick):
            x0 = j * step
            im = ax.imshow(db[:, :, k], origin="lower", aspect="auto", extent=(x0, x0 + width, r0, r1), cmap="jet",
                           vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
            ax.text(x0 + width / 2, r1, f"{name}, t = {s.range_doppler_time[k]:.2f} s", fontsize=8, ha="center",
                    va="bottom")
            ticks += [x0 + v - v0 for v in v_ticks]
            labels += [f"{v:g}" for v in v_ticks]
        ax.set_xlim(0, (len(pick) - 1) * step + width)
        ax.set_ylim(r0, r1)
        ax.set_xticks(ticks, labels)
        ax.set_ylabel("range [m]")
        ax.set_xlabel("velocity [m/s]")
        for side in ("top", "right", "left", "bottom"):
            ax.spines[side].set_visible(False)
    _colorbar_right(fig, im)
    return _save(fig, path, title)


def plot_all(sigs: dict[str, Signature], out_dir: Path, title: str = "") -> list[Path]:
    """All figures into `out_dir`: pvt.png, mean_velocity.png, range.png and (when the signatures carry
    range-Doppler maps) range_doppler.png.

    Args:
        sigs: {link name: Signature}.
        out_dir: folder to write into (created if missing).
        title: figure title (default none).

    Returns:
        The paths written.
    """
    out_dir = Path(out_dir)
    out = [plot_pvt(sigs, out_dir / "pvt.png", title), plot_mean_velocity(sigs, out_dir / "mean_velocity.png", title),
           plot_range(sigs, out_dir / "range.png", title)]
    rd = plot_range_doppler(sigs, out_dir / "range_doppler.png", title)
    return out + ([rd] if rd is not None else [])
