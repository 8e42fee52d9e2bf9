"""Many-path FMCW synthesis: paths spread onto an oversampled beat-frequency grid (a non-uniform FFT).

The exact synthesiser (`synthesis.tone_sum`) costs paths x chirps x samples, fine for the seed's 21 points but
not for ~10^4 mesh facets. Write sample n of a chirp as n = n' + N/2 (n' = -N/2 .. N/2 - 1, N = samples):

    s(n) = sum_p c_p exp(j 2 pi n' X_p / M),   c_p = a_p exp(j 2 pi f_c tau_p),   X_p = gamma tau_p M / fs,

with f_c = f_s + gamma (N/2) / fs the instantaneous frequency at sample N/2 (centring the fast-time frequencies
halves the largest |n'|). This is a type-1 non-uniform DFT: path p sits at the non-integer cell X_p of a grid
of M = oversample x N cells per beat-frequency period (the grid wraps modulo M exactly as a real ADC aliases
beat frequencies beyond fs). Spreading every path onto the cells l near it with a smooth kernel phi
(`synthesis_kernel`), b[l] = sum_p c_p phi(X_p - l), gives by Poisson summation

    sum_l b[l] exp(j 2 pi n' l / M) = sum_p c_p exp(j 2 pi n' X_p / M) phihat(n'/M) (1 + e_p(n')),

so s(n) = [M ifft(b)](n') / phihat(n'/M) (`grid_to_iq`), and any linear map of a chirp's samples, such as the
DSP's range FFT of the used bins and its coherent range sum, is one matrix applied to b (`projection_matrix`),
which the kernel applies itself over the cells the paths touch (`spread(..., matrix)`). |e_p| <=
`SpreadKernel.error_bound` per path and sample: 1.8e-6 (-115 dB) at the defaults, against 1e-3 for the Taylor
grid this replaces.

Cost. Each path keeps a reference cell f for a few chirps (re-chosen on a fixed chirp schedule before its delay
can have drifted by `drift` cells) and its weights on cells f - w/2 .. f + w/2 + 1 are polynomials of degree 5
in its offset, so a path only adds c_p y_p^d (d = 0..5) to the moments of its reference cell; paths are
counting-sorted once per frame interval by the cell their reference follows (delay plus range-Doppler shift),
the ~7,000 facets of a body share a few tens of cells (runs of ~35 paths on the bench walk), and a
cell's moments go through the w + 2 weight polynomials once per chirp. Per path and chirp that is ~35 flops
(phasor, delay, six complex moments), in loops over structure-of-arrays state that vectorise.

Slow time: inside one frame interval a path's delay is a cubic in time (the Hermite spline of the frames'
delays and delay rates, or a rate extrapolation for frame-local paths, `synthesis.grid_pieces`), so its phasor
exp(j 2 pi f_c tau) is advanced from chirp to chirp by forward differences (three complex multiplications), seeded
in float64 at the first chirp of every frame interval (and chunk) from the phase in cycles reduced modulo 1.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import scipy.fft

from processing.numba_math import sincos as _sincos
from processing.synthesis.kernel import DEGREE, OVERSAMPLE, SpreadKernel, spread_kernel

__all__ = ["OVERSAMPLE", "SpreadKernel", "fold", "grid_cells", "grid_to_iq", "gridded_tone_sum", "prepare_frames",
           "projection_matrix", "spread", "spread_kernel"]

BLOCK = 256  # paths processed together (state and moments stay in L1/L2)
# fast-math without "nnan"/"ninf": reassociation and contraction let the loops vectorise, while NaN tests
# (absent frames' delay rates) keep working
FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}

def grid_cells(n_samples: int, kernel: SpreadKernel) -> int:
    """Grid length M = oversample x N."""
    return kernel.oversample * n_samples


def centre_sample(n_samples: int) -> int:
    """Sample N // 2 whose instantaneous frequency carries the paths' phases (module docstring)."""
    return n_samples // 2


@numba.njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def _spread(t, pri, t_first, t_last, first_index, knots, y0, y1, m0, m1, g0, g1, f_ref, x_scale, n_grid, kc,
            y_a, y_b, drift, kappa, delta, out, pm, proj):  # pragma: no cover
    """Add every path's chirp phasors, spread by the kernel, onto the grid rows out[C, 2 L] (re, im adjacent).

    t: chirp start times [C] (s) of this chunk, chirps first_index.. of the recording t_first + k pri, k up to
    (t_last - t_first) / pri. Everything but the phasors' float64 seeds depends only on the recording, not
    on the chunk (reference cells are re-chosen on a global chirp schedule), so chunking changes the
    output by float rounding only. knots: interval edges [I+1] (s). y0, y1, m0, m1: delay (s) and
    delay rate at the start and end of each interval [I, P] (cubic Hermite). g0, g1: complex gains at the
    start/end of each interval [I, P] (linear in between); NaN rates count as 0. f_ref: carrier of the phases (Hz).
    kappa: range-Doppler coupling (s per s/s, `synthesis.exact.coupling_s`): a path's cell follows
    tau + kappa dtau/dt; delta (s per s/s): its phase at the centre sample follows f_ref (tau + delta dtau/dt),
    the exact synthesiser's tone (phase f_s tau at the chirp's start) seen at the centre. x_scale: grid
    cells per second of delay. kc: fitted weights [w + 2, 8]. y_a, y_b: offset -> polynomial variable.
    pm: [L, 2K] projection matrix (re, im adjacent) or [L, 0]: then proj[C, 2K] receives each finished row
    times pm over the cells this interval touched (K = 0: no projection).
    Chirps of one interval are written only by the thread that owns that interval (no races). Real
    arithmetic by hand (numba's complex multiply is slower) and structure-of-arrays state, so that the
    per-chirp loops over paths vectorise.
    """
    n_cells = kc.shape[0]
    kt = np.ascontiguousarray(kc[:, :DEGREE + 1].T)  # [degree + 1, cells]
    c_n = t.shape[0]
    n_int = knots.shape[0] - 1
    n_paths = y0.shape[1]
    first = min(max(np.searchsorted(knots, t[0], side="right") - 1, 0), n_int - 1)
    last = min(max(np.searchsorted(knots, t[c_n - 1], side="right") - 1, 0), n_int - 1)
    two_pi = 2.0 * math.pi
    fm = float(n_grid)
    for i in numba.prange(first, last + 1):
        # chirps whose start lies in [knots[i], knots[i+1]) (the end intervals also take what lies beyond)
        lo = np.searchsorted(t, knots[i], side="left") if i > first else 0
        hi = np.searchsorted(t, knots[i + 1], side="left") if i < last else c_n
        if hi <= lo:
            continue
        h = knots[i + 1] - knots[i]
        inv_h = 1.0 / h
        s_lo = t[lo] - knots[i]
        # time span of the whole interval's chirps (the end intervals also take chirps beyond the knots)
        s_a = min(-pri, t_first - knots[i]) if i == 0 else -pri
        s_b = max(h, t_last - knots[i]) if i == n_int - 1 else h
        s_max = max(-s_a, s_b)
        anchor = int(math.floor((knots[i] - t_first) / pri))  # global chirp index the reference schedule starts at
        # active paths, counting-sorted by their cell at the knot: paths sharing a cell become runs. The key is
        # the cell the reference follows, tau + kappa dtau/dt (Doppler-shifted): sorted by the delay alone, the
        # limbs' Doppler shifts scattered a cell's paths into runs of ~10 (bench walk) instead of ~35
        key = np.empty(n_paths, np.int64)
        for p in range(n_paths):
            rk = m0[i, p]
            xk = x_scale * (y0[i, p] + kappa * (rk if math.isfinite(rk) else 0.0))
            c = int(xk - fm * math.floor(xk / fm))
            key[p] = n_grid if (g0[i, p] == 0 and g1[i, p] == 0) else min(max(c, 0), n_grid - 1)
        count = np.zeros(n_grid + 2, np.int64)
        for p in range(n_paths):
            count[key[p] + 1] += 1
        n_act = n_paths - count[n_grid + 1]
        if n_act == 0:
            continue
        for c in range(n_grid):
            count[c + 1] += count[c]
        act = np.empty(n_paths, np.int64)
        for p in range(n_paths):
            act[count[key[p]]] = p
            count[key[p]] += 1
        b = min(BLOCK, n_act)
        cf = np.empty((4, b))  # delay cubic in powers of the time since the knot (s, then cells)
        gn = np.empty((4, b))  # gain at the knot and its slope (re, im)
        # phasor e and its forward-difference steps e1, e2, e3 (re, im); one array each: the per-chirp loops
        # vectorise better than over the rows of one 2-D array (measured)
        er, ei, e1r, e1i = np.empty(b), np.empty(b), np.empty(b), np.empty(b)
        e2r, e2i, e3r, e3i = np.empty(b), np.empty(b), np.empty(b), np.empty(b)
        cr, ci, yy = np.empty(b), np.empty(b), np.empty(b)  # this chirp: c = gain x phasor, polynomial variable
        ref = np.empty(b)
        tr, ti = np.empty(n_cells), np.empty(n_cells)  # one run's additions to its cells (re, im)
        cell = np.empty(b, np.int64)
        starts = np.empty(b + 1, np.int64)
        e_lo, e_hi = n_grid, 0  # extended cells touched by this interval: [e_lo, e_hi + n_cells)
        for j0 in range(0, n_act, BLOCK):
            nb = min(BLOCK, n_act - j0)
            for jj in range(nb):
                p = act[j0 + jj]
                ya, ma, mb = y0[i, p], m0[i, p], m1[i, p]
                ma = ma if math.isfinite(ma) else 0.0  # absent frames' NaN rates read as 0 (np.nan_to_num)
                mb = mb if math.isfinite(mb) else 0.0
                slope = (y1[i, p] - ya) * inv_h
                tq = (ma + mb - 2.0 * slope) * inv_h
                cf[0, jj], cf[1, jj], cf[2, jj], cf[3, jj] = tq * inv_h, (slope - ma) * inv_h - tq, ma, ya
                ga, gb = g0[i, p], g1[i, p]
                gn[0, jj], gn[1, jj] = ga.real, ga.imag
                gn[2, jj], gn[3, jj] = (gb.real - ga.real) * inv_h, (gb.imag - ga.imag) * inv_h
            for jj in range(nb):
                a3, a2, a1, a0 = cf[0, jj], cf[1, jj], cf[2, jj], cf[3, jj]
                # the phase at the centre sample includes the Doppler phase since the chirp's start:
                # f_ref (tau + delta dtau/dt), again a cubic (delta = kappa (f_ref - f_s) / f_ref)
                a2, a1, a0 = a2 + 3.0 * delta * a3, a1 + 2.0 * delta * a2, a0 + delta * a1
                # phase and its forward differences at step PRI, in cycles (reduced modulo 1 in float64)
                p0 = f_ref * (((a3 * s_lo + a2) * s_lo + a1) * s_lo + a0)
                p0 -= np.floor(p0)
                d1 = f_ref * (a3 * (3 * s_lo * s_lo * pri + 3 * s_lo * pri * pri + pri * pri * pri)
                              + a2 * (2 * s_lo * pri + pri * pri) + a1 * pri)
                d1 -= np.floor(d1)
                d2 = f_ref * (a3 * (6 * s_lo * pri * pri + 6 * pri * pri * pri) + 2 * a2 * pri * pri)
                d3 = f_ref * 6 * a3 * pri * pri * pri
                ei[jj], er[jj] = _sincos(two_pi * p0)
                e1i[jj], e1r[jj] = _sincos(two_pi * d1)
                e2i[jj], e2r[jj] = _sincos(two_pi * d2)
                e3i[jj], e3r[jj] = _sincos(two_pi * d3)
            for jj in range(nb):  # the cell follows tau + kappa dtau/dt (Doppler shift inside the chirp)
                a3, a2, a1 = cf[0, jj], cf[1, jj], cf[2, jj]
                cf[1, jj], cf[2, jj], cf[3, jj] = a2 + 3.0 * kappa * a3, a1 + 2.0 * kappa * a2, cf[3, jj] + kappa * a1
            rate = 0.0  # largest |d tau / dt| over the chirps of this interval
            for jj in range(nb):
                v = (abs(3 * cf[0, jj]) * s_max + abs(2 * cf[1, jj])) * s_max + abs(cf[2, jj])
                if v > rate:
                    rate = v
            for k in range(4):
                for jj in range(nb):
                    cf[k, jj] *= x_scale
            # chirps per reference cell: the delay may drift by at most `drift` cells meanwhile
            step = rate * x_scale * pri
            n_sub = 1 + int(min(drift / step, 1e9)) if step > 0 else 1 << 30
            ma_ = lo
            while ma_ < hi:
                k_sub = (first_index + ma_ - anchor) // n_sub
                g_ref = anchor + k_sub * n_sub  # global index of this sub-interval's reference chirp
                mb_ = min(hi, g_ref + n_sub - first_index)
                s = t_first + g_ref * pri - knots[i]
                for jj in range(nb):
                    ref[jj] = np.floor(((cf[0, jj] * s + cf[1, jj]) * s + cf[2, jj]) * s + cf[3, jj])
                for jj in range(nb):
                    f = ref[jj]
                    cell[jj] = int(f - fm * np.floor(f / fm))
                for jj in range(nb):
                    e_lo = min(e_lo, cell[jj])
                    e_hi = max(e_hi, cell[jj])
                n_run = 0
                starts[0] = 0
                for jj in range(1, nb):
                    if cell[jj] != cell[jj - 1]:
                        n_run += 1
                        starts[n_run] = jj
                n_run += 1
                starts[n_run] = nb
                for m in range(ma_, mb_):
                    s = t[m] - knots[i]
                    row = out[m]
                    for jj in range(nb):
                        x = ((cf[0, jj] * s + cf[1, jj]) * s + cf[2, jj]) * s + cf[3, jj]
                        yy[jj] = (x - ref[jj]) * y_a - y_b
                    for jj in range(nb):
                        xr, xi = gn[0, jj] + gn[2, jj] * s, gn[1, jj] + gn[3, jj] * s
                        a, bb = er[jj], ei[jj]
                        cr[jj] = xr * a - xi * bb
                        ci[jj] = xr * bb + xi * a
                        c1, s1 = e1r[jj], e1i[jj]
                        er[jj], ei[jj] = a * c1 - bb * s1, a * s1 + bb * c1
                        c2, s2 = e2r[jj], e2i[jj]
                        e1r[jj], e1i[jj] = c1 * c2 - s1 * s2, c1 * s2 + s1 * c2
                        c3, s3 = e3r[jj], e3i[jj]
                        e2r[jj], e2i[jj] = c2 * c3 - s2 * s3, c2 * s3 + s2 * c3
                    for r in range(n_run):
                        r0 = r1 = r2 = r3 = r4 = r5 = 0.0
                        i0 = i1 = i2 = i3 = i4 = i5 = 0.0
                        # views indexed from 0: with indices read from `starts` numba cannot rule out negative
                        # ones, wraps them, and the vectorised loop gathers instead of loading (11 % of the kernel)
                        j0, j1 = starts[r], starts[r + 1]
                        yv, crv, civ = yy[j0:j1], cr[j0:j1], ci[j0:j1]
                        for k in range(j1 - j0):
                            y = yv[k]
                            vr, vi = crv[k], civ[k]
                            r0 += vr
                            i0 += vi
                            vr *= y
                            vi *= y
                            r1 += vr
                            i1 += vi
                            vr *= y
                            vi *= y
                            r2 += vr
                            i2 += vi
                            vr *= y
                            vi *= y
                            r3 += vr
                            i3 += vi
                            vr *= y
                            vi *= y
                            r4 += vr
                            i4 += vi
                            vr *= y
                            vi *= y
                            r5 += vr
                            i5 += vi
                        # the cells' weights from the moments as loops over contiguous rows of kt, which
                        # vectorise (the interleaved re/im row does not): -7 % of the kernel
                        for q in range(n_cells):
                            tr[q] = (kt[0, q] * r0 + kt[1, q] * r1 + kt[2, q] * r2 + kt[3, q] * r3 + kt[4, q] * r4
                                     + kt[5, q] * r5)
                            ti[q] = (kt[0, q] * i0 + kt[1, q] * i1 + kt[2, q] * i2 + kt[3, q] * i3 + kt[4, q] * i4
                                     + kt[5, q] * i5)
                        base = 2 * cell[starts[r]]
                        rv = row[base:base + 2 * n_cells]
                        for q in range(n_cells):
                            rv[2 * q] += tr[q]
                            rv[2 * q + 1] += ti[q]
                ma_ = mb_
        n_out = pm.shape[1]
        if n_out:
            acc = np.empty(n_out)
            for m in range(lo, hi):
                row = out[m]
                acc[:] = 0.0
                for e in range(e_lo, e_hi + n_cells):
                    br, bi = row[2 * e], row[2 * e + 1]
                    for k in range(0, n_out, 2):
                        acc[k] += br * pm[e, k] - bi * pm[e, k + 1]
                        acc[k + 1] += br * pm[e, k + 1] + bi * pm[e, k]
                proj[m, :] = acc
    return out


@numba.njit(parallel=True, cache=True)
def _prepare_frames(times, out, rates, gains, gaps):  # pragma: no cover - jitted
    """Fill the NaN gaps of `out` [K, P] (a copy of the delays) in place; largest |rate| (NaN as 0) and largest
    delay of the present paths."""
    n, n_paths = out.shape
    rate_max = np.zeros(n)
    delay_max = np.zeros(n)
    for k in numba.prange(n):
        rm, dm = 0.0, 0.0
        for p in range(n_paths):
            if gains[k, p].real != 0 or gains[k, p].imag != 0:
                v = rates[k, p] if rates.shape[0] else 0.0
                v = v if math.isfinite(v) else 0.0
                rm = max(rm, abs(v))
                dm = max(dm, out[k, p])
        rate_max[k], delay_max[k] = rm, dm
    # gaps filled row by row (a column walk would touch a new cache line per frame): next present frame of
    # every gap column from a backward sweep, then interpolation from the last present one in a forward sweep
    n_gaps = gaps.size
    nxt = np.empty((n, n_gaps), np.int32)
    follow = np.full(n_gaps, n, np.int32)
    for k in range(n - 1, -1, -1):
        for gi in range(n_gaps):
            if math.isfinite(out[k, gaps[gi]]):
                follow[gi] = k
            nxt[k, gi] = follow[gi]
    prev = np.full(n_gaps, -1, np.int64)
    for k in range(n):
        for gi in range(n_gaps):
            p = gaps[gi]
            if math.isfinite(out[k, p]):
                prev[gi] = k
                continue
            a, b = prev[gi], nxt[k, gi]
            if a < 0 and b >= n:
                out[k, p] = 0.0
            elif a < 0:
                out[k, p] = out[b, p]
            elif b >= n:
                out[k, p] = out[a, p]
            else:
                slope = (out[b, p] - out[a, p]) / (times[b] - times[a])
                out[k, p] = slope * (times[k] - times[a]) + out[a, p]
    return rate_max.max() if n else 0.0, delay_max.max() if n else 0.0


def prepare_frames(times: np.ndarray, delays: np.ndarray, rates: np.ndarray | None, gains: np.ndarray):
    """(delays [K, P] with NaN gaps filled as `synthesis._fill_absent` fills them (np.interp's arithmetic,
    bitwise the same; the input itself if it has no gap), largest |delay rate| (NaN as 0) and largest delay [s]
    of the present paths (gain != 0))."""
    gaps = np.flatnonzero(~np.isfinite(delays).all(axis=0))
    out = delays.copy() if gaps.size else delays
    rate_max, delay_max = _prepare_frames(times, out, np.zeros((0, 0)) if rates is None else rates, gains, gaps)
    return out, float(rate_max), float(delay_max)


def spread(t: np.ndarray, knots: np.ndarray, y0: np.ndarray, y1: np.ndarray, m0: np.ndarray, m1: np.ndarray,
           g0: np.ndarray, g1: np.ndarray, start_hz: float, slope: float, fs: float, n_samples: int,
           kernel: SpreadKernel, matrix: np.ndarray | None = None, pri: float | None = None,
           t_all: tuple[float, float] | None = None) -> np.ndarray:
    """Spread grid [C, M + w + 1] (complex128, cell e <-> grid cell (e - w/2) mod M) of many paths, or with
    `matrix` [M + w + 1, K] (`projection_matrix`) the projection grid @ matrix [C, K], formed in the kernel
    over the cells the paths touch.

    Args:
        t: chirp start times [C] (s), uniformly spaced by the PRI, within or at the ends of the knots.
        knots: frame times bounding the delay pieces [I+1] (s).
        y0, y1, m0, m1: delays [s] and delay rates [s/s] at the start and end of each piece [I, P]: the delay
            is their cubic Hermite interpolant inside the piece.
        g0, g1: complex gains at the start and end of each piece [I, P]; linear in between.
        start_hz: chirp start frequency f_s (Hz). slope: chirp slope gamma (Hz/s). fs: ADC rate (Hz).
        n_samples: samples per chirp N. kernel: `spread_kernel()`.
        pri: chirp interval (s); default t[1] - t[0]. t_all: (first, last) chirp start time of the whole
            recording when t is one chunk of it (default t's own), so that chunks give the same result.
    """
    if kernel.weights.shape[1] != DEGREE + 1:
        raise ValueError(f"the spreading loop is written for degree-{DEGREE} weights")
    m = grid_cells(n_samples, kernel)
    f_ref = start_hz + slope * centre_sample(n_samples) / fs
    out = np.zeros((t.size, 2 * (m + kernel.n_cells - 1)))
    pm = np.zeros((out.shape[1] // 2, 0)) if matrix is None else \
        np.ascontiguousarray(np.asarray(matrix, np.complex128)).view(np.float64)
    if pm.shape[0] != out.shape[1] // 2:
        raise ValueError(f"projection matrix must have {out.shape[1] // 2} rows, got {pm.shape[0]}")
    proj = np.zeros((t.size, pm.shape[1]))
    if t.size and y0.size:
        a = 2.0 / (1 + 2 * kernel.drift)
        pri = float(t[1] - t[0] if pri is None else pri)
        t_first, t_last = (float(t[0]), float(t[-1])) if t_all is None else map(float, t_all)
        first_index = int(round((t[0] - t_first) / pri))
        _spread(np.ascontiguousarray(t, np.float64), pri, t_first, t_last, first_index,
                np.ascontiguousarray(knots, np.float64), y0, y1, m0, m1, g0, g1, float(f_ref), float(slope * m / fs), m,
                np.ascontiguousarray(kernel.weights), a, a / 2, float(kernel.drift), float(f_ref / slope),
                float((f_ref - start_hz) / slope), out, pm, proj)
    return out.view(np.complex128) if matrix is None else proj.view(np.complex128)


def projection_matrix(weights: np.ndarray, n_samples: int, kernel: SpreadKernel) -> np.ndarray:
    """[M + w + 1, K] matrix taking a spread grid to `iq @ weights` (weights [N, K] over fast time)."""
    m = grid_cells(n_samples, kernel)
    n_prime = np.arange(n_samples) - centre_sample(n_samples)
    cells = np.arange(m + kernel.n_cells - 1) - kernel.width // 2
    roots = np.exp(2j * np.pi * np.arange(m) / m)  # exp(j 2 pi l n' / M) depends on l n' mod M only
    dft = roots[np.outer(cells, n_prime) % m] / kernel.phihat(n_prime / m)
    return dft @ np.asarray(weights, dtype=np.complex128)


def fold(grid: np.ndarray, kernel: SpreadKernel) -> np.ndarray:
    """Spread grid [C, M + w + 1] -> periodic grid [C, M] (cells 0..M-1)."""
    half = kernel.width // 2
    m = grid.shape[1] - kernel.n_cells + 1
    g = grid[:, half:half + m].copy()
    g[:, m - half:] += grid[:, :half]
    g[:, :grid.shape[1] - half - m] += grid[:, half + m:]
    return g


def grid_to_iq(grid: np.ndarray, n_samples: int, kernel: SpreadKernel) -> np.ndarray:
    """Beat signal [C, N] (complex128) of a spread grid: M ifft of the folded grid over phihat."""
    g = fold(grid, kernel)
    m = g.shape[1]
    n_prime = np.arange(n_samples) - centre_sample(n_samples)
    spec = scipy.fft.ifft(g, axis=1, workers=numba.get_num_threads())  # FFT threads follow numba's
    return spec[:, n_prime % m] * (m / kernel.phihat(n_prime / m))


def gridded_tone_sum(t, knots, y0, y1, m0, m1, g0, g1, start_hz: float, slope: float, fs: float, n_samples: int,
                     kernel: SpreadKernel | None = None) -> np.ndarray:
    """Beat signal [C, N] (complex128) of many paths (arguments as `spread`)."""
    kernel = spread_kernel() if kernel is None else kernel
    grid = spread(t, knots, y0, y1, m0, m1, g0, g1, start_hz, slope, fs, n_samples, kernel)
    return grid_to_iq(grid, n_samples, kernel)
