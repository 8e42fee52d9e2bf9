"""Signal-layer augmentation on raw IQ (before DSP): receiver noise at a given SNR and static clutter.

Definitions (per link, on the IQ matrix [C chirps, N samples]):

* signal power P_s = mean(|iq|^2) over all chirps and samples of the noiseless, clutter-free IQ;
* SNR [dB] = 10 log10(P_s / P_n), with complex white Gaussian noise of power P_n (P_n / 2 per I and Q),
  i.e. the SNR of one raw ADC sample, before the range and Doppler FFT gains (64 x 128 at the seed's
  settings, +39 dB, lift the signature well above the raw-sample SNR);
* clutter-to-signal ratio CSR [dB] = 10 log10(P_c / P_s), P_c the total power of the static returns.

Static returns are fixed point targets at ranges r_k (delay tau_k = 2 r_k / c): the same beat tone in
every chirp, with the synthesiser's phase model exp(j (2 pi gamma tau m / fs + 2 pi f_start tau)). The DSP's
static-return removal (mean over slow time) cancels them exactly; they matter with ``static_removal: none``
or as a test of that removal.
"""
from __future__ import annotations

import numpy as np

from processing.radar.waveform import C0, Waveform


def signal_power(iq: np.ndarray) -> float:
    """Mean power mean(|iq|^2) of an IQ array (arbitrary units)."""
    return float(np.mean(np.abs(iq.astype(np.complex128)) ** 2)) if iq.size else 0.0


def add_noise(iq: np.ndarray, snr_db: float, rng: np.random.Generator, reference_power: float | None = None
              ) -> np.ndarray:
    """`iq` plus complex white Gaussian noise at `snr_db` relative to `reference_power` (default: the
    IQ's own mean power). Returns complex64. A signal of zero power gets no noise (SNR undefined)."""
    p_s = signal_power(iq) if reference_power is None else float(reference_power)
    if p_s <= 0:
        return iq.astype(np.complex64)
    p_n = p_s / 10.0 ** (snr_db / 10.0)
    noise = rng.standard_normal(iq.shape + (2,), dtype=np.float32).view(np.complex64)[..., 0]
    return (iq + np.float32(np.sqrt(p_n / 2.0)) * noise).astype(np.complex64)


def static_clutter(wf: Waveform, n_chirps: int, ranges_m: np.ndarray, amplitudes: np.ndarray) -> np.ndarray:
    """IQ [n_chirps, N] (complex128) of static point returns at `ranges_m` [K] (m) with complex
    `amplitudes` [K]; identical in every chirp."""
    tau = 2.0 * np.asarray(ranges_m, float) / C0
    m = np.arange(wf.samples_per_chirp) / wf.fs
    tones = np.exp(1j * 2 * np.pi * (wf.slope * np.outer(tau, m) + np.mod(wf.start_hz * tau, 1.0)[:, None]))
    row = np.asarray(amplitudes, complex) @ tones
    return np.broadcast_to(row, (n_chirps, row.size)).copy()


def add_clutter(iq: np.ndarray, wf: Waveform, rng: np.random.Generator, n_scatterers: int, csr_db: float,
                range_m: tuple[float, float], reference_power: float | None = None
                ) -> tuple[np.ndarray, dict]:
    """`iq` plus `n_scatterers` static returns, uniformly placed in `range_m` (m), Rayleigh amplitudes with
    uniform phases, scaled so their total power is `csr_db` above the signal power.

    Returns (complex64 IQ, {"ranges_m", "power_db"} of the drawn returns).
    """
    p_s = signal_power(iq) if reference_power is None else float(reference_power)
    r = rng.uniform(range_m[0], range_m[1], n_scatterers)
    a = (rng.standard_normal(n_scatterers) + 1j * rng.standard_normal(n_scatterers)) / np.sqrt(2)
    c = static_clutter(wf, iq.shape[0], r, a)
    p_c = signal_power(c)
    if p_s > 0 and p_c > 0:
        c *= np.sqrt(p_s * 10.0 ** (csr_db / 10.0) / p_c)
    else:
        c[:] = 0
    info = {"ranges_m": [float(x) for x in r], "power_db": [float(x) for x in 20 * np.log10(np.abs(a) + 1e-300)]}
    return (iq + c).astype(np.complex64), info
