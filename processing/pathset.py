"""The backend-independent path-set contract.

Every scattering backend (points, facets, sionna) hands the synthesiser, per radar link, the delays and
complex gains of its propagation paths at frame times t_k. The gain excludes the propagation phase
2*pi*f0*tau, which the synthesiser forms in float64 from the delay.

Two kinds of path sets:
- persistent (``ids`` given): column p is the same physical path in every frame (a point scatterer, a
  mesh facet). Delays are interpolated smoothly between frames, so the Doppler of a path comes from its
  delay history, and a path that is absent in a frame (gain 0, delay NaN) fades in and out.
- frame-local (``ids`` is None): columns carry no identity across frames (e.g. Sionna RT paths). Each
  frame's paths are extrapolated with their delay rates and successive frames are cross-faded.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.errors import InputError


_CHECK_BLOCK = 1 << 15  # elements per block of the value checks (~0.5 MB of complex gains)


@dataclass
class PathSet:
    """Paths of one radar link.

    Attributes:
        times: frame times t_k [K] in seconds, strictly increasing.
        delays: propagation delays tau [K, P] in seconds (float64); NaN where a path is absent.
        gains: complex amplitude gains [K, P] (no propagation phase); 0 where a path is absent. In the
            synthesiser's convention (multiplied by exp(+j 2 pi f tau), beat = tx x conj(rx)): the complex
            conjugate of a channel coefficient such as Sionna RT's `a`; |gain|^2 = P_r / P_t.
        ids: stable path identities [P] (int64), or None for frame-local paths.
        delay_rates: d tau / dt [K, P] (dimensionless, s/s), or None. Required for Doppler of
            frame-local paths; optional for persistent ones (then used for Hermite interpolation).
        link: name of the radar link these paths belong to.
    """

    times: np.ndarray
    delays: np.ndarray
    gains: np.ndarray
    ids: np.ndarray | None = None
    delay_rates: np.ndarray | None = None
    link: str = ""

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64)
        self.delays = np.asarray(self.delays, dtype=np.float64)
        self.gains = np.asarray(self.gains, dtype=np.complex128)
        k, p = self.delays.shape
        if self.times.shape != (k,) or self.gains.shape != (k, p):
            raise InputError(f"PathSet shapes disagree: times {self.times.shape}, delays {self.delays.shape}, "
                             f"gains {self.gains.shape}")
        if self.ids is not None and np.shape(self.ids) != (p,):
            raise InputError(f"PathSet ids must have shape ({p},), got {np.shape(self.ids)}")
        if self.delay_rates is not None:
            self.delay_rates = np.asarray(self.delay_rates, dtype=np.float64)
            if self.delay_rates.shape != (k, p):
                raise InputError("PathSet delay_rates must have the shape of delays")
        if k >= 2 and not np.all(np.diff(self.times) > 0):
            raise InputError("PathSet times must be strictly increasing")
        if not self._values_ok():
            present = self.gains != 0
            if not np.all(np.isfinite(self.gains)):
                raise InputError(f"PathSet for link '{self.link}' has NaN/inf gains")
            if np.any(present & ~np.isfinite(self.delays)):
                raise InputError(f"PathSet for link '{self.link}' has a path with a gain but no finite delay")
            if np.any(self.delays[present] < 0):
                raise InputError(f"PathSet for link '{self.link}' has negative delays")

    def _values_ok(self) -> bool:
        """Whether every gain is finite and every present path (gain != 0) has a finite delay >= 0, checked
        in blocks of rows that stay in cache (the arrays of a facet path set are tens of MB; the checks
        above, which name the problem, run only when this finds one)."""
        k, p = self.delays.shape
        rows = max(1, _CHECK_BLOCK // max(1, p))
        for r in range(0, k, rows):
            g, d = self.gains[r:r + rows], self.delays[r:r + rows]
            parts = g.view(np.float64) if g.strides[-1] == g.itemsize else g  # complex: finite iff both parts are
            if not np.isfinite(parts).all():
                return False
            if np.any((g != 0) & ~((d >= 0) & (d < np.inf))):  # NaN fails >= 0, inf fails < inf
                return False
        return True

    @property
    def n_frames(self) -> int:
        return self.delays.shape[0]

    @property
    def n_paths(self) -> int:
        return self.delays.shape[1]

    @property
    def persistent(self) -> bool:
        return self.ids is not None

    def __repr__(self) -> str:
        k, p = self.delays.shape
        span = f"{self.times[0]:.3g}-{self.times[-1]:.3g} s" if k else "no frames"
        present = self.gains != 0
        kind = "persistent ids" if self.persistent else "frame-local"
        if present.any():
            tau = self.delays[present]
            power = np.abs(self.gains[present]) ** 2
            values = (f"; delays {tau.min() * 1e9:.3g}-{tau.max() * 1e9:.3g} ns, |a|^2 "
                      f"{10 * np.log10(power.max()):.1f} dB (P_r/P_t) at most, {present.mean():.0%} of entries present")
        else:
            values = "; no path present"
        return f"<PathSet {self.link!r}: {k} frames ({span}) x {p} paths ({kind}){values}>"

    def __eq__(self, other) -> bool:
        """Bit-for-bit equality of every array (NaN delays of absent paths compare equal) and the link name."""
        if not isinstance(other, PathSet):
            return NotImplemented
        return self.link == other.link and all(_same_bits(getattr(self, f), getattr(other, f))
                                               for f in ("times", "delays", "gains", "ids", "delay_rates"))

    # not hashable (mutable arrays): @dataclass with eq=True and frozen=False sets __hash__ = None

    def to_xarray(self):
        """The paths as an `xarray.Dataset`: ``delay`` [s] and ``gain`` (complex, |a|^2 = P_r/P_t) over
        (time [s], path), ``delay_rate`` [s/s] when given; the path coordinate holds the ids (persistent sets)
        or the column index (frame-local sets)."""
        import xarray as xr

        path = self.ids if self.ids is not None else np.arange(self.n_paths)
        data = {"delay": (("time", "path"), self.delays, {"units": "s"}),
                "gain": (("time", "path"), self.gains, {"units": "1", "long_name": "amplitude, |a|^2 = P_r/P_t"})}
        if self.delay_rates is not None:
            data["delay_rate"] = (("time", "path"), self.delay_rates, {"units": "s/s"})
        return xr.Dataset(data, coords={"time": ("time", self.times, {"units": "s"}), "path": path},
                          attrs={"link": self.link, "persistent": int(self.persistent)})


def _same_bits(a, b) -> bool:
    """Both None, or arrays of one dtype and shape holding the same bytes."""
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
