"""Tapers by `scipy.signal.get_window` name, without importing scipy.signal for the rectangular window.

Importing scipy.signal costs 0.25-0.4 s (it pulls in scipy.stats); the project's default tapers (range
and Doppler) are rectangular, so the default chain never needs it, and checking a configured name (a
`DSPConfig` is built at import time: `GLASGOW_DSP`) must not need it either. Any other window is scipy's.
"""
from __future__ import annotations

import numbers

import numpy as np

# scipy.signal.get_window's names of the rectangular window (`boxcar` and its aliases).
RECTANGULAR = frozenset({"boxcar", "box", "ones", "rect", "rectangular"})
# Names scipy.signal.get_window (1.11-1.17) accepts as a plain string (windows without a required parameter).
NAMED = RECTANGULAR | frozenset({
    "bart", "barthann", "bartlett", "bkh", "black", "blackharr", "blackman", "blackmanharris", "blk", "bman", "bmn",
    "bohman", "brt", "brthan", "bth", "cosine", "exponential", "flat", "flattop", "flt", "halfcosine", "ham", "hamm",
    "hamming", "han", "hann", "lanczos", "nut", "nutl", "nuttall", "par", "parz", "parzen", "poisson", "sinc",
    "taylor", "taylorwin", "tri", "triang", "triangle", "tuk", "tukey"})


def is_window_name(name) -> bool:
    """True if `get_window(name, n)` works: a name of `NAMED` without importing scipy, else scipy's verdict."""
    if isinstance(name, str) and name in NAMED:
        return True
    from scipy.signal import get_window as scipy_get_window

    try:
        scipy_get_window(name, 8)
    except (ValueError, TypeError):
        return False
    return True


def get_window(name, n: int, fftbins: bool = True) -> np.ndarray:
    """`scipy.signal.get_window(name, n, fftbins)`: the taper [n] (float64, peak 1). The rectangular window
    is built here (ones, periodic and symmetric alike, as scipy's `boxcar`); anything else, including
    invalid arguments and their errors, is scipy's."""
    if isinstance(name, str) and name in RECTANGULAR and isinstance(n, numbers.Integral) and n > 0 \
            and isinstance(fftbins, bool):
        return np.ones(int(n), dtype=np.float64)
    from scipy.signal import get_window as scipy_get_window

    return scipy_get_window(name, n, fftbins=fftbins)


__all__ = ["NAMED", "RECTANGULAR", "get_window", "is_window_name"]
