"""Render a spectrogram (dB or power on a velocity x time grid) into an image in exactly a given layout.

Simulated signatures written in the layout of real recordings (e.g. the Glasgow one) can be compared
side by side with them and read back through the same `processing.realdata.spectrogram_image` reader.

The plot box holds only the spectrogram, coloured as MATLAB's ``imagesc`` and matplotlib's ``imshow``
do: the span [top - span, top] dB (top = the strongest value of the grid unless given) is cut into N
equal bins, bin k gets colour entry k, values below the span get entry 0; colours are stored as
floor(255 c). Each box pixel takes the grid cell that contains its centre ("nearest", as ``imagesc``)
or a linear interpolation in dB between cell centres ("linear"); pixels outside the grid are below the
scale. Axes, labels, title and colour bar are drawn by matplotlib (Agg) around the box; the box itself
is placed with ``figimage`` at integer pixel offsets (no resampling) and checked pixel by pixel, and the
1-px frame (if the layout has one) is set on exact pixels, since an antialiased spine is not.
"""
from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from processing.atomic import atomic_path
from processing.realdata.colormaps import colormap_inverse
from processing.dsp.signatures import Signature
from processing.realdata.spectrogram_image import ImageLayout, SpectrogramImageError, cell_edges
from processing.errors import InputError


def _colour_indices(db: np.ndarray, top_db: float, layout: ImageLayout) -> np.ndarray:
    """Colour entry [0, N-1] of each dB value: floor((dB - (top - span)) / span * N), clipped."""
    n = layout.colormap_size
    x = (db - (top_db - layout.db_span)) / layout.db_span * n
    return np.clip(np.floor(np.where(np.isfinite(x), x, -1.0)), 0, n - 1).astype(np.intp)


def render_box(velocity: np.ndarray, time: np.ndarray, db: np.ndarray, layout: ImageLayout, *,
               top_db: float | None = None, interpolation: Literal["nearest", "linear"] = "nearest") -> np.ndarray:
    """The plot box's pixels (uint8 [rows, columns, 3]) for dB values [V, T] on ascending velocity [V]
    (m/s) and time [T] (s). `top_db`: value at the top of the colour scale (default: the grid's maximum).
    Raises ValueError for malformed axes or NaN / +inf values (-inf is allowed: below the scale)."""
    db = np.asarray(db, dtype=np.float64)
    velocity, time = np.asarray(velocity, dtype=np.float64), np.asarray(time, dtype=np.float64)
    v_edges, t_edges = cell_edges(velocity, "velocity"), cell_edges(time, "time")
    if db.shape != (v_edges.size - 1, t_edges.size - 1):
        raise InputError(f"dB grid is {db.shape}, axes give ({v_edges.size - 1}, {t_edges.size - 1})")
    if np.isnan(db).any() or np.isposinf(db).any():
        raise InputError("dB grid holds NaN or +inf")
    finite = db[np.isfinite(db)]
    top = (float(finite.max()) if finite.size else 0.0) if top_db is None else float(top_db)
    v_pix, t_pix = layout.row_velocity(), layout.column_time()
    iv = np.searchsorted(v_edges, v_pix, side="right") - 1
    it = np.searchsorted(t_edges, t_pix, side="right") - 1
    inside = ((iv >= 0) & (iv < db.shape[0]))[:, None] & ((it >= 0) & (it < db.shape[1]))[None, :]
    if interpolation == "nearest":
        vals = db[np.clip(iv, 0, db.shape[0] - 1)][:, np.clip(it, 0, db.shape[1] - 1)]
    elif interpolation == "linear":
        low = top - 2 * layout.db_span  # -inf would poison the interpolation; anything below the span is alike
        interp = RegularGridInterpolator((velocity, time), np.maximum(db, low))
        vv = np.clip(v_pix, velocity[0], velocity[-1])
        tt = np.clip(t_pix, time[0], time[-1])
        vals = interp(np.stack(np.meshgrid(vv, tt, indexing="ij"), axis=-1))
    else:
        raise InputError(f"interpolation must be 'nearest' or 'linear', not {interpolation!r}")
    idx = np.where(inside, _colour_indices(vals, top, layout), 0)
    return colormap_inverse(layout.colormap, layout.colormap_size).entries[idx]


def _decorate(fig, layout: ImageLayout, title: str | None) -> None:
    """Axes (ticks outward, so none enter the box), labels, title and a colour bar of relative dB."""
    w, h = layout.width, layout.height
    rows, cols = layout.box_shape
    # the axes' edges on the centres of the pixels just outside the box, where the Glasgow axis limits are
    ax = fig.add_axes(((layout.box_left - 0.5) / w, (h - layout.box_bottom - 1.5) / h, (cols + 1) / w, (rows + 1) / h))
    dt = (layout.time_right - layout.time_left) / cols
    dv = (layout.velocity_top - layout.velocity_bottom) / rows
    ax.set_xlim(layout.time_left - dt / 2, layout.time_right + dt / 2)
    ax.set_ylim(layout.velocity_bottom - dv / 2, layout.velocity_top + dv / 2)
    ax.set_facecolor("none")
    for s in ax.spines.values():
        s.set_visible(False)
    ax.tick_params(direction="out")
    ax.set_xlabel("Time [s]")
    ax.set_ylabel("Velocity [m/s]")
    if title:
        ax.set_title(title, fontsize=10)
    x0 = layout.box_right + 25
    if x0 + 55 <= w:  # room for a bar and its labels
        entries = colormap_inverse(layout.colormap, layout.colormap_size).entries
        cax = fig.add_axes((x0 / w, (h - layout.box_bottom - 1) / h, 18 / w, rows / h))
        cax.imshow(entries[::-1, None, :], aspect="auto", extent=(0, 1, -layout.db_span, 0),
                   interpolation="nearest")
        cax.set_xticks([])
        cax.yaxis.tick_right()
        cax.set_title("dB", fontsize=8)


def render_image(velocity: np.ndarray, time: np.ndarray, layout: ImageLayout, *, db: np.ndarray | None = None,
                 power: np.ndarray | None = None, top_db: float | None = None,
                 interpolation: Literal["nearest", "linear"] = "nearest", title: str | None = None,
                 decorations: bool = True, dpi: int = 100) -> np.ndarray:
    """The whole image (uint8 [height, width, 3]) of a spectrogram given as dB [V, T] or power [V, T]
    (>= 0; dB = 10 log10 power) on ascending velocity [V] m/s and time [T] s. See `render_box`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if (db is None) == (power is None):
        raise InputError("give exactly one of db and power")
    if db is None:
        power = np.asarray(power, dtype=np.float64)
        if np.isnan(power).any() or (power < 0).any():
            raise InputError("power must be >= 0 and not NaN")
        with np.errstate(divide="ignore"):
            db = 10.0 * np.log10(power)
    box = render_box(velocity, time, db, layout, top_db=top_db, interpolation=interpolation)
    red, green, blue = layout.background_rgb
    fig = Figure(figsize=(layout.width / dpi, layout.height / dpi), dpi=dpi,
                 facecolor=(red / 255.0, green / 255.0, blue / 255.0))
    canvas = FigureCanvasAgg(fig)
    if decorations:
        _decorate(fig, layout, title)
    fig.figimage(box, xo=layout.box_left, yo=layout.height - 1 - layout.box_bottom, origin="upper", zorder=10)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if img.shape[:2] != (layout.height, layout.width):
        raise RuntimeError(f"matplotlib drew {img.shape[1]}x{img.shape[0]} px, not {layout.width}x{layout.height}")
    sl = (slice(layout.box_top, layout.box_bottom + 1), slice(layout.box_left, layout.box_right + 1))
    if not np.array_equal(img[sl], box):
        raise RuntimeError("matplotlib did not place the plot box pixel-exactly")
    if layout.frame_rgb is not None:
        t, b, lft, r = layout.box_top - 1, layout.box_bottom + 1, layout.box_left - 1, layout.box_right + 1
        img[[t, b], lft:r + 1] = layout.frame_rgb
        img[t:b + 1, [lft, r]] = layout.frame_rgb
    return img


def write_spectrogram_image(path: str | Path, velocity: np.ndarray, time: np.ndarray, layout: ImageLayout,
                            **kwargs) -> Path:
    """Write a spectrogram as a PNG in `layout` (keywords as `render_image`). Returns the path.
    Raises SpectrogramImageError naming the file for bad input or an unknown colormap."""
    from PIL import Image

    path = Path(path)
    try:
        img = render_image(velocity, time, layout, **kwargs)
    except ValueError as e:
        raise SpectrogramImageError(f"{path}: {e}") from None
    with atomic_path(path) as tmp:
        Image.fromarray(img).save(tmp, format="PNG")
    return path


def through_image(sig: Signature, layout: ImageLayout, duration_s: float | None = None) -> Signature:
    """`sig` as an image in `layout` shows it: drawn (`render_box`: cells to pixels, 8-bit colour, the
    layout's dB span below the strongest cell, quieter cells at the bottom colour) and read back with
    `read_spectrogram_image` (below-scale pixels carry no power). Simulated signatures then share the
    display chain of real spectrogram images (a classifier trained on them sees what it sees on the images).

    Like the Glasgow script (``linspace(0, duration, n)`` over the window centres), the window centres are
    stretched over 0..`duration_s` [s] (default: the layout's time axis, edge to edge) before drawing. The result's
    range fields are empty (an image has none); `power` is the image's column power; `valid` and mean velocity are
    noise-aware exactly as for real images (`real_images.noise_aware`: columns 30 dB below the strongest one
    are noise), so a classifier sees the same masks on both."""
    from dataclasses import replace

    from processing.realdata.real_images import noise_aware
    from processing.realdata.spectrogram_image import read_spectrogram_image

    p = np.asarray(sig.p_vt, dtype=np.float64) * np.asarray(sig.power, dtype=np.float64)[None, :]
    with np.errstate(divide="ignore"):
        db = 10.0 * np.log10(p)
    t = np.asarray(sig.time, dtype=np.float64)
    if t.size > 1:
        t = np.linspace(0.0, float(duration_s), t.size) if duration_s is not None else \
            np.linspace(layout.time_left, layout.time_right, t.size)
    box = render_box(sig.velocity, t, db, layout)
    rgb = np.empty((layout.height, layout.width, 3), np.uint8)
    rgb[...] = layout.background_rgb
    rgb[layout.box_top:layout.box_bottom + 1, layout.box_left:layout.box_right + 1] = box
    out = noise_aware(read_spectrogram_image(rgb, layout, name="<simulated>").signature)
    return replace(out, range=np.zeros(0), range_distribution=np.zeros((0, out.time.size)))
