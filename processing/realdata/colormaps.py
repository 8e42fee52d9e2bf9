"""Colormaps as renderers draw them, and their inverse (8-bit colour -> position on the colormap).

MATLAB's `jet` is not matplotlib's `jet` (they differ by up to 33 of 255 levels: MATLAB's starts at dark
blue 0.516, matplotlib's at 0.5 and the ramps have other knots), so MATLAB's is built here from its
defining formula (jet.m); any other name is looked up in matplotlib.

Both MATLAB and matplotlib draw a scaled image with a *discrete* colormap of N entries: the value
interval [cmin, cmax] is cut into N equal bins and bin k gets entry k. Both store a colour as
floor(255 c) (MATLAB's `jet` and matplotlib's `Colormap(bytes=True)` truncate; checked on the Glasgow
images, whose colours are exactly floor(255 * jet(256)) and not round(...)).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from processing.errors import InputError



def matlab_jet(m: int = 256) -> np.ndarray:
    """MATLAB's ``jet(m)`` [m, 3] in [0, 1], transcribed from jet.m (R2014b and later)."""
    n = int(np.ceil(m / 4))
    u = np.concatenate([np.arange(1, n + 1) / n, np.ones(n - 1), np.arange(n, 0, -1) / n])
    g = int(np.ceil(n / 2)) - int(m % 4 == 1) + np.arange(1, u.size + 1)  # 1-based, as in jet.m
    r, b = g + n, g - n
    g, r, b = g[g <= m], r[r <= m], b[b >= 1]
    rgb = np.zeros((m, 3))
    rgb[r - 1, 0] = u[:r.size]
    rgb[g - 1, 1] = u[:g.size]
    rgb[b - 1, 2] = u[u.size - b.size:]
    return rgb


_MATLAB = {"matlab_jet": matlab_jet}


def colormap_rgb(name: str, n: int = 256) -> np.ndarray:
    """The n entries [n, 3] (floats in [0, 1]) of colormap `name`: ``matlab_jet`` or a matplotlib name.

    Raises ValueError naming the colormap if it is unknown.
    """
    if name in _MATLAB:
        return _MATLAB[name](n)
    import matplotlib

    try:
        cmap = matplotlib.colormaps[name]
    except KeyError:
        known = ", ".join(_MATLAB)
        raise InputError(f"unknown colormap {name!r} (use {known} or a matplotlib colormap name)") from None
    return np.asarray(cmap.resampled(n)(np.arange(n)), dtype=np.float64)[:, :3]


def eight_bit(rgb: np.ndarray) -> np.ndarray:
    """Colours in [0, 1] as the renderers store them: floor(255 c) as uint8."""
    return (np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)  # truncation, as matplotlib's bytes=True


class ColormapInverse:
    """Nearest-colour inverse of an N-entry colormap.

    The N 8-bit entries are joined by straight lines in RGB, sampled `substeps` times per entry: a pixel
    maps to the nearest point of that polyline, so an exact entry returns its index and a blend of two
    neighbouring entries (image resampling in some renderers) returns an index between them. Runs of
    neighbouring entries that 8-bit storage makes identical (gray, viridis: runs of 2; matplotlib's jet:
    4) are one point of the polyline at the run's middle index, so an exact colour is read within
    `max_run` / 2 entries of the entry that was drawn (1/2 when all entries are distinct, as MATLAB's jet).
    """

    def __init__(self, name: str, n: int = 256, substeps: int = 16):
        self.name, self.n = name, n
        self.entries = eight_bit(colormap_rgb(name, n))  # [n, 3] uint8: what a renderer writes
        new_run = np.concatenate([[True], np.any(self.entries[1:] != self.entries[:-1], axis=1)])
        starts = np.flatnonzero(new_run)
        ends = np.append(starts[1:], n) - 1
        self.max_run = int((ends - starts).max()) + 1
        anchors = self.entries[starts].astype(np.float64)
        where = (starts + ends) / 2.0  # entry index each distinct colour stands for
        self.floor_position = float(where[0])  # where the bottom colour (entry 0) reads
        if anchors.shape[0] == 1:
            raise InputError(f"colormap {name!r} has a single colour")
        u = np.linspace(0.0, anchors.shape[0] - 1.0, (anchors.shape[0] - 1) * substeps + 1)
        k = np.minimum(np.floor(u).astype(int), anchors.shape[0] - 2)
        frac = u - k
        self.position = where[k] * (1 - frac) + where[k + 1] * frac
        self._tree = cKDTree(anchors[k] * (1 - frac[:, None]) + anchors[k + 1] * frac[:, None])

    def invert(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position [...] in entry units 0..N-1, distance [...] in 8-bit levels) of uint8 colours [..., 3].

        Looks up each distinct colour once (an image holds a few hundred), so a 120k-pixel box costs ~ms.
        """
        flat = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)
        code = (flat[:, 0].astype(np.int32) << 16) | (flat[:, 1].astype(np.int32) << 8) | flat[:, 2]
        uniq, inverse = np.unique(code, return_inverse=True)
        cols = np.stack([uniq >> 16, (uniq >> 8) & 255, uniq & 255], axis=1).astype(np.float64)
        dist, idx = self._tree.query(cols)
        shape = np.shape(rgb)[:-1]
        return self.position[idx][inverse].reshape(shape), dist[inverse].reshape(shape)

    def ambiguity(self, tolerance: float, min_separation: int | None = None) -> tuple[int, int] | None:
        """A pair of entries at least `min_separation` apart (default N/16) whose 8-bit colours are within
        2 * tolerance of each other (so a pixel could be read as either), or None: the colormap is
        invertible. Cyclic (hsv, twilight) and repeating (flag, prism) colormaps fail this."""
        sep = max(2, self.n // 16) if min_separation is None else min_separation
        pairs = cKDTree(self.entries.astype(np.float64)).query_pairs(2 * tolerance, output_type="ndarray")
        far = pairs[np.abs(pairs[:, 0] - pairs[:, 1]) >= sep]
        return None if far.size == 0 else (int(far[0, 0]), int(far[0, 1]))


@lru_cache(maxsize=16)
def colormap_inverse(name: str, n: int = 256) -> ColormapInverse:
    """Cached `ColormapInverse` (building the KD-tree of 4k points takes a few ms)."""
    return ColormapInverse(name, n)
