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
from processing.radar.receiver import ReceiverConfig, receive
from processing.radar.waveform import C0, Waveform
from processing.errors import InputError


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


def coupling_s(wf: Waveform) -> float:
    """Range-Doppler coupling kappa [s per s/s] = f_c / gamma: a path whose delay changes at rate dtau/dt
    beats at gamma (tau + kappa dtau/dt) in fast time, the Doppler shift f_c dtau/dt of the chirp's carrier
    adding to the range frequency (f_c = the frequency at the chirp's centre sample, where the linearised
    phase is exact to first order: the brute-force beat 2 pi (f_s tau(t) + gamma t' tau(t)) with tau at
    every ADC sample has mean frequency f_s + gamma T / 2 over the chirp)."""
    n = wf.samples_per_chirp
    return (wf.start_hz + wf.slope * (n // 2) / wf.fs) / wf.slope


def tone_sum(delays: np.ndarray, gains: np.ndarray, wf: Waveform, rates: np.ndarray | None = None) -> np.ndarray:
    """Beat signal [C, N] (complex128) of paths with delays [C, P] (s), gains [C, P] and delay rates [C, P]
    (s/s; None: static), one row per chirp.

    Fast time: exp(j 2 pi gamma (tau + kappa dtau/dt) m / fs) (`coupling_s`: the Doppler shift inside the
    chirp, 0.16 range bins at 4 m/s on the Glasgow radar); slow time: exp(j 2 pi f_s tau) at the chirp's
    start. The fast-time tone is built by repeated multiplication with its per-sample step (float64: after
    N steps the relative phase error is ~N * 1e-16), several times cheaper than N complex exponentials.
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
    fast = tau if rates is None else tau + coupling_s(wf) * np.nan_to_num(rates[:, active])
    step = np.exp(1j * (2 * np.pi * wf.slope / wf.fs) * fast)
    out[:, 0] = acc.sum(axis=1)
    for m in range(1, n):
        acc *= step
        out[:, m] = acc.sum(axis=1)
    return out


def _check_nyquist(delays, gains, rates, wf: Waveform, link: str, reported: set) -> None:
    present = gains != 0
    if present.any():
        _warn_nyquist(float(np.abs(rates[present]).max()), float(delays[present].max()), wf, link, reported)


def _warn_nyquist(rate_max: float, delay_max: float, wf: Waveform, link: str, reported: set) -> None:
    """Warn (once per kind) if the largest |delay rate| or delay of the present paths aliases."""
    v = rate_max * C0 / 2
    if "v" not in reported and v > wf.v_max:
        reported.add("v")
        warnings.warn(f"link '{link}': a path moves at {v:.2f} m/s radially, above v_max = "
                      f"{wf.v_max:.2f} m/s (lambda/4PRI): its Doppler aliases", NyquistWarning, stacklevel=4)
    if "r" not in reported and delay_max >= wf.max_unambiguous_delay:
        reported.add("r")
        warnings.warn(f"link '{link}': a path at range {delay_max * C0 / 2:.2f} m lies beyond the maximum "
                      f"unambiguous range {wf.max_unambiguous_range:.2f} m: its beat frequency aliases",
                      NyquistWarning, stacklevel=4)


GRID_MIN_PATHS = 64  # below this the exact tone sum is used (cheap at the points backend's 21 paths, and exact)


def grid_pieces(paths: PathSet) -> tuple:
    """(knots [I+1], y0, y1, m0, m1, g0, g1 [I, P'], largest |delay rate| and largest delay [s] of the
    present paths) of a path set for `synthesis_grid`: per frame interval, the delays [s] and delay rates at
    its ends, whose cubic Hermite interpolant is the delay inside it, and the complex gains at its ends
    (linear in between).

    Persistent paths: the frames' delays (gaps filled as `_PersistentPaths` does) with the delay rates, or
    without rates the slopes of the same not-a-knot cubic spline, so the pieces are `_PersistentPaths`'
    spline (P' = P; no copies). Frame-local paths: frame k's paths extrapolated with their rates and fading
    out, plus frame k+1's fading in (P' = 2P), as `_FrameLocalPaths` does.
    """
    from processing.synthesis.grid import prepare_frames

    t, g = paths.times, paths.gains
    if paths.persistent:
        d, rate_max, delay_max = prepare_frames(t, paths.delays, paths.delay_rates, g)
        r = paths.delay_rates  # NaN at absent frames, read as 0 by the kernel (np.nan_to_num, as _PersistentPaths)
        if r is None:
            r = CubicSpline(t, d, axis=0)(t, 1)
            present = g != 0
            rate_max = float(np.abs(r[present]).max()) if present.any() else 0.0
        return t, d[:-1], d[1:], r[:-1], r[1:], g[:-1], g[1:], rate_max, delay_max
    present = g != 0
    d = np.where(present, paths.delays, 0.0)
    r = np.zeros_like(d) if paths.delay_rates is None else np.where(present, paths.delay_rates, 0.0)
    h = np.diff(t)[:, None]
    zeros = np.zeros((t.size - 1, d.shape[1]), np.complex128)
    y0 = np.concatenate([d[:-1], d[1:] - r[1:] * h], axis=1)
    y1 = np.concatenate([d[:-1] + r[:-1] * h, d[1:]], axis=1)
    m = np.concatenate([r[:-1], r[1:]], axis=1)
    return (t, y0, y1, m, m, np.concatenate([g[:-1], zeros], axis=1), np.concatenate([zeros, g[1:]], axis=1),
            float(np.abs(r).max()) if r.size else 0.0, float(d.max()) if d.size else 0.0)


def uses_grid(paths: PathSet, method: str = "auto") -> bool:
    """Whether `iter_synthesis` takes the gridded route for this path set and method."""
    if method not in ("auto", "exact", "grid"):
        raise InputError(f"synthesis method must be auto, exact or grid, got {method!r}")
    return paths.n_frames >= 2 and (method == "grid" or (method == "auto" and paths.n_paths >= GRID_MIN_PATHS))


def iter_synthesis(paths: PathSet, wf: Waveform, t_start: float | None = None, t_stop: float | None = None,
                   chunk_chirps: int = 1024, method: str = "auto",
                   oversample: int | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (chirp start times [C] s, IQ [C, N] complex64) chunk by chunk over [t_start, t_stop].

    Defaults span the path set's frames. `method`: "exact" (per-path tone recurrence, cost ~ paths x
    chirps x samples), "grid" (`synthesis_grid`: paths spread onto a grid of oversample x N cells with a
    fitted kernel and inverse-FFT'd, relative error per path and sample below
    `synthesis_kernel.spread_kernel(oversample).error_bound`, 1.8e-6 at the default oversample 4; cost ~
    paths x chirps) or "auto" (grid from GRID_MIN_PATHS paths on). Emits `NyquistWarning` (once per kind)
    when a present path exceeds v_max or the maximum unambiguous range.
    """
    for t, iq in iter_weighted(paths, wf, None, t_start, t_stop, chunk_chirps, method, oversample):
        yield t, iq.astype(np.complex64)


def iter_weighted(paths: PathSet, wf: Waveform, weights: np.ndarray | None = None, t_start: float | None = None,
                  t_stop: float | None = None, chunk_chirps: int = 1024, method: str = "auto",
                  oversample: int | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (chirp start times [C] s, iq @ weights [C, K] complex128) chunk by chunk, iq being the beat
    signal [C, N] of `iter_synthesis` (in complex128; itself when `weights` [N, K] is None). With the grid
    method and weights, iq is never formed: the kernel projects the spread grid (`synthesis_grid.spread`)."""
    t0 = paths.times[0] if t_start is None else t_start
    t1 = paths.times[-1] if t_stop is None else t_stop
    t_all = chirp_times(t0, t1, wf.pri_s)
    n = wf.samples_per_chirp
    if weights is not None:
        weights = np.asarray(weights, dtype=np.complex128)
        if weights.ndim != 2 or weights.shape[0] != n:
            raise InputError(f"weights must be [{n}, K] (samples per chirp, outputs), got {weights.shape}")
    use_grid = uses_grid(paths, method)
    reported: set = set()
    if use_grid:
        from processing.synthesis.grid import OVERSAMPLE, grid_to_iq, projection_matrix, spread, spread_kernel

        kernel = spread_kernel(OVERSAMPLE if oversample is None else oversample)
        knots, y0, y1, m0, m1, g0, g1, rate_max, delay_max = grid_pieces(paths)
        # the grid path never forms per-chirp delays in Python: check Nyquist on the frames' values
        _warn_nyquist(rate_max, delay_max, wf, paths.link, reported)
        matrix = None if weights is None else projection_matrix(weights, n, kernel)
        for s in range(0, t_all.size, chunk_chirps):
            t = t_all[s:s + chunk_chirps]
            out = spread(t, knots, y0, y1, m0, m1, g0, g1, wf.start_hz, wf.slope, wf.fs, n, kernel, matrix,
                         pri=wf.pri_s, t_all=(t_all[0], t_all[-1]))
            yield t, (grid_to_iq(out, n, kernel) if weights is None else out)
        return
    evaluate = _PersistentPaths(paths) if paths.persistent else _FrameLocalPaths(paths)
    for s in range(0, t_all.size, chunk_chirps):
        t = t_all[s:s + chunk_chirps]
        delays, gains, rates = evaluate(t)
        _check_nyquist(delays, gains, rates, wf, paths.link, reported)
        iq = tone_sum(delays, gains, wf, rates)
        yield t, (iq if weights is None else iq @ weights)


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


def received_iq(paths, wf: Waveform, cfg: "ReceiverConfig | None", seed, chunk_chirps: int = 1024,
                method: str = "auto", oversample: int | None = None, progress=None) -> tuple[np.ndarray, np.ndarray]:
    """(chirp start times [C] s, IQ [C, N]) of a path set synthesised chunk by chunk and, with a receiver
    `cfg`, received (`receive`: sqrt(W), leakage, thermal noise keyed by chirp index, so chunking never
    changes it); without one the IQ stays in units of the transmit power. `progress(n chirps)` per chunk."""
    t_parts, iq_parts, done = [], [], 0
    for t, iq in iter_synthesis(paths, wf, chunk_chirps=chunk_chirps, method=method, oversample=oversample):
        if cfg is not None:
            iq = receive(iq, cfg, wf, seed=seed, first_chirp=done)
        done += t.size
        t_parts.append(t)
        iq_parts.append(iq)
        if progress is not None:
            progress(t.size)
    t_all = np.concatenate(t_parts) if t_parts else np.zeros(0)
    iq = np.concatenate(iq_parts) if iq_parts else np.zeros((0, wf.samples_per_chirp), np.complex64)
    return t_all, iq
