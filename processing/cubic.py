"""Cubic Hermite and not-a-knot splines, PCHIP slopes and log-sum-exp in numpy alone (the synthesiser's delay
curves, with or without delay rates; the procedural motions' key-frame curves and soft minimum).

A points `rtchannel simulate` needed `scipy.interpolate` (and with it `scipy.spatial`, `scipy.linalg`,
`scipy.optimize`, ...) for these few small functions only: ~0.2 s of its ~0.9 s of CPU, on top of the
`scipy.fft` its fast-time stage needs (measured, 2-core machine). They are the same computations in numpy,
operation for operation in the order SciPy 1.17 performs them (`CubicHermiteSpline`'s coefficients, `PPoly`'s
evaluation as a power sum and its derivative's coefficients; `CubicSpline`'s not-a-knot system solved in
LAPACK dgtsv's elimination order, as `solve_banded` does; PCHIP's Fritsch-Carlson interior slopes;
`logsumexp` with every maximal element taken out of the sum), so delays and motions are bit-identical to the
SciPy route's (tests/test_cubic.py compares them, and fails if a SciPy release changes its order).
"""
from __future__ import annotations

import numpy as np


def _column(v: np.ndarray, ndim: int) -> np.ndarray:
    """A 1-D array shaped to broadcast along axis 0 of an `ndim`-D array."""
    return v.reshape((-1,) + (1,) * (ndim - 1))


class HermiteSpline:
    """The cubic Hermite spline through (`x`, `y`) with slopes `dydx`, extrapolated beyond the knots by the
    end pieces (as `scipy.interpolate.CubicHermiteSpline(x, y, dydx)`, `axis=0`).

    Args:
        x: knots [K], strictly increasing, finite (any unit).
        y: values [K, ...] at the knots.
        dydx: slopes [K, ...] at the knots (unit of y per unit of x).
    """

    def __init__(self, x, y, dydx):
        x = np.asarray(x, np.float64)
        y, d = np.asarray(y, np.float64), np.asarray(dydx, np.float64)
        if x.ndim != 1 or x.shape[0] < 2 or y.shape[0] != x.shape[0] or d.shape != y.shape:
            raise ValueError("HermiteSpline: needs >= 2 knots, and values and slopes of one length each")
        dx = np.diff(x)
        if not (np.all(np.isfinite(x)) and np.all(dx > 0)):
            raise ValueError("HermiteSpline: the knots must be finite and strictly increasing")
        dxr = _column(dx, y.ndim)
        slope = np.diff(y, axis=0) / dxr
        t = (d[:-1] + d[1:] - 2 * slope) / dxr
        self.x, self.trailing = x, y.shape[1:]
        # per piece, the coefficients of s^3, s^2, s, 1 with s = u - x[i]
        self.c: tuple[np.ndarray, ...] = (t / dxr, (slope - d[:-1]) / dxr - t, d[:-1], y[:-1])

    def derivative(self) -> "HermiteSpline":
        """The first derivative of the cubic (a piecewise quadratic; `PPoly.derivative`'s coefficients 3 c0,
        2 c1, c2); not itself differentiable again here."""
        out = object.__new__(HermiteSpline)
        out.x, out.trailing = self.x, self.trailing
        c0, c1, c2, _ = self.c
        out.c = (c0 * 3.0, c1 * 2.0, c2 * 1.0)
        return out

    def __call__(self, u, nu: int = 0) -> np.ndarray:
        """The curve's `nu`-th derivative (0 or 1) at `u` (any shape, unit of x): float64
        [*u.shape, *y.shape[1:]]."""
        u = np.asarray(u, np.float64)
        flat = u.ravel()
        # the piece of x[i] <= u < x[i+1], the last one closed on the right; outside: the end pieces
        i = np.clip(np.searchsorted(self.x, flat, side="right") - 1, 0, self.x.shape[0] - 2)
        s = _column(flat - self.x[i], len(self.trailing) + 1)
        # PPoly's power sum (scipy's evaluate_poly1), lowest order first: sum_k c[-1-k] s^(k-nu) k!/(k-nu)!
        # (products by 1.0 left out: they change no bit; np.take: gathers ~5x faster than fancy indexing)
        n = len(self.c)
        res = np.take(self.c[n - 1 - nu], i, axis=0)
        res += 0.0  # scipy's sum starts at 0.0 (-0.0 + 0.0 = +0.0)
        z = None  # s^(k - nu)
        for k in range(nu + 1, n):
            prefactor = 1.0
            for f in range(k, k - nu, -1):
                prefactor *= f
            z = s if z is None else z * s
            term = np.take(self.c[n - 1 - k], i, axis=0)
            term *= z
            if prefactor != 1.0:
                term *= prefactor
            res += term
        return np.asarray(res).reshape(u.shape + self.trailing)


def _gtsv(dl: np.ndarray, d: np.ndarray, du: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The solution of the tridiagonal system (sub-, main and super-diagonal `dl` [n-1], `d` [n], `du` [n-1])
    for the right-hand sides `b` [n, m], by LAPACK dgtsv's Gaussian elimination with partial pivoting, in its
    order of operations (what `scipy.linalg.solve_banded((1, 1), ...)` calls)."""
    dl, d, du, b = dl.copy(), d.copy(), du.copy(), b.copy()
    n = d.shape[0]
    for i in range(n - 1):
        if abs(d[i]) >= abs(dl[i]):  # no row interchange
            if d[i] == 0:
                raise np.linalg.LinAlgError("singular matrix")
            fact = dl[i] / d[i]
            d[i + 1] = d[i + 1] - fact * du[i]
            b[i + 1] = b[i + 1] - fact * b[i]
            if i < n - 2:
                dl[i] = 0.0
        else:  # interchange rows i and i+1
            fact = d[i] / dl[i]
            d[i] = dl[i]
            temp = d[i + 1]
            d[i + 1] = du[i] - fact * temp
            if i < n - 2:
                dl[i] = du[i + 1]
                du[i + 1] = -fact * dl[i]
            du[i] = temp
            temp_b = b[i].copy()
            b[i] = b[i + 1]
            b[i + 1] = temp_b - fact * b[i + 1]
    if d[n - 1] == 0:
        raise np.linalg.LinAlgError("singular matrix")
    b[n - 1] = b[n - 1] / d[n - 1]
    if n > 1:
        b[n - 2] = (b[n - 2] - du[n - 2] * b[n - 1]) / d[n - 2]
    for i in range(n - 3, -1, -1):
        b[i] = (b[i] - du[i] * b[i + 1] - dl[i] * b[i + 2]) / d[i]
    return b


def not_a_knot_spline(x, y) -> HermiteSpline:
    """The not-a-knot cubic spline through (`x`, `y`) (as `scipy.interpolate.CubicSpline(x, y, axis=0)`, for
    at least 4 knots; fewer: SciPy's own).

    Args:
        x: knots [K], strictly increasing, finite.
        y: values [K, ...].

    Returns:
        The spline as a `HermiteSpline` (its slopes solved from the not-a-knot tridiagonal system).
    """
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    n = x.shape[0]
    if n < 4 or y.shape[0] != n:
        from scipy.interpolate import CubicSpline  # the special cases of 2 and 3 knots

        spline = CubicSpline(x, y, axis=0)
        out = object.__new__(HermiteSpline)
        out.x, out.trailing = np.asarray(spline.x, np.float64), y.shape[1:]
        out.c = tuple(np.asarray(spline.c[k], np.float64) for k in range(4))
        return out
    dx = np.diff(x)
    if not (np.all(np.isfinite(x)) and np.all(dx > 0)):
        raise ValueError("not_a_knot_spline: the knots must be finite and strictly increasing")
    dxr = _column(dx, y.ndim)
    slope = np.diff(y, axis=0) / dxr
    diag, upper, lower = np.zeros(n), np.zeros(n), np.zeros(n)  # scipy's banded rows A[1], A[0], A[-1]
    b = np.empty((n,) + y.shape[1:])
    diag[1:-1] = 2 * (dx[:-1] + dx[1:])
    upper[2:] = dx[:-1]
    lower[:-2] = dx[1:]
    b[1:-1] = 3 * (dxr[1:] * slope[:-1] + dxr[:-1] * slope[1:])
    diag[0] = dx[1]
    upper[1] = x[2] - x[0]
    d = x[2] - x[0]
    b[0] = ((dxr[0] + 2 * d) * dxr[1] * slope[0] + dxr[0] ** 2 * slope[1]) / d
    diag[-1] = dx[-2]
    lower[-2] = x[-1] - x[-3]
    d = x[-1] - x[-3]
    b[-1] = (dxr[-1] ** 2 * slope[-2] + (2 * d + dxr[-1]) * dxr[-2] * slope[-1]) / d
    s = _gtsv(lower[:-1], diag, upper[1:], b.reshape(n, -1)).reshape(b.shape)
    return HermiteSpline(x, y, s)


def hermite_spline(x, y, dydx, u) -> np.ndarray:
    """`HermiteSpline(x, y, dydx)(u)`: float64 [*u.shape, *y.shape[1:]] (see `HermiteSpline`)."""
    return HermiteSpline(x, y, dydx)(u)


def pchip_slopes(x, y) -> np.ndarray:
    """The monotone (Fritsch-Carlson, PCHIP) slopes at the interior knots of (`x`, `y`): zero where the
    neighbouring secants differ in sign or one is flat, else their weighted harmonic mean (as
    `scipy.interpolate.PchipInterpolator`). The end slopes are returned as 0 (the one caller holds the
    curve constant beyond its ends); with two knots both slopes are 0.

    Args:
        x: knots [K], strictly increasing.
        y: values [K, ...].

    Returns:
        float64 [K, ...] (unit of y per unit of x).
    """
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    hk = _column(x[1:] - x[:-1], y.ndim)
    mk = (y[1:] - y[:-1]) / hk
    dk = np.zeros_like(y)
    if y.shape[0] < 3:
        return dk
    smk = np.sign(mk)
    condition = (smk[1:] != smk[:-1]) | (mk[1:] == 0) | (mk[:-1] == 0)
    w1 = 2 * hk[1:] + hk[:-1]
    w2 = hk[1:] + 2 * hk[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):  # the divisions by 0 are the masked entries
        whmean = (w1 / mk[:-1] + w2 / mk[1:]) / (w1 + w2)
    inner = dk[1:-1]
    inner[~condition] = 1.0 / whmean[~condition]
    return dk


def logsumexp(a, axis: int = 0) -> np.ndarray:
    """log(sum(exp(a))) along `axis`, without overflow (as `scipy.special.logsumexp(a, axis=axis)` for real
    finite input: the maximal elements are taken out of the sum and added back as log1p).

    Args:
        a: real finite values (any shape).
        axis: the axis summed over.

    Returns:
        float64, `a`'s shape without `axis`.
    """
    a = np.asarray(a, np.float64)
    a_max = np.max(a, axis=axis, keepdims=True)
    mask = a == a_max
    m = np.sum(mask.astype(np.float64), axis=axis, keepdims=True)
    s = np.sum(np.exp(np.where(mask, -np.inf, a) - a_max), axis=axis, keepdims=True)
    s = np.where(s == 0, s, s / m)
    out = np.log1p(s) + np.log(m) + a_max
    return np.squeeze(out, axis=axis)


__all__ = ["HermiteSpline", "hermite_spline", "logsumexp", "not_a_knot_spline", "pchip_slopes"]
