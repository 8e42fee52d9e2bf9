"""Distances between radar signatures: normalised DTW of mean-velocity curves (the seed's Table I),
total-variation distance between velocity distributions, mean-velocity RMSE.

All take arrays from `processing.dsp.signatures.Signature` (or a stored `signature.h5`) of equal waveform and DSP
settings; time axes of different lengths are compared over their common prefix (RMSE, TV) or warped (DTW).

Determinism: every sum here is a numpy reduction (`sum`, `cumsum`, `mean`) or dtaidistance's C loop, whose
order of additions is fixed by the array shape; no BLAS call (`@`, `dot`) is used, so results are the same
bytes for any BLAS thread count or CPU kernel.
"""
from __future__ import annotations

import numpy as np
from dtaidistance import dtw

from processing.errors import InputError


def normalised_dtw(a: np.ndarray, b: np.ndarray, scale: float | None = None) -> float:
    """DTW distance between two mean-velocity curves [m/s], normalised to be unit-free.

    dtaidistance's DTW is the root of the summed squared differences along the optimal warping path;
    dividing by sqrt(max(len a, len b)) makes it an RMS difference per time bin, and dividing by `scale`
    [m/s] makes it a fraction of that. Default scale: the larger peak |v| of the two curves, so the value
    is 0 for identical curves and at most ~1 (the range of the seed's Table I, whose normalisation is not
    stated); pass v_max for an absolute scale. Two all-zero curves are at distance 0.
    """
    a = np.ascontiguousarray(a, dtype=np.double)
    b = np.ascontiguousarray(b, dtype=np.double)
    if a.size == 0 or b.size == 0:
        raise InputError("DTW needs two non-empty curves")
    if scale is None:
        scale = max(np.abs(a).max(), np.abs(b).max())
        if scale == 0:
            return 0.0
    if scale <= 0:
        raise InputError("DTW scale must be positive")
    # use_pruning=False: dtaidistance 2.5's default pruning (Euclidean upper bound) returns inf for some
    # pairs whose optimal path is near the diagonal (measured: a near-zero simulated curve against a real
    # sit-down gave inf, the unpruned C DTW 4.74); the unpruned C loop is exact.
    return float(dtw.distance_fast(a, b, use_pruning=False) / np.sqrt(max(a.size, b.size)) / scale)


def _column_distributions(p_vt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Columns of p(v,t) normalised to sum 1, and which columns carry any signal."""
    p = np.asarray(p_vt, dtype=np.float64)
    total = p.sum(axis=0)
    ok = total > 0
    return np.where(ok, p / np.where(ok, total, 1.0), 0.0), ok


def pvt_tv_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Mean total-variation distance (0..1) between the velocity distributions of two p(v,t) [V, T].

    Per time bin, TV = 1/2 sum_v |p(v) - q(v)| of the column-normalised distributions; averaged over the
    common time bins where both carry signal (1.0 if a bin has signal in only one of them).
    """
    if p.shape[0] != q.shape[0]:
        raise InputError(f"p(v,t) velocity axes differ: {p.shape[0]} vs {q.shape[0]} bins")
    n = min(p.shape[1], q.shape[1])
    pp, ok_p = _column_distributions(p[:, :n])
    qq, ok_q = _column_distributions(q[:, :n])
    tv = 0.5 * np.abs(pp - qq).sum(axis=0)
    tv = np.where(ok_p ^ ok_q, 1.0, tv)
    used = ok_p | ok_q
    return float(tv[used].mean()) if used.any() else 0.0


def pvt_wasserstein(p: np.ndarray, q: np.ndarray, velocity: np.ndarray) -> float:
    """Mean earth-mover (Wasserstein-1) distance [m/s] between the velocity distributions of two p(v,t)
    [V, T] on the axis `velocity` [V] (m/s), over the common time bins where both carry signal.

    Unlike TV, a one-bin shift of a narrow line costs one bin width, not 1: it measures how far in
    velocity the energy sits apart. Per time bin: integral over v of |CDF_p - CDF_q| dv.
    """
    if p.shape[0] != q.shape[0] or p.shape[0] != len(velocity):
        raise InputError("p(v,t) velocity axes differ")
    n = min(p.shape[1], q.shape[1])
    pp, ok_p = _column_distributions(p[:, :n])
    qq, ok_q = _column_distributions(q[:, :n])
    both = ok_p & ok_q
    if not both.any():
        return 0.0
    dv = np.diff(np.asarray(velocity, dtype=np.float64))
    cdf_gap = np.abs(np.cumsum(pp[:, both] - qq[:, both], axis=0))[:-1]
    return float((cdf_gap * dv[:, None]).sum(axis=0).mean())


def mean_velocity_rmse(a: np.ndarray, b: np.ndarray) -> float:
    """RMS difference [m/s] of two mean-velocity curves over their common time bins."""
    n = min(len(a), len(b))
    if n == 0:
        raise InputError("RMSE needs two non-empty curves")
    return float(np.sqrt(np.mean((np.asarray(a[:n]) - np.asarray(b[:n])) ** 2)))


def signature_distances(a, b) -> dict[str, float]:
    """Distances between two signatures of one link (objects with `p_vt`, `velocity`, `mean_velocity`):
    `dtw` (normalised by the peak speed), `tv` (mean TV of p(v,t)), `emd` (mean Wasserstein-1 of p(v,t),
    m/s), `rmse` (mean velocity, m/s)."""
    return {"dtw": normalised_dtw(a.mean_velocity, b.mean_velocity),
            "emd": pvt_wasserstein(a.p_vt, b.p_vt, a.velocity),
            "tv": pvt_tv_distance(a.p_vt, b.p_vt),
            "rmse": mean_velocity_rmse(a.mean_velocity, b.mean_velocity)}
