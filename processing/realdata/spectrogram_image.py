"""Micro-Doppler spectrogram images: layout, reader (image -> dB grid -> p(v,t)), Glasgow preset and names.

Real recordings that exist only as rendered figures (e.g. the Glasgow "Radar signatures of human
activities" set, DOI 10.5525/gla.researchdata.848) are read back into the project's p(v,t) (seed eq. 7)
and mean velocity (eq. 8) by inverting the colormap pixel by pixel. The writer that renders simulated
signatures in the same layout is `processing.realdata.spectrogram_image_writer`.

Pixel convention: 0-based (row, column) indices with row 0 at the top, as numpy indexes an image; the
plot box is given by its first and last row and column, *inclusive*. The axis values of the layout are
those at the box's outer edges (matplotlib's ``extent``), so pixel centres sit half a pixel inside.

dB convention: the image shows a dB scale whose top is the strongest pixel of the recording; the reader
returns dB relative to that top (0 dB = top of the colour scale, -span = bottom). Colour entry k of N
covers [-span + k span/N, -span + (k+1) span/N) and is read as that bin's centre, so an exact colour
carries at most span/(2N) of error (0.078 dB for 40 dB and 256 colours; L span/(2N) for colormaps whose
8-bit entries repeat in runs of L, see `processing.realdata.colormaps.ColormapInverse`). The Glasgow images are
20 log10 of an STFT *magnitude*; 20 log10 |S| = 10 log10 |S|^2, so power = 10^(dB/10) either way.

Floor: the bottom colour holds everything from -span + span/N dB down to -inf, i.e. "below the scale".
By default (`floor="zero"`) such pixels get power 0, so a column with nothing above the floor is empty
(p = 0, mean velocity 0, valid False, as in `processing.dsp.signatures`) instead of a uniform 1e-4 pedestal that
would pull the mean velocity of quiet columns toward the middle of the axis. `floor="keep"` gives them
the floor bin's centre value.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.ndimage import distance_transform_edt

from processing.errors import InputError
from processing.realdata.ancortek import GLASGOW_ACTIVITY_CODES
from processing.realdata.colormaps import colormap_inverse
from processing.dsp.signatures import DSPConfig, Signature, _normalise, mean_velocity

# Colour distance (Euclidean, 8-bit levels) within which a pixel counts as a colormap colour: renderers
# truncate (or round) 255 c, i.e. <= 1 level per channel, sqrt(3) ~ 1.7 in all; 6 leaves room for
# blends of neighbouring entries, while text and tick marks over the image sit 50+ levels away.
MAX_COLOUR_DISTANCE = 6.0
# Fraction of the box allowed off the colormap: the Glasgow images have exactly 54 tick-mark pixels
# inside the box (0.045 %, all 360 images); 1 % (~1200 px) also lets a few grid lines through, while a
# wrong colormap or layout puts most of the box off the map.
MAX_OFF_MAP_FRACTION = 0.01

RGB = tuple[int, int, int]


# spectrogram images are < 1 MP (Glasgow: 560 x 420); 2^25 (32 MP, 100 MB as RGB) still takes an 8K screenshot,
# and bounds what a few hundred bytes of compressed PNG claiming 40000 x 40000 may ask to allocate
MAX_IMAGE_PIXELS = 1 << 25


class SpectrogramImageError(InputError):
    """A spectrogram image (or its file name, or layout) cannot be read; the message names the file."""


class ImageLayout(BaseModel):
    """Where and how a spectrogram is drawn in an image (pixel indices 0-based, row 0 at the top)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    width: int = Field(gt=0, description="image width [px]")
    height: int = Field(gt=0, description="image height [px]")
    box_top: int = Field(ge=0, description="first row of the coloured plot area (inclusive)")
    box_bottom: int = Field(ge=0, description="last row of the plot area (inclusive)")
    box_left: int = Field(ge=0, description="first column of the plot area (inclusive)")
    box_right: int = Field(ge=0, description="last column of the plot area (inclusive)")
    velocity_top: float = Field(description="radial velocity at the top edge of row box_top [m/s]")
    velocity_bottom: float = Field(description="radial velocity at the bottom edge of row box_bottom [m/s]")
    time_left: float = Field(description="time at the left edge of column box_left [s]")
    time_right: float = Field(description="time at the right edge of column box_right [s]")
    colormap: str = Field("matlab_jet", description="'matlab_jet' or a matplotlib colormap name; checked "
                          "when an image is read or written, so that the error can name the file")
    colormap_size: int = Field(256, ge=2, le=4096, description="number of discrete colours N")
    db_span: float = Field(40.0, gt=0, description="dB from the bottom to the top of the colour scale")
    frame_rgb: tuple[int, int, int] | None = Field(
        None, description="colour of a 1-px frame drawn just outside the box (None: no frame)")
    background_rgb: tuple[int, int, int] = Field((240, 240, 240), description="figure colour for the writer")

    @model_validator(mode="after")
    def _check(self) -> "ImageLayout":
        if not (self.box_top < self.box_bottom < self.height and self.box_left < self.box_right < self.width):
            raise InputError(f"plot box rows {self.box_top}-{self.box_bottom}, columns {self.box_left}-"
                             f"{self.box_right} must be ordered and inside the {self.width}x{self.height} image")
        if self.frame_rgb is not None and (min(self.box_top, self.box_left) < 1 or self.box_bottom > self.height - 2
                                           or self.box_right > self.width - 2):
            raise InputError("a frame needs one pixel round the plot box inside the image")
        if self.velocity_top == self.velocity_bottom or not self.time_left < self.time_right:
            raise InputError("velocity_top must differ from velocity_bottom and time_left < time_right")
        for c in (self.frame_rgb or (0, 0, 0)) + self.background_rgb:
            if not 0 <= c <= 255:
                raise InputError(f"colour component {c} outside 0-255")
        return self

    @property
    def box_shape(self) -> tuple[int, int]:
        """(rows, columns) of the plot box."""
        return self.box_bottom - self.box_top + 1, self.box_right - self.box_left + 1

    def row_velocity(self) -> np.ndarray:
        """Velocity [m/s] at the centre of each box row, top row first."""
        n = self.box_shape[0]
        return self.velocity_top + (np.arange(n) + 0.5) * (self.velocity_bottom - self.velocity_top) / n

    def column_time(self) -> np.ndarray:
        """Time [s] at the centre of each box column, left column first."""
        n = self.box_shape[1]
        return self.time_left + (np.arange(n) + 0.5) * (self.time_right - self.time_left) / n

    def velocity_edges(self) -> np.ndarray:
        """Ascending velocity edges [rows + 1] of the box rows [m/s]."""
        lo, hi = sorted((self.velocity_top, self.velocity_bottom))
        return np.linspace(lo, hi, self.box_shape[0] + 1)

    def time_edges(self) -> np.ndarray:
        """Ascending time edges [columns + 1] of the box columns [s]."""
        return np.linspace(self.time_left, self.time_right, self.box_shape[1] + 1)


# ---- Glasgow preset ------------------------------------------------------------------------------
# Measured on all 360 images of campaign 1: a 1-px frame of colour (38, 38, 38) on rows 36 and 354 and
# columns 64 and 442 (10 s recordings) or 448 (5 s); the coloured box is strictly inside. The inward
# tick marks (54 px inside the box) put 0 m/s on row 195 with 53 rows per 2 m/s, i.e. +-6 m/s on the
# frame rows' centres, and the time ticks (76.8 px/s for 5 s, 37.8 px/s for 10 s, within 0.6 px) put 0
# and T on the frame columns: the axis limits are on the frame, half a pixel outside the box.
GLASGOW_FRAME = {"top": 36, "bottom": 354, "left": 64}
GLASGOW_FRAME_RIGHT = {5.0: 448, 10.0: 442}
GLASGOW_FRAME_RGB = (38, 38, 38)
GLASGOW_V_LIMIT = 6.0


def glasgow_layout(duration_s: float = 5.0) -> ImageLayout:
    """Layout of the Glasgow campaign-1 images: 560x420, MATLAB jet(256), 40 dB, +-6 m/s, 0-5 s or 0-10 s."""
    if duration_s not in GLASGOW_FRAME_RIGHT:
        raise SpectrogramImageError(f"Glasgow images are 5 s or 10 s long, not {duration_s} s")
    f = dict(GLASGOW_FRAME, right=GLASGOW_FRAME_RIGHT[duration_s])
    dv = 2 * GLASGOW_V_LIMIT / (f["bottom"] - f["top"])
    dt = duration_s / (f["right"] - f["left"])
    return ImageLayout(width=560, height=420, box_top=f["top"] + 1, box_bottom=f["bottom"] - 1,
                       box_left=f["left"] + 1, box_right=f["right"] - 1,
                       velocity_top=GLASGOW_V_LIMIT - dv / 2, velocity_bottom=-GLASGOW_V_LIMIT + dv / 2,
                       time_left=dt / 2, time_right=duration_s - dt / 2, colormap="matlab_jet",
                       colormap_size=256, db_span=40.0, frame_rgb=GLASGOW_FRAME_RGB)


def detect_glasgow_duration(rgb: np.ndarray) -> float | None:
    """5.0 or 10.0 [s] from where the Glasgow plot frame's right edge is in an RGB image [420, 560, 3];
    None if the image has no Glasgow frame."""
    if rgb.shape[:2] != (420, 560):
        return None
    f = GLASGOW_FRAME
    is_frame = np.all(rgb == np.array(GLASGOW_FRAME_RGB, dtype=rgb.dtype), axis=-1)
    rows = slice(f["top"] + 1, f["bottom"])  # the corner pixels are blended: leave them out
    if not (is_frame[rows, f["left"]].all() and is_frame[f["top"], f["left"] + 1:440].all()):
        return None
    hits = [t for t, col in GLASGOW_FRAME_RIGHT.items() if is_frame[rows, col].all()]
    return hits[0] if len(hits) == 1 else None


class GlasgowName(NamedTuple):
    """Labels in a Glasgow file name such as ``1P36A01R01.png``."""

    activity: str  # project name: walk, sit, stand, pick, drink, fall
    subject: int  # person number (per campaign), 36 for P36
    repetition: int
    activity_digit: int  # 1-6, the leading digit (= the A code)
    stem: str


_GLASGOW_NAME = re.compile(r"(\d)P(\d+)A(\d+)R(\d+)", re.IGNORECASE)
_DIGIT_ACTIVITY = {int(code[1:]): name for code, name in GLASGOW_ACTIVITY_CODES.items()}


class ContradictoryNameError(SpectrogramImageError):
    """A Glasgow file name whose leading activity digit and A-code name different activities (some published
    files do): its label cannot be trusted either way."""


def parse_glasgow_name(name: str | Path) -> GlasgowName:
    """Activity, subject and repetition from a Glasgow file name ``K P<subject> A<code> R<rep>`` (K = code)."""
    stem = Path(name).stem
    m = _GLASGOW_NAME.fullmatch(stem)
    if m is None:
        raise SpectrogramImageError(f"{name}: not a Glasgow file name (expected like 1P36A01R01.png)")
    digit, subject, code, rep = (int(g) for g in m.groups())
    if digit not in _DIGIT_ACTIVITY:
        known = ", ".join(f"{k} {v}" for k, v in _DIGIT_ACTIVITY.items())
        raise SpectrogramImageError(f"{name}: unknown activity digit {digit} (known: {known})")
    if code != digit:
        raise ContradictoryNameError(f"{name}: activity digit {digit} disagrees with activity code A{code:02d}")
    return GlasgowName(_DIGIT_ACTIVITY[digit], subject, rep, digit, stem)


# ---- reader --------------------------------------------------------------------------------------
@dataclass
class ImageSpectrogram:
    """A spectrogram read from an image.

    Attributes:
        name: file name (or "<array>").
        db: [V, T] dB relative to the top of the colour scale (0 = strongest pixel), velocity and time
            ascending; pixels below the scale read as `floor_db`.
        velocity: [V] m/s ascending (pixel centres, or the requested grid).
        time: [T] s ascending.
        signature: p(v,t) (eq. 7), mean velocity (eq. 8, over the image's velocity axis), valid, power
            (column sums of 10^(dB/10)); range fields empty.
        off_map_fraction: share of box pixels whose colour is not on the colormap (filled from the
            nearest on-map pixel).
        floor_db: the value a pixel at the bottom colour reads as.
    """

    name: str
    db: np.ndarray
    velocity: np.ndarray
    time: np.ndarray
    signature: Signature
    off_map_fraction: float
    floor_db: float


def load_rgb(source, name: str | None = None) -> tuple[np.ndarray, str]:
    """(RGB uint8 [H, W, 3], name) of an image file or an array [H, W, 3|4]; one-line error if unreadable."""
    if isinstance(source, np.ndarray):
        name = name or "<array>"
        if source.ndim != 3 or source.shape[2] not in (3, 4) or source.dtype != np.uint8:
            raise SpectrogramImageError(f"{name}: expected a uint8 [H, W, 3] array, got {source.dtype} {source.shape}")
        return source[..., :3], name
    import warnings

    from PIL import Image, UnidentifiedImageError

    name = name or str(source)
    w: int | None = None
    h: int | None = None
    try:
        with warnings.catch_warnings():  # PIL's own bomb warning: the size is refused below, in one line
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(source) as im:  # reads the header only: the size before any pixel is decoded
                w, h = im.size
                if w * h <= MAX_IMAGE_PIXELS:
                    return np.asarray(im.convert("RGB")), name
    except Image.DecompressionBombError:  # PIL refuses more than twice its own limit in `open`
        w = h = None
    except (OSError, UnidentifiedImageError, ValueError) as e:
        why = " ".join(str(e).split()) or type(e).__name__
        raise SpectrogramImageError(f"{name}: not a readable image ({why})") from None
    size = f"{w} x {h} pixels" if w is not None else "its size"
    raise SpectrogramImageError(f"{name}: {size} exceeds the {MAX_IMAGE_PIXELS} pixels an image may have "
                                "(a decompression bomb?)")


@lru_cache(maxsize=16)
def _checked_inverse(cmap: str, n: int, tolerance: float):
    inv = colormap_inverse(cmap, n)
    pair = inv.ambiguity(tolerance)
    if pair is not None:
        raise InputError(f"colormap {cmap!r} is not invertible: entries {pair[0]} and {pair[1]} look alike")
    return inv


def cell_edges(centres: np.ndarray, what: str = "axis") -> np.ndarray:
    """Edges [n + 1] of the cells around ascending centres [n] (midpoints; half a spacing beyond the ends)."""
    c = np.asarray(centres, dtype=np.float64)
    if c.ndim != 1 or c.size < 2 or not np.all(np.isfinite(c)) or np.any(np.diff(c) <= 0):
        raise InputError(f"{what} must be a finite, strictly ascending 1-D array of 2 or more values")
    mid = (c[1:] + c[:-1]) / 2
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def remap_matrix(src_edges: np.ndarray, dst_centres: np.ndarray, what: str = "axis") -> np.ndarray:
    """Weights [D, S]: each target cell's average over the source cells it overlaps (area-weighted, so
    power is conserved when coarsening and held piecewise constant when refining). Target cells are
    clipped to the source extent; a target centre outside it is an error."""
    lo, hi = src_edges[0], src_edges[-1]
    dst = cell_edges(dst_centres, what)
    c = np.asarray(dst_centres, dtype=np.float64)
    if c[0] < lo - 1e-9 * (hi - lo) or c[-1] > hi + 1e-9 * (hi - lo):
        raise InputError(f"requested {what} {c[0]:.4g} to {c[-1]:.4g} is outside the image's {lo:.4g} to {hi:.4g}")
    d_lo, d_hi = np.clip(dst[:-1], lo, hi), np.clip(dst[1:], lo, hi)
    overlap = np.clip(np.minimum(d_hi[:, None], src_edges[None, 1:])
                      - np.maximum(d_lo[:, None], src_edges[None, :-1]), 0, None)
    total = overlap.sum(axis=1, keepdims=True)
    return overlap / np.where(total > 0, total, 1.0)


def read_spectrogram_image(source, layout: ImageLayout, *, velocity: np.ndarray | None = None,
                           time: np.ndarray | None = None, floor: Literal["zero", "keep"] = "zero",
                           max_colour_distance: float = MAX_COLOUR_DISTANCE,
                           max_off_map_fraction: float = MAX_OFF_MAP_FRACTION,
                           name: str | None = None) -> ImageSpectrogram:
    """Read a spectrogram image drawn in `layout` back into relative dB and p(v,t).

    Args:
        source: image file path, or uint8 array [H, W, 3].
        layout: where the plot box is and how it is coloured.
        velocity, time: optional ascending grids [m/s], [s] to resample onto (area-weighted power
            average over each target cell); default: the pixel centres.
        floor: power of pixels at the bottom colour: "zero" (default) or "keep" (the floor bin's centre).
        max_colour_distance: 8-bit RGB distance beyond which a pixel is off the colormap.
        max_off_map_fraction: tolerated share of off-map box pixels (tick marks, grid lines).
        name: name used in messages (default: the path, or "<array>").
    Raises SpectrogramImageError (one line, naming the file) for an unreadable image, a wrong size, an
    unknown or non-invertible colormap, too many off-map pixels or a requested grid outside the image.
    """
    rgb, name = load_rgb(source, name)
    try:
        return _read(rgb, name, layout, velocity, time, floor, max_colour_distance, max_off_map_fraction)
    except SpectrogramImageError:
        raise
    except ValueError as e:
        raise SpectrogramImageError(f"{name}: {e}") from None


def _read(rgb, name, layout, velocity, time, floor, max_dist, max_off) -> ImageSpectrogram:
    if floor not in ("zero", "keep"):
        raise InputError(f"floor must be 'zero' or 'keep', not {floor!r}")
    inv = _checked_inverse(layout.colormap, layout.colormap_size, float(max_dist))
    if rgb.shape[:2] != (layout.height, layout.width):
        raise InputError(f"image is {rgb.shape[1]}x{rgb.shape[0]} px, the layout expects "
                         f"{layout.width}x{layout.height}")
    box = rgb[layout.box_top:layout.box_bottom + 1, layout.box_left:layout.box_right + 1]
    pos, dist = inv.invert(box)
    off = dist > max_dist
    frac = float(off.mean())
    if frac > max_off:
        raise InputError(f"{frac:.1%} of the plot box ({int(off.sum())} px) is off the {layout.colormap} colormap "
                         f"(tolerated {max_off:.1%}): wrong layout or colormap, or not a spectrogram")
    if off.any():  # tick marks and the like: take the nearest on-map pixel's colour
        idx = distance_transform_edt(off, return_distances=False, return_indices=True)
        pos = pos[idx[0], idx[1]]
    n, span = layout.colormap_size, layout.db_span
    db = -span + (pos + 0.5) * span / n
    floor_db = -span + (inv.floor_position + 0.5) * span / n
    at_floor = pos <= inv.floor_position
    if layout.velocity_top > layout.velocity_bottom:  # rows run from high to low velocity: flip to ascending
        db, at_floor = db[::-1], at_floor[::-1]
    v_pix, t_pix = np.sort(layout.row_velocity()), layout.column_time()

    keep = 10.0 ** (db / 10.0)
    power = np.where(at_floor, 0.0, keep) if floor == "zero" else keep
    v_out, t_out = v_pix, t_pix
    if velocity is not None or time is not None:
        wv = remap_matrix(layout.velocity_edges(), v_pix if velocity is None else velocity, "velocity")
        wt = remap_matrix(layout.time_edges(), t_pix if time is None else time, "time")
        power, keep = wv @ power @ wt.T, wv @ keep @ wt.T
        db = np.maximum(10.0 * np.log10(np.maximum(keep, 1e-300)), floor_db)
        v_out = v_pix if velocity is None else np.asarray(velocity, dtype=np.float64)
        t_out = t_pix if time is None else np.asarray(time, dtype=np.float64)

    p_vt, valid, total = _normalise(power, DSPConfig().empty_floor)
    v_max = float(np.max(np.abs(v_out)))
    mean_v = mean_velocity(p_vt, v_out, v_max, DSPConfig(mean_velocity="seed"))  # cropped axis: not periodic
    sig = Signature(time=t_out, velocity=v_out, p_vt=p_vt, mean_velocity=mean_v, range=np.zeros(0),
                    range_distribution=np.zeros((0, t_out.size)), valid=valid, power=total)
    return ImageSpectrogram(name=name, db=db, velocity=v_out, time=t_out, signature=sig,
                            off_map_fraction=frac, floor_db=floor_db)


def read_glasgow_image(source, duration_s: float | None = None, **kwargs) -> ImageSpectrogram:
    """Read a Glasgow campaign-1 image; its 5 s / 10 s layout is taken from where its plot frame is
    (not from the activity: one sit-down is 10 s long), or from `duration_s`. Keywords as
    `read_spectrogram_image`."""
    rgb, name = load_rgb(source, kwargs.pop("name", None))
    if duration_s is None:
        duration_s = detect_glasgow_duration(rgb)
        if duration_s is None:
            raise SpectrogramImageError(f"{name}: no Glasgow plot frame found (560x420 image with the frame "
                                        f"at rows 36/354, columns 64 and 442 or 448); pass duration_s")
    try:
        layout = glasgow_layout(duration_s)
    except SpectrogramImageError as e:
        raise SpectrogramImageError(f"{name}: {e}") from None
    return read_spectrogram_image(rgb, layout, name=name, **kwargs)
