"""Many-path FMCW synthesis: delay gridding with a Taylor correction, slow-time phase recurrences.

The exact synthesiser (`synthesis.tone_sum`) costs paths x chirps x samples, which is fine for the seed's
21 points but not for ~10^4 mesh facets. Here the beat signal of chirp m,

    s_m(n) = sum_p c_p exp(j 2 pi gamma tau_p n / fs),    c_p = a_p exp(j 2 pi f_s tau_p),

is evaluated by splitting each delay onto a grid, tau_p = q_p Delta + delta_p with |delta_p| <= Delta/2 and
Delta = fs / (gamma L), so that the grid factor is exp(j 2 pi q n / L): a length-L inverse DFT. The
remainder exp(j u_p n), u_p = 2 pi gamma delta_p / fs, is expanded to order K:

    s_m(n) = sum_k n^k IDFT_L[ sum_{p in q} c_p (j u_p)^k / k! ](n),   n < N.

With L = oversample * N, |u_p n| <= pi / oversample, so the truncation error is below
(pi/oversample)^(K+1) / (K+1)! of each path's amplitude (8x, K = 3: 1e-3, i.e. -60 dB). The grid index is
taken modulo L, which is exactly the beat-frequency aliasing of a real ADC. Per path and chirp the work
is O(K): the slow-time phase 2 pi f_s tau(t) is a cubic in the chirp index inside one frame interval
(the delay spline is a cubic there), so its phasor is advanced by forward differences (three complex
multiplications, no transcendental function), reseeded in float64 at every frame interval.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import scipy.fft

BLOCK = 256  # paths per cache block in the accumulation kernel
ORDER = 3  # Taylor order of the sub-grid correction (see module docstring for the error bound)


@numba.njit(parallel=True, cache=True, fastmath=True, error_model="numpy")
def _accumulate(t, knots, coef, g0, g1, start_hz, u_scale, delta, n_grid, out):  # pragma: no cover - jitted
    """Add every path's chirp phasors onto the delay grid.

    t: chirp start times [C] (s), PRI-spaced. knots: interval edges [I+1] (s). coef: delay cubic per
    interval [4, I, P] (s, in powers of s - knots[i], highest first). g0/g1: complex gain at the
    start/end of each interval [I, P] (linear in between). out: [C, n_grid, 2 (ORDER+1)] float64
    (re, im of each order adjacent, so one grid hit touches one cache line), zeroed by the caller.
    Chirps of one interval are written only by the thread that owns that interval (no races).
    Real arithmetic by hand: numba's complex multiply is ~2x slower (measured).
    """
    c_n = t.shape[0]
    n_int = knots.shape[0] - 1
    n_paths = coef.shape[2]
    pri = t[1] - t[0] if c_n > 1 else 1.0
    first = min(max(np.searchsorted(knots, t[0], side="right") - 1, 0), n_int - 1)
    last = min(max(np.searchsorted(knots, t[c_n - 1], side="right") - 1, 0), n_int - 1)
    w = 2.0 * math.pi * start_hz
    two_pi = 2.0 * math.pi
    inv_delta = 1.0 / delta
    mask = n_grid - 1
    for i in numba.prange(first, last + 1):
        # chirps whose start lies in [knots[i], knots[i+1]) (the end intervals also take what lies beyond)
        lo = np.searchsorted(t, knots[i], side="left") if i > first else 0
        hi = np.searchsorted(t, knots[i + 1], side="left") if i < last else c_n
        if hi <= lo:
            continue
        h = knots[i + 1] - knots[i]
        s0 = t[lo] - knots[i]
        tt = pri
        # per-path state, then blocks of paths: chirp-outer / path-inner within a block keeps the block's
        # state in cache and its writes in a few lines of one grid row (neighbouring facets have similar
        # delays); path-outer order strided rows 64 kB apart, all-paths-inner streamed MBs of state (measured)
        act = np.empty(n_paths, np.int64)
        n_act = 0
        for p in range(n_paths):
            if g0[i, p] != 0 or g1[i, p] != 0:
                act[n_act] = p
                n_act += 1
        st = np.empty((n_act, 14))  # e, e1, e2, e3 (re, im), g (re, im), dg (re, im), 2 spare
        cf = np.empty((n_act, 4))
        for j in range(n_act):
            p = act[j]
            a3, a2, a1, a0 = coef[0, i, p], coef[1, i, p], coef[2, i, p], coef[3, i, p]
            cf[j, 0], cf[j, 1], cf[j, 2], cf[j, 3] = a3, a2, a1, a0
            # phase and its forward differences at step PRI from the cubic's coefficients (no cancellation)
            ph0 = w * (((a3 * s0 + a2) * s0 + a1) * s0 + a0)
            ph0 -= two_pi * math.floor(ph0 / two_pi)
            d1 = w * (a3 * (3 * s0 * s0 * tt + 3 * s0 * tt * tt + tt * tt * tt) + a2 * (2 * s0 * tt + tt * tt)
                      + a1 * tt)
            d2 = w * (a3 * (6 * s0 * tt * tt + 6 * tt * tt * tt) + 2 * a2 * tt * tt)
            d3 = w * 6 * a3 * tt * tt * tt
            st[j, 0], st[j, 1] = math.cos(ph0), math.sin(ph0)
            st[j, 2], st[j, 3] = math.cos(d1), math.sin(d1)
            st[j, 4], st[j, 5] = math.cos(d2), math.sin(d2)
            st[j, 6], st[j, 7] = math.cos(d3), math.sin(d3)
            ga, gb = g0[i, p], g1[i, p]
            st[j, 8], st[j, 9] = ga.real, ga.imag
            st[j, 10], st[j, 11] = (gb.real - ga.real) / h, (gb.imag - ga.imag) / h
        for j0 in range(0, n_act, BLOCK):
            for m in range(lo, hi):
                s = t[m] - knots[i]
                row = out[m]
                for j in range(j0, min(j0 + BLOCK, n_act)):
                    tau = ((cf[j, 0] * s + cf[j, 1]) * s + cf[j, 2]) * s + cf[j, 3]
                    er, ei = st[j, 0], st[j, 1]
                    xr, xi = st[j, 8] + st[j, 10] * s, st[j, 9] + st[j, 11] * s
                    cr, ci = xr * er - xi * ei, xr * ei + xi * er
                    q = math.floor(tau * inv_delta + 0.5)
                    u = u_scale * (tau - q * delta)
                    idx = int(q) & mask  # q mod L (L a power of two): beat-frequency aliasing
                    row[idx, 0] += cr
                    row[idx, 1] += ci
                    cr, ci = -ci * u, cr * u  # times j u
                    row[idx, 2] += cr
                    row[idx, 3] += ci
                    f = 0.5 * u
                    cr, ci = -ci * f, cr * f
                    row[idx, 4] += cr
                    row[idx, 5] += ci
                    f = u / 3.0
                    cr, ci = -ci * f, cr * f
                    row[idx, 6] += cr
                    row[idx, 7] += ci
                    e1r, e1i, e2r, e2i = st[j, 2], st[j, 3], st[j, 4], st[j, 5]
                    st[j, 0], st[j, 1] = er * e1r - ei * e1i, er * e1i + ei * e1r
                    st[j, 2], st[j, 3] = e1r * e2r - e1i * e2i, e1r * e2i + e1i * e2r
                    e3r, e3i = st[j, 6], st[j, 7]
                    st[j, 4], st[j, 5] = e2r * e3r - e2i * e3i, e2r * e3i + e2i * e3r
    return out


def grid_size(samples_per_chirp: int, oversample: int) -> int:
    """Delay-grid length L: the power of two >= oversample * N (fast inverse FFT, modulo by bit mask)."""
    return 1 << int(math.ceil(math.log2(oversample * samples_per_chirp)))


def gridded_tone_sum(t: np.ndarray, knots: np.ndarray, coef: np.ndarray, g0: np.ndarray, g1: np.ndarray,
                     start_hz: float, slope: float, fs: float, n_samples: int, oversample: int = 8,
                     ) -> np.ndarray:
    """Beat signal [C, N] (complex128) of many paths with piecewise-cubic delays.

    Args:
        t: chirp start times [C] (s), uniformly spaced by the PRI.
        knots: frame times bounding the polynomial pieces [I+1] (s); t must lie within them.
        coef: delay cubic per piece [4, I, P] in powers of (t - knots[i]) (s), highest power first
            (scipy PPoly layout).
        g0, g1: complex gains at the start and end of each piece [I, P]; linear in between.
        start_hz: chirp start frequency f_s (Hz). slope: chirp slope gamma (Hz/s). fs: ADC rate (Hz).
        n_samples: samples per chirp N. oversample: grid refinement L / N (error bound in module doc).
    """
    n_grid = grid_size(n_samples, oversample)
    delta = fs / (slope * n_grid)
    u_scale = 2 * np.pi * slope / fs
    acc = np.zeros((t.size, n_grid, 2 * (ORDER + 1)), dtype=np.float64)
    _accumulate(np.ascontiguousarray(t, np.float64), np.ascontiguousarray(knots, np.float64),
                np.ascontiguousarray(coef, np.float64), np.ascontiguousarray(g0, np.complex128),
                np.ascontiguousarray(g1, np.complex128), float(start_hz), float(u_scale), float(delta),
                n_grid, acc)
    # sum_q A[q] exp(+j 2 pi q n / L) = L * ifft(A)[n]; FFT threads follow numba's (NUMBA_NUM_THREADS)
    spec = scipy.fft.ifft(acc.view(np.complex128), axis=1, workers=numba.get_num_threads())[:, :n_samples]
    spec *= n_grid
    n = np.arange(n_samples, dtype=np.float64)
    out = spec[:, :, 0]
    for k in range(1, ORDER + 1):
        out = out + n ** k * spec[:, :, k]
    return out
