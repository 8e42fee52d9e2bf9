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

import math
import os
import sys
import threading
import warnings
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from processing.pathset import PathSet
from processing.radar.receiver import ReceiverConfig, receive_inplace
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
        gains, later = self.gains[k], self.gains[k + 1]  # (1 - w) g_k + w g_k+1, in place on the gathers
        gains *= 1 - w
        later *= w
        gains += later
        assert self.dspline is not None  # set with the spline
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


_CIS_CELLS = 4096
_CIS_TABLE = np.exp(2j * np.pi * np.arange(_CIS_CELLS) / _CIS_CELLS)


def _cis(x: np.ndarray) -> np.ndarray:
    """exp(j 2 pi x) (complex128) of x [cycles]: the nearest of 4096 roots of unity times the Taylor series of
    the rest (|2 pi r| <= pi / 4096: later terms < 1e-21), float64-accurate, ~3x cheaper than complex np.exp."""
    k = np.rint(x * _CIS_CELLS)
    y = (x - k * (1.0 / _CIS_CELLS)) * (2 * np.pi)
    y2 = y * y
    rest = np.empty(x.shape, np.complex128)
    rest.real = 1.0 - y2 * (0.5 - y2 * (1 / 24))
    rest.imag = y * (1.0 - y2 * (1 / 6 - y2 * (1 / 120)))
    out = _CIS_TABLE[k.astype(np.int64) & (_CIS_CELLS - 1)]
    out *= rest
    return out


def tone_sum(delays: np.ndarray, gains: np.ndarray, wf: Waveform, rates: np.ndarray | None = None) -> np.ndarray:
    """Beat signal [C, N] (complex128) of paths with delays [C, P] (s), gains [C, P] and delay rates [C, P]
    (s/s; None: static), one row per chirp.

    Fast time: exp(j 2 pi gamma (tau + kappa dtau/dt) m / fs) (`coupling_s`: the Doppler shift inside the
    chirp, 0.16 range bins at 4 m/s on the Glasgow radar); slow time: exp(j 2 pi f_s tau) at the chirp's
    start. The fast-time tone is built by repeated multiplication with its per-sample step (float64: after
    N steps the relative phase error is ~N * 1e-16), several times cheaper than N complex exponentials.
    """
    return np.ascontiguousarray(_tone_sum_t(delays, gains, wf, rates).T)


def _tone_sum_t(delays, gains, wf: Waveform, rates=None, out: np.ndarray | None = None) -> np.ndarray:
    """`tone_sum` transposed, [N, C] (into `out` if given): the recurrence runs on [paths, chirps] arrays so
    that each sample is one multiplication and one row-by-row sum (paths added in a fixed order, whatever
    the chunk) over contiguous chirps."""
    c = delays.shape[0]
    n = wf.samples_per_chirp
    if c == 1:  # numpy sums a single column pairwise, not row by row: the chirp would differ in its last bits
        one = _tone_sum_t(np.repeat(delays, 2, axis=0), np.repeat(gains, 2, axis=0), wf,
                          None if rates is None else np.repeat(rates, 2, axis=0))[:, :1]
        if out is not None:
            out[...] = one
        return one if out is None else out
    out = np.empty((n, c), np.complex128) if out is None else out
    active = np.flatnonzero(np.any(gains != 0, axis=0))
    if active.size == 0:
        out[:] = 0
        return out
    tau = np.asarray(delays).T[active]  # [P', C], contiguous
    x0 = wf.start_hz * tau  # the phase in cycles, reduced before the roots-of-unity table is indexed
    x0 -= np.floor(x0)
    acc = _cis(x0)
    acc *= np.asarray(gains).T[active]
    fast = tau if rates is None else tau + coupling_s(wf) * np.nan_to_num(np.asarray(rates).T[active])
    step = _cis((wf.slope / wf.fs) * fast)
    np.add.reduce(acc, axis=0, out=out[0])
    for m in range(1, n):
        acc *= step
        np.add.reduce(acc, axis=0, out=out[m])
    return out


def _check_nyquist(delays, gains, rates, wf: Waveform, link: str, reported: set) -> None:
    if len(reported) == 2:  # both kinds already warned about
        return
    present = gains != 0
    if present.size and present.all():  # (the usual case) no gathered copies
        _warn_nyquist(float(np.abs(rates).max()), float(np.max(delays)), wf, link, reported)
    elif present.any():
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
        yield t, np.asarray(iq, dtype=np.complex64, order="C")


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
    for t, delays, gains, rates in _evaluated(paths, wf, t_all, chunk_chirps, reported):
        iq = _tone_sum_t(delays, gains, wf, rates).T  # [C, N] view: the caller's cast or product reorders it
        yield t, (iq if weights is None else iq @ weights)


def _evaluated(paths: PathSet, wf: Waveform, t_all: np.ndarray, chunk_chirps: int, reported: set):
    """(chirp times, delays, gains, delay rates) per chunk of the exact route, Nyquist-checked."""
    evaluate = _PersistentPaths(paths) if paths.persistent else _FrameLocalPaths(paths)
    for s in range(0, t_all.size, chunk_chirps):
        t = t_all[s:s + chunk_chirps]
        delays, gains, rates = evaluate(t)
        _check_nyquist(delays, gains, rates, wf, paths.link, reported)
        yield t, delays, gains, rates


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


def _threads() -> int:
    """Threads for the exact route: the usable cores (<= 8), fewer if OMP_NUM_THREADS or, once loaded, numba's
    thread count say so (dataset workers set both to 1: one worker per core)."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    omp = os.environ.get("OMP_NUM_THREADS", "")
    n = min(n, int(omp)) if omp.isdigit() and int(omp) > 0 else n
    return max(1, min(n, 8, sys.modules["numba"].get_num_threads() if "numba" in sys.modules else n))


_POOL: dict = {}  # one persistent pool (its threads keep their scratch arrays), rebuilt if the count changes
_LOCAL = threading.local()
if hasattr(os, "register_at_fork"):  # a forked child has none of the pool's threads: it would wait forever
    os.register_at_fork(after_in_child=_POOL.clear)


def _scratch(name: str, shape: tuple, dtype) -> np.ndarray:
    """A per-thread array reused from chunk to chunk: fresh MB-sized temporaries cost page faults (glibc gives
    them back to the system on free), more than the arithmetic on them."""
    buf = getattr(_LOCAL, name, None)
    if buf is None or buf.dtype != dtype or buf.size < math.prod(shape):
        buf = np.empty(math.prod(shape), dtype)
        setattr(_LOCAL, name, buf)
    return buf[:math.prod(shape)].reshape(shape)


def iter_received(paths: PathSet, wf: Waveform, cfg: "ReceiverConfig | None", seed, chunk_chirps: int = 1024,
                  method: str = "auto", oversample: int | None = None, finish=None,
                  out: np.ndarray | None = None) -> Iterator[tuple]:
    """Yield (chirp start times [C] s, result) chunk by chunk in order: the IQ [C, N] (complex64) of
    `iter_synthesis` received (`receive(iq, cfg, wf, seed, first_chirp)`; as is if `cfg` is None), or
    `finish(that IQ)` (e.g. the DSP's fast-time projection; it must not keep the IQ: its memory is reused).
    `out` [all chirps, N] (complex64): the IQ is written into its rows, and views of them yielded.

    On the exact route, tone sum, reception and `finish` run chunk by chunk on a pool of `_threads()`
    threads (numpy's loops release the GIL). Each chirp's bytes depend only on that chirp (paths evaluated
    at its time and summed in a fixed order, noise keyed by chirp index): neither chunking nor thread count
    changes them. Paths are evaluated and Nyquist-checked in the calling thread (its warnings); the grid
    route runs there too (its kernel has numba's threads)."""
    def received(iq, first):
        iq = iq if cfg is None else receive_inplace(iq, cfg, wf, seed, first)
        return iq if finish is None else finish(iq)

    def chunk(delays, gains, rates, first):
        c, n = delays.shape[0], wf.samples_per_chirp
        beat = _tone_sum_t(delays, gains, wf, rates, out=_scratch("beat", (n, c), np.complex128))
        iq = out[first:first + c] if out is not None else np.empty((c, n), np.complex64) if finish is None \
            else _scratch("iq", (c, n), np.complex64)
        np.copyto(iq, beat.T, casting="same_kind")
        return received(iq, first)

    first = 0
    if uses_grid(paths, method):
        for t, iq in iter_synthesis(paths, wf, chunk_chirps=chunk_chirps, method=method, oversample=oversample):
            if out is not None:
                out[first:first + t.size] = iq
                iq = out[first:first + t.size]
            yield t, received(iq, first)
            first += t.size
        return
    chunks = _evaluated(paths, wf, chirp_times(paths.times[0], paths.times[-1], wf.pri_s), chunk_chirps, set())
    n_threads = _threads()
    if n_threads == 1 or threading.current_thread().name.startswith("rtchannel-synthesis"):
        n_threads, submit = 0, lambda *a: (lambda done=chunk(*a): done)  # computed now, no look-ahead
    else:
        if _POOL.get("n") != n_threads:
            _POOL.update(n=n_threads, pool=ThreadPoolExecutor(n_threads, thread_name_prefix="rtchannel-synthesis"))
        submit = lambda *a: _POOL["pool"].submit(chunk, *a).result  # noqa: E731
    pending: deque[tuple[np.ndarray, Callable[[], np.ndarray]]] = deque()
    for t, delays, gains, rates in chunks:
        pending.append((t, submit(delays, gains, rates, first)))
        first += t.size
        if len(pending) > 2 * n_threads:
            t_done, job = pending.popleft()
            yield t_done, job()
    while pending:  # bounded look-ahead above (memory stays a few chunks), the rest here
        t_done, job = pending.popleft()
        yield t_done, job()


def received_iq(paths, wf: Waveform, cfg: "ReceiverConfig | None", seed, chunk_chirps: int = 1024,
                method: str = "auto", oversample: int | None = None, progress=None) -> tuple[np.ndarray, np.ndarray]:
    """(chirp start times [C] s, IQ [C, N]) of a path set synthesised chunk by chunk and, with a receiver
    `cfg`, received (`receive`: sqrt(W), leakage, thermal noise keyed by chirp index, so chunking never
    changes it); without one the IQ stays in units of the transmit power. `progress(n chirps)` per chunk."""
    t_all = chirp_times(paths.times[0], paths.times[-1], wf.pri_s)
    iq = np.empty((t_all.size, wf.samples_per_chirp), np.complex64)
    for t, _ in iter_received(paths, wf, cfg, seed, chunk_chirps, method, oversample, out=iq):
        if progress is not None:
            progress(t.size)
    return t_all, iq
