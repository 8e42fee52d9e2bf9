"""Elementary functions for compiled (numba) loops, where libm's calls are the cost.

`sincos` gives both values of one argument in one branch-free pass (Cody-Waite reduction by pi/2 and fdlibm's
polynomial kernels): a libm sin and cos cost a call each and keep loops around them from vectorising. Used by the
gridded synthesiser's phasor seeds (`processing.synthesis.grid`) and the facet backend's triangle integral.
"""
from __future__ import annotations

import math

import numba

_TWO_OVER_PI = 2.0 / math.pi
_PIO2_HI = 1.57079632673412561417e+00  # pi/2 in two parts (fdlibm): k * _PIO2_HI is exact for |k| < 2^20
_PIO2_LO = 6.07710050650619224932e-11


@numba.njit(inline="always")
def sincos(x):  # pragma: no cover - jitted
    """(sin x, cos x) of x in radians, to ~1e-16 for |x| < 1e6 (absolute error ~|x| ulp of pi/2's tail):
    Cody-Waite reduction by pi/2, fdlibm's kernels, branch-free quadrant selection (so that loops calling it
    vectorise)."""
    k = math.floor(x * _TWO_OVER_PI + 0.5)
    r = (x - k * _PIO2_HI) - k * _PIO2_LO
    z = r * r
    s = r + r * z * (-1.66666666666666324348e-01 + z * (8.33333333332248946124e-03 + z * (
        -1.98412698298579493134e-04 + z * (2.75573137070700676789e-06 + z * (
            -2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)))))
    c = 1.0 - 0.5 * z + z * z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 + z * (
        2.48015872894767294178e-05 + z * (-2.75573143513906633035e-07 + z * (
            2.08757232129817482790e-09 + z * -1.13596475577881948265e-11)))))
    q = int(k) & 3
    sn = c if (q & 1) == 1 else s
    cs = s if (q & 1) == 1 else c
    return (-sn if q >= 2 else sn), (-cs if (q == 1 or q == 2) else cs)
