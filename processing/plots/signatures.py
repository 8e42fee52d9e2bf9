"""Figures of signatures: micro-Doppler spectrograms, mean-velocity curves, range-time maps and range-Doppler maps.

Every `plot_*` draws onto the Axes the caller gives (``ax=``: one per link for the per-link panels) or onto a
new figure, and returns the `Figure`; writing files is a separate step (`save_figure`, or `save_figures` for
the set `rtchannel simulate` writes). The old call with a file path in place of ``ax`` still works for one
release and warns (DeprecationWarning).

Spectrograms and maps are drawn as a radar display shows them: power on one colour scale for the whole
recording (the strongest cell at 0 dB, `DYNAMIC_RANGE_DB` below it black-blue), i.e. p(v,t) times each
window's power. The per-window normalisation of p(v,t) (eq. 7) is what the classifier sees, but drawn as
it is a window with only receiver noise would look as bright as one with a person in it.
"""
from __future__ import annotations

import os
import warnings
from typing import cast
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from processing.atomic import savefig_atomic
from processing.dsp.signatures import Signature
from processing.errors import InputError

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


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write `fig` to `path` atomically (format from the suffix; PNGs at 110 dpi, fast zlib level).

    Args:
        fig: a figure from one of the `plot_*` functions (or any matplotlib Figure).
        path: file to write (its folder must exist).

    Returns:
        `path` as a Path.
    """
    return savefig_atomic(fig, path, **_PNG)


def _links(sigs) -> dict[str, Signature]:
    """{link name: Signature} from a dict or a single `Signature` (named "")."""
    return {"": sigs} if isinstance(sigs, Signature) else dict(sigs)


def _old_path(ax, what: str):
    """The file path of the deprecated call ``plot_x(sigs, path, title)``, else None."""
    if isinstance(ax, (str, os.PathLike)):
        warnings.warn(f"{what}(sigs, path) is deprecated: use fig = {what}(sigs, ax=...) and save_figure(fig, path)",
                      DeprecationWarning, stacklevel=3)
        return Path(ax)
    return None


def _panels(ax, n: int, width_in: float, height_in: float, margins: dict, ncols: int | None = None):
    """(figure, [Axes] x n, whether the figure is ours): the caller's `ax` (one Axes, or a sequence of n) or a
    new figure of one row (or `ncols` columns) of n panels."""
    if ax is None:
        fig = _figure(width_in, height_in)
        cols = n if ncols is None else ncols
        _margins(fig, ncols=cols, nrows=-(-n // cols), **margins)
        return fig, list(fig.subplots(-(-n // cols), cols, squeeze=False).ravel()[:n]), True
    axes = list(np.ravel(np.asarray(ax, dtype=object)))
    if len(axes) != n:
        raise InputError(f"ax: {n} Axes needed (one per link), got {len(axes)}")
    return axes[0].figure, axes, False


def _finish(fig: Figure, own: bool, im, axes, title: str) -> Figure:
    """The shared colour bar (dB re max) and the title: in the right margin of our own figure, or beside the
    caller's Axes."""
    if im is not None:
        if own:
            _colorbar_right(fig, im)
        else:
            fig.colorbar(im, ax=axes, label="dB re max")
    if title:
        fig.suptitle(title, y=0.99, va="top")
    return fig


def _label(name: str, what: str) -> str:
    return f"{name}: {what}" if name else what


def plot_pvt(sigs, ax=None, title: str = "") -> Figure | Path:
    """Micro-Doppler spectrogram p(v,t) x window power of every link (dB re the recording's strongest cell,
    40 dB range) with the mean radial velocity (eq. 8) over the windows that carry signal.

    Args:
        sigs: a `Signature`, or {link name: Signature} to draw, one panel per link.
        ax: matplotlib Axes to draw on (one per link: an Axes or a sequence of them); default a new figure.
        title: figure title (default none).

    Returns:
        The `Figure` (write it with `save_figure`).
    """
    path = _old_path(ax, "plot_pvt")
    sigs = _links(sigs)
    fig, axes, own = _panels(None if path else ax, len(sigs), 5.2 * len(sigs) + 0.9, 4,
                             dict(left=0.75, right=1.2, bottom=0.5, top=0.6, wspace=0.8))
    im = None
    for a, (name, s) in zip(axes, sigs.items()):
        extent = (*_edges(s.time), *_edges(s.velocity))
        im = a.imshow(_db(_weighted(s.p_vt, s.power)), origin="lower", aspect="auto", extent=extent, cmap="jet",
                      vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        mv = np.where(s.valid, s.mean_velocity, np.nan)
        a.plot(s.time, mv, "w-", lw=1.2, label="mean velocity")
        a.set(title=_label(name, "micro-Doppler p(v,t)"), xlabel="time [s]",
              ylabel="radial velocity [m/s] (+ = approaching)")
        a.legend(loc="upper right", fontsize=8)
    fig = _finish(fig, own, im, axes, title)
    return save_figure(fig, path) if path else fig


def plot_mean_velocity(sigs, ax=None, title: str = "") -> Figure | Path:
    """Mean radial velocity [m/s] (seed eq. 8) of every link against time [s], one curve per link on one Axes.

    Args:
        sigs: a `Signature`, or {link name: Signature}.
        ax: one matplotlib Axes to draw on; default a new figure.
        title: Axes title (default "mean radial velocity").

    Returns:
        The `Figure` (write it with `save_figure`).
    """
    path = _old_path(ax, "plot_mean_velocity")
    sigs = _links(sigs)
    fig, (a,), _ = _panels(None if path else ax, 1, 7, 3.5, dict(left=0.7, right=0.15, bottom=0.5, top=0.35))
    for (name, s), style in zip(sigs.items(), ("-", ":", "--", "-.") * 8):
        a.plot(s.time, s.mean_velocity, style, lw=1.5, label=name or None)
    a.axhline(0, color="0.6", lw=0.8)
    a.set(xlabel="time [s]", ylabel="mean radial velocity [m/s]", title=title or "mean radial velocity")
    a.grid(alpha=0.3)
    if any(sigs):
        a.legend()
    return save_figure(fig, path) if path else fig


def plot_range(sigs, ax=None, title: str = "") -> Figure | Path:
    """Range-time map: the range distribution p'(r,t) (seed eq. 10) x window power, dB re max, 40 dB.

    Args:
        sigs: a `Signature`, or {link name: Signature} to draw, one panel per link.
        ax: matplotlib Axes to draw on (one per link); default a new figure.
        title: figure title (default none).

    Returns:
        The `Figure` (write it with `save_figure`).
    """
    path = _old_path(ax, "plot_range")
    sigs = _links(sigs)
    fig, axes, own = _panels(None if path else ax, len(sigs), 5.2 * len(sigs) + 0.9, 4,
                             dict(left=0.6, right=1.2, bottom=0.5, top=0.6, wspace=0.6))
    im = None
    for a, (name, s) in zip(axes, sigs.items()):
        extent = (*_edges(s.time), *_edges(s.range))
        im = a.imshow(_db(_weighted(s.range_distribution, s.power)), origin="lower", aspect="auto", extent=extent,
                      cmap="viridis", vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
        a.set(title=_label(name, "range-time map"), xlabel="time [s]", ylabel="range [m]")
    fig = _finish(fig, own, im, axes, title)
    return save_figure(fig, path) if path else fig


def plot_range_doppler(sigs, ax=None, title: str = "", panels: int = RD_PANELS) -> Figure | Path | None:
    """Range-Doppler maps (range [m] x radial velocity [m/s]) of `panels` evenly spaced windows per link, one
    colour scale per link (dB re its strongest cell, 40 dB). None if no link carries maps.

    Each link is one row: its maps side by side in one Axes, separated by gaps, each with its own velocity
    ticks (one Axes per row instead of one per map: creating and ticking Axes is most of the drawing time).

    Args:
        sigs: a `Signature`, or {link name: Signature}; links without maps are left out.
        ax: matplotlib Axes to draw on (one per link that carries maps); default a new figure.
        title: figure title (default none).
        panels: maps shown per link.

    Returns:
        The `Figure` (write it with `save_figure`), or None.
    """
    path = _old_path(ax, "plot_range_doppler")
    have = {n: s for n, s in _links(sigs).items() if s.range_doppler is not None and s.range_doppler.size}
    if not have:
        return None
    from matplotlib.ticker import MaxNLocator

    fig, axes, own = _panels(None if path else ax, len(have), 2.4 * panels + 0.9, 2.6 * len(have),
                             dict(left=0.6, right=1.2, bottom=0.5, top=0.55, hspace=0.6), ncols=1)
    im = None
    for a, (name, s) in zip(axes, have.items()):
        rd, rd_time, rd_v = s.range_doppler, s.range_doppler_time, s.range_doppler_velocity
        assert rd is not None and rd_time is not None and rd_v is not None  # `have` holds links with a map
        db = _db(rd)
        pick = np.unique(np.linspace(0, rd.shape[2] - 1, panels).round().astype(int))
        (v0, v1), (r0, r1) = _edges(rd_v), _edges(s.range)
        width = v1 - v0
        step = 1.08 * width  # map width plus a gap
        v_ticks = [v for v in MaxNLocator(4).tick_values(v0, v1) if v0 <= v <= v1]
        ticks, labels = [], []
        for j, k in enumerate(pick):
            x0 = j * step
            im = a.imshow(db[:, :, k], origin="lower", aspect="auto", extent=(x0, x0 + width, r0, r1), cmap="jet",
                          vmin=-DYNAMIC_RANGE_DB, vmax=0, interpolation="nearest")
            a.text(x0 + width / 2, r1, _label(name, f"t = {rd_time[k]:.2f} s").replace(": ", ", "),
                   fontsize=8, ha="center", va="bottom")
            ticks += [x0 + v - v0 for v in v_ticks]
            labels += [f"{v:g}" for v in v_ticks]
        a.set_xlim(0, (len(pick) - 1) * step + width)
        a.set_ylim(r0, r1)
        a.set_xticks(ticks, labels)
        a.set_ylabel("range [m]")
        a.set_xlabel("velocity [m/s]")
        for side in ("top", "right", "left", "bottom"):
            a.spines[side].set_visible(False)
    fig = _finish(fig, own, im, axes, title)
    return save_figure(fig, path) if path else fig


def figures(sigs, title: str = "") -> dict[str, Figure]:
    """The figures `rtchannel simulate` writes, by name: "pvt", "mean_velocity", "range" and (when the
    signatures carry range-Doppler maps) "range_doppler".

    Args:
        sigs: a `Signature`, or {link name: Signature}.
        title: figure title (default none).
    """
    # without the deprecated path argument every plot returns its Figure
    out = {"pvt": plot_pvt(sigs, title=title), "mean_velocity": plot_mean_velocity(sigs, title=title),
           "range": plot_range(sigs, title=title)}
    rd = plot_range_doppler(sigs, title=title)
    if rd is not None:
        out["range_doppler"] = rd
    return cast(dict[str, Figure], out)


def save_figures(sigs, out_dir: str | Path, title: str = "") -> list[Path]:
    """All `figures` into `out_dir` as NAME.png (pvt.png, mean_velocity.png, range.png, range_doppler.png).

    Args:
        sigs: a `Signature`, or {link name: Signature}.
        out_dir: folder to write into (created if missing).
        title: figure title (default none).

    Returns:
        The paths written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [save_figure(fig, out_dir / f"{name}.png") for name, fig in figures(sigs, title).items()]


def plot_all(sigs, out_dir: str | Path, title: str = "") -> list[Path]:
    """Deprecated name of `save_figures` (warns; kept for one release).

    Args:
        sigs: a `Signature`, or {link name: Signature}.
        out_dir: folder to write into.
        title: figure title.
    """
    warnings.warn("plot_all / rtchannel.plot_signatures is deprecated: use save_figures(sigs, out_dir) or "
                  "SimulationResult.save_figures(out_dir)", DeprecationWarning, stacklevel=2)
    return save_figures(sigs, out_dir, title)
