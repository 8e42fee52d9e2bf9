"""Slow-time clutter removal (moving-target indication, MTI) of range profiles and slow-time signals.

Every filter here runs along slow time (one sample per chirp, rate PRF = 1 / PRI), independently per range
bin, so a static return (wall, furniture, a person standing still) is a constant and is removed, while a
mover's Doppler tone passes. All are linear, so filtering range profiles and then summing range bins is
the same as summing and then filtering (the DSP filters the coherent range sum's slow-time signal itself).

Kinds (`DSPConfig.static_removal`):

- ``moving_average``: subtract a centred moving average of L chirps (zero phase, non-causal: offline
  processing). Its response 1 - D(f), D(f) = sin(pi f L / PRF) / (L sin(pi f / PRF)), is 0 at DC and
  -3 dB where D = 1 - 1/sqrt(2), i.e. at f L / PRF = 0.7554 (continuous limit), so L is the odd integer
  nearest to 0.7554 PRF / f_c (e.g. f_c = 3 Hz at PRF 2 kHz: L = 503 chirps = 0.25 s). Above the cut-off
  the response ripples by at most +1.7 dB (D's first sidelobe, -0.217) and is exactly 1 at f = k PRF / L.
  Near the recording's ends the average is taken over the chirps that exist (the window shrinks to one
  side), so a static return is removed exactly from the first to the last chirp; slow drifts near the
  ends are suppressed less (the one-sided average lags).
- ``butterworth``: Butterworth high-pass of order `mti_order` with -3 dB at f_c (scipy
  `butter(..., output="sos")`; |H|^2 = 1 / (1 + (tan(pi f_c / PRF) / tan(pi f / PRF))^(2 order))).
  Causal (`sosfilt`, what real-time radar hardware runs) or, with `mti_zero_phase`, forward-backward
  (`sosfiltfilt`: |H|^2 applied with zero phase, -6 dB at f_c, odd-extension padding at the ends).
- ``mean``: subtract each bin's mean over the whole recording (the seed-era default; it leaves the
  negative of every long-dwelling return, e.g. the final standing pose, as a 0-velocity ghost in every
  window).
- ``none``: no clutter removal.

Cut-off: `mti_cutoff_hz` [Hz], or `mti_cutoff_mps` [m/s] converted with the carrier wavelength,
f_c = 2 v_c / lambda (the Doppler of a target at radial velocity v_c). Defaults: see `DSPConfig`.

Edge transients of the causal filter. A causal high-pass started from rest (`mti_initial="zero"`, MATLAB's
`filter`) sees every return present at the first chirp as a step switched on at t = 0: its output is the
step response, a decaying oscillation at a few Hz (the slowest pole pair decays as exp(-2 pi f_c
sin(pi / 2n) t) for order n), so the first ~1/f_c seconds show the static scene (walls, the standing body)
at their ranges and at v ~ 0 in p(v,t), fading (`settling_time_s` gives the time to fall 40 dB).
`mti_initial="steady"` (default) starts the filter in the steady state of a constant input equal to the
first chirp (scipy `sosfilt_zi` scaled by it), as if the scene before the recording had been as in the
first chirp: static returns then vanish from the first chirp on, and only what moves at t = 0 shows a
(small) start transient. The same step response appears wherever a mover stops (a body coming to rest
at a new range): the causal filter shows it there for ~1/f_c afterwards, the centred average for L/2
chirps either side, the whole-recording mean in every window.
"""
from __future__ import annotations

import numpy as np

from processing.radar.waveform import C0
from processing.errors import InputError

MA_CUTOFF_PRODUCT = 0.7553772304823293  # f_c L / PRF where sinc(f L / PRF) = 1 - 1/sqrt(2) (-3 dB of 1 - sinc)


def cutoff_hz(cfg, carrier_hz: float) -> float:
    """The MTI cut-off frequency [Hz] of `cfg` (a `DSPConfig`): `mti_cutoff_hz` if set, else 2 v_c / lambda
    from `mti_cutoff_mps` with lambda = c0 / `carrier_hz`."""
    if cfg.mti_cutoff_hz is not None:
        return float(cfg.mti_cutoff_hz)
    return 2.0 * cfg.mti_cutoff_mps * carrier_hz / C0


def moving_average_length(fc_hz: float, prf_hz: float) -> int:
    """Odd length L [chirps] of the centred moving average whose subtraction has its -3 dB point at fc_hz."""
    n = MA_CUTOFF_PRODUCT * prf_hz / fc_hz
    return max(1, 2 * int(round((n - 1) / 2)) + 1)


def butterworth_sos(order: int, fc_hz: float, prf_hz: float) -> np.ndarray:
    """Second-order sections of the Butterworth high-pass (-3 dB at fc_hz) at sample rate prf_hz."""
    from scipy.signal import butter  # only here: scipy.signal costs ~0.3 s to import, the default MTI needs none

    return butter(order, fc_hz, btype="highpass", fs=prf_hz, output="sos")


def _check_cutoff(fc: float, prf: float) -> None:
    if not 0 < fc < prf / 2:
        raise InputError(f"MTI cut-off {fc:g} Hz must lie between 0 and the slow-time Nyquist frequency "
                         f"PRF/2 = {prf / 2:g} Hz (set mti_cutoff_hz or mti_cutoff_mps lower)")


def mti_filter(x: np.ndarray, prf_hz: float, carrier_hz: float, cfg) -> np.ndarray:
    """Slow-time clutter filter of `x` [C, ...] (axis 0 = chirps, any trailing axes, e.g. range bins).

    Args:
        x: complex slow-time samples, one per chirp.
        prf_hz: chirp repetition frequency 1 / PRI [Hz].
        carrier_hz: carrier for converting `mti_cutoff_mps` to Hz (the waveform's centre frequency).
        cfg: `DSPConfig` (static_removal, mti_cutoff_hz/mps, mti_order, mti_zero_phase, mti_initial).

    Returns:
        Filtered array of x's shape (complex128, or x itself for ``none``).
    """
    kind = cfg.static_removal
    if kind == "none" or x.shape[0] == 0:
        return x
    if kind == "mean":
        return x - x.mean(axis=0, keepdims=True)
    fc = cutoff_hz(cfg, carrier_hz)
    _check_cutoff(fc, prf_hz)
    if kind == "moving_average":
        return _subtract_moving_average(np.asarray(x), moving_average_length(fc, prf_hz) // 2)
    x = np.asarray(x, dtype=np.complex128)
    from scipy.signal import sosfilt, sosfilt_zi, sosfiltfilt

    sos = butterworth_sos(cfg.mti_order, fc, prf_hz)
    if cfg.mti_zero_phase:
        pad = min(3 * (2 * sos.shape[0] + 1), x.shape[0] - 1)  # scipy's default, shortened for short records
        return sosfiltfilt(sos, x, axis=0, padlen=pad) if pad > 0 else x - x.mean(axis=0, keepdims=True)
    if cfg.mti_initial == "zero":
        return sosfilt(sos, x, axis=0)
    zi = sosfilt_zi(sos).reshape((sos.shape[0], 2) + (1,) * (x.ndim - 1)) * x[0][None, None]
    return sosfilt(sos, x, axis=0, zi=zi)[0]


def _subtract_moving_average(x: np.ndarray, half: int) -> np.ndarray:
    """x [C, ...] minus its centred moving average over [n - half, n + half] clipped to the record (divided by
    the number of chirps in it), from a running sum, in complex128. Interior rows as one slice difference, in
    place, x cast element by element: fewer [C, ...] temporaries (each MB-sized one costs page faults) than
    converting x and gathering both window ends for every row (same arithmetic, same bytes)."""
    n_c = x.shape[0]
    c = np.empty((n_c + 1,) + x.shape[1:], np.complex128)
    c[0] = 0
    np.cumsum(x, axis=0, dtype=np.complex128, out=c[1:])
    out = np.empty(x.shape, np.complex128)
    a, b = min(half, n_c), max(n_c - half - 1, min(half, n_c))  # rows a..b-1 see the whole window
    if b > a:
        mid = out[a:b]
        np.subtract(c[a + half + 1:b + half + 1], c[a - half:b - half], out=mid)
        mid /= 2 * half + 1
        np.subtract(x[a:b], mid, out=mid)
    edge = np.r_[0:a, b:n_c]
    if edge.size:
        lo, hi = np.maximum(edge - half, 0), np.minimum(edge + half + 1, n_c)
        count = (hi - lo).reshape((-1,) + (1,) * (x.ndim - 1))
        out[edge] = x[edge] - (c[hi] - c[lo]) / count
    return out


def settling_time_s(cfg, prf_hz: float, carrier_hz: float, level_db: float = -40.0) -> float:
    """Time [s] after a step (a return appearing, or a mover stopping) until the MTI output stays below
    `level_db` of the step: ``butterworth`` causal from its step response, zero-phase on each side of the
    step; ``moving_average`` half its length; ``mean`` infinite; ``none`` 0."""
    kind = cfg.static_removal
    if kind == "none":
        return 0.0
    if kind == "mean":
        return float("inf")
    fc = cutoff_hz(cfg, carrier_hz)
    _check_cutoff(fc, prf_hz)
    if kind == "moving_average":
        return (moving_average_length(fc, prf_hz) // 2 + 1) / prf_hz
    from scipy.signal import sosfilt

    sos = butterworth_sos(cfg.mti_order, fc, prf_hz)
    n = int(np.ceil(200 * prf_hz / fc))  # 200 cut-off periods: far beyond any Butterworth's settling
    step = sosfilt(sos, np.ones(n))
    if cfg.mti_zero_phase:
        step = sosfilt(sos, step[::-1])[::-1]
    above = np.flatnonzero(np.abs(step) > 10 ** (level_db / 20))
    return float((above[-1] + 1) / prf_hz) if above.size else 0.0

