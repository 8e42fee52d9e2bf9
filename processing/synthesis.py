"""The shared FMCW beat-signal synthesiser (seed eqs. 1-3).

For chirp n starting at slow time t_n = n * PRI and fast-time sample m (t' = m / fs), the complex
baseband beat signal is

    s(t', t_n) = sum_l a_l(t_n) exp(j (2 pi gamma tau_l(t_n) t' + 2 pi f_s tau_l(t_n)))

where f_s = f0 - B/2 is the chirp's start frequency (the seed's f0 with t' counted from the chirp start;
our `carrier_hz` is the sweep centre, so the phase at mid-chirp is 2 pi f0 tau)
with each path short-time stationary over one chirp (the seed's assumption). Delays known at animation
frames are interpolated to every chirp *before* phases are formed, so the synthesisable radial velocity
is limited by the PRI (v_max = lambda / 4 PRI), not by the frame interval. Everything is float64 until
the final complex64 IQ; work is done in chunks of chirps so memory stays bounded for long activities.
"""
from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from processing.pathset import PathSet
from processing.waveform import C0, Waveform


class NyquistWarning(UserWarning):
    """A path moves faster than v_max or lies beyond the maximum unambiguous range: it will alias."""


def chirp_times(t_start: float, t_stop: float, pri: float) -> np.ndarray:
    """Start times [s] of the chirps that fit in [t_start, t_stop]."""
    n = int(np.floor((t_stop - t_start) / pri + 1e-9)) + 1
    return t_start + pri * np.arange(max(n, 0))


def _fill_absent(times: np.ndarray, delays: np.ndarray) -> np.ndarray:
    """Delays with NaN gaps filled by linear interpolation (held at the ends), so splines stay finite."""
    out = delays.copy()
    for p in np.flatnonzero(~np.isfinite(out).all(axis=0)):
        ok = np.isfinite(out[:, p])
        out[:, p] = np.interp(times, times[ok], out[ok, p]) if ok.any() else 0.0
    return out


class _PersistentPaths:
    """Evaluates a persistent path set at arbitrary slow times (delay splines, linear gain fades)."""

    def __init__(self, paths: PathSet):
        self.times = paths.times
        self.gains = paths.gains
        delays = _fill_absent(paths.times, paths.delays)
        if paths.n_frames < 2:
            self.spline = None
            self.delays = delays
        elif paths.delay_rates is not None:
            rates = np.nan_to_num(paths.delay_rates)
            self.spline = CubicHermiteSpline(paths.times, delays, rates, axis=0)
        else:
            self.spline = CubicSpline(paths.times, delays, axis=0)
        self.dspline = None if self.spline is None else self.spline.derivative()

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(delays [C, P] s, gains [C, P], delay rates [C, P]) at chirp times t [C]."""
        if self.spline is None:
            shape = (t.size, self.gains.shape[1])
            return (np.broadcast_to(self.delays[0], shape), np.broadcast_to(self.gains[0], shape),
                    np.zeros(shape))
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, self.times.size - 2)
        w = ((t - self.times[k]) / (self.times[k + 1] - self.times[k]))[:, None]
        gains = (1 - w) * self.gains[k] + w * self.gains[k + 1]
        return self.spline(t), gains, self.dspline(t)


class _FrameLocalPaths:
    """Frame-local paths: frame k's paths extrapolated by their delay rates, cross-faded with frame k+1."""

    def __init__(self, paths: PathSet):
        self.times = paths.times
        self.delays = np.where(paths.gains != 0, paths.delays, 0.0)
        self.gains = paths.gains
        self.rates = (np.zeros_like(self.delays) if paths.delay_rates is None
                      else np.where(paths.gains != 0, paths.delay_rates, 0.0))

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        last = self.times.size - 1
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, max(last - 1, 0))
        kb = np.minimum(k + 1, last)
        span = np.where(kb > k, self.times[kb] - self.times[k], 1.0)
        w = np.where(kb > k, (t - self.times[k]) / span, 0.0)[:, None]
        tau_a = self.delays[k] + self.rates[k] * (t - self.times[k])[:, None]
        tau_b = self.delays[kb] + self.rates[kb] * (t - self.times[kb])[:, None]
        delays = np.concatenate([tau_a, tau_b], axis=1)
        gains = np.concatenate([(1 - w) * self.gains[k], w * self.gains[kb]], axis=1)
        rates = np.concatenate([self.rates[k], self.rates[kb]], axis=1)
        return delays, gains, rates


def tone_sum(delays: np.ndarray, gains: np.ndarray, wf: Waveform) -> np.ndarray:
    """Beat signal [C, N] (complex128) of paths with delays [C, P] (s) and gains [C, P], one row per chirp.

    The fast-time tone exp(j 2 pi gamma tau m / fs) is built by repeated multiplication with its
    per-sample step (float64: after N steps the relative phase error is ~N * 1e-16), which is several
    times cheaper than N complex exponentials per path.
    """
    c, p = delays.shape
    n = wf.samples_per_chirp
    out = np.empty((c, n), dtype=np.complex128)
    active = np.flatnonzero(np.any(gains != 0, axis=0))
    if active.size == 0:
        out[:] = 0
        return out
    tau = delays[:, active]
    acc = gains[:, active] * np.exp(1j * np.mod(2 * np.pi * wf.start_hz * tau, 2 * np.pi))
    step = np.exp(1j * (2 * np.pi * wf.slope / wf.fs) * tau)
    out[:, 0] = acc.sum(axis=1)
    for m in range(1, n):
        acc *= step
        out[:, m] = acc.sum(axis=1)
    return out


def _check_nyquist(delays, gains, rates, wf: Waveform, link: str, reported: set) -> None:
    present = gains != 0
    if not present.any():
        return
    v = np.abs(rates[present]) * C0 / 2
    if "v" not in reported and v.max() > wf.v_max:
        reported.add("v")
        warnings.warn(f"link '{link}': a path moves at {v.max():.2f} m/s radially, above v_max = "
                      f"{wf.v_max:.2f} m/s (lambda/4PRI): its Doppler aliases", NyquistWarning, stacklevel=3)
    tau = delays[present]
    if "r" not in reported and tau.max() >= wf.max_unambiguous_delay:
        reported.add("r")
        warnings.warn(f"link '{link}': a path at range {tau.max() * C0 / 2:.2f} m lies beyond the maximum "
                      f"unambiguous range {wf.max_unambiguous_range:.2f} m: its beat frequency aliases",
                      NyquistWarning, stacklevel=3)


GRID_MIN_PATHS = 64  # below this the exact tone sum is as fast as the gridded one (measured)


def _pieces(paths: PathSet, evaluate) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(knots [I+1], delay cubics [4, I, P'], gains at piece start/end [I, P']) of a path set.

    Persistent paths: the delay spline's own pieces. Frame-local paths: frame k's paths extrapolated
    with their rates and fading out, plus frame k+1's fading in (P' = 2P), as `_FrameLocalPaths` does.
    """
    if isinstance(evaluate, _PersistentPaths):
        return evaluate.times, evaluate.spline.c, evaluate.gains[:-1], evaluate.gains[1:]
    d, r, g = evaluate.delays, evaluate.rates, evaluate.gains
    h = np.diff(evaluate.times)[:, None]
    n_int, p = d.shape[0] - 1, d.shape[1]
    coef = np.zeros((4, n_int, 2 * p))
    coef[2, :, :p], coef[3, :, :p] = r[:-1], d[:-1]
    coef[2, :, p:], coef[3, :, p:] = r[1:], d[1:] - r[1:] * h
    zeros = np.zeros((n_int, p), np.complex128)
    return (evaluate.times, coef, np.concatenate([g[:-1], zeros], axis=1),
            np.concatenate([zeros, g[1:]], axis=1))


def iter_synthesis(paths: PathSet, wf: Waveform, t_start: float | None = None, t_stop: float | None = None,
                   chunk_chirps: int = 1024, method: str = "auto",
                   oversample: int = 8) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (chirp start times [C] s, IQ [C, N] complex64) chunk by chunk over [t_start, t_stop].

    Defaults span the path set's frames. `method`: "exact" (per-path tone recurrence, cost ~ paths x
    chirps x samples), "grid" (`synthesis_grid`: delay grid L = oversample x N with a third-order
    sub-grid correction, per-path error below (pi/oversample)^4/24, -60 dB at 8x; cost ~ paths x chirps)
    or "auto" (grid from GRID_MIN_PATHS paths on). Emits `NyquistWarning` (once per kind) when a present
    path exceeds v_max or the maximum unambiguous range.
    """
    if method not in ("auto", "exact", "grid"):
        raise ValueError(f"synthesis method must be auto, exact or grid, got {method!r}")
    t0 = paths.times[0] if t_start is None else t_start
    t1 = paths.times[-1] if t_stop is None else t_stop
    t_all = chirp_times(t0, t1, wf.pri_s)
    evaluate = _PersistentPaths(paths) if paths.persistent else _FrameLocalPaths(paths)
    use_grid = paths.n_frames >= 2 and (method == "grid" or (method == "auto" and paths.n_paths >= GRID_MIN_PATHS))
    reported: set = set()
    if use_grid:
        from processing.synthesis_grid import gridded_tone_sum

        knots, coef, g0, g1 = _pieces(paths, evaluate)
        # the grid path never forms per-chirp delays in Python: check Nyquist on the frames' values
        rates = (evaluate.dspline(paths.times) if paths.persistent else evaluate.rates)
        _check_nyquist(np.where(paths.gains != 0, paths.delays, 0.0), paths.gains, rates, wf, paths.link,
                       reported)
        chunk_chirps = min(chunk_chirps, 512)  # the grid accumulator is (ORDER+1) x L per chirp
    for s in range(0, t_all.size, chunk_chirps):
        t = t_all[s:s + chunk_chirps]
        if use_grid:
            iq = gridded_tone_sum(t, knots, coef, g0, g1, wf.start_hz, wf.slope, wf.fs, wf.samples_per_chirp,
                                  oversample)
        else:
            delays, gains, rates = evaluate(t)
            _check_nyquist(delays, gains, rates, wf, paths.link, reported)
            iq = tone_sum(delays, gains, wf)
        yield t, iq.astype(np.complex64)


def synthesise(paths: PathSet, wf: Waveform, t_start: float | None = None, t_stop: float | None = None,
               chunk_chirps: int = 1024, method: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Raw IQ of one link: (chirp start times [C] s, IQ [C, N] complex64), the seed's matrix D (eq. 1)."""
    t_parts, iq_parts = [], []
    for t, iq in iter_synthesis(paths, wf, t_start, t_stop, chunk_chirps, method):
        t_parts.append(t)
        iq_parts.append(iq)
    if not t_parts:
        return np.zeros(0), np.zeros((0, wf.samples_per_chirp), np.complex64)
    return np.concatenate(t_parts), np.concatenate(iq_parts)
