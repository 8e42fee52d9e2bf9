"""The fast-time model: raw IQ [chirps, samples] -> range profiles and the coherent range sum of each chirp.

The neutral home of what synthesis and DSP share, below both (so data flows radar -> synthesis -> dsp and
neither calls the other): the synthesisers form a chirp's projection straight from paths
(`processing.synthesis.projection`), the DSP's fast-time stage applies it to raw IQ
(`processing.dsp.signatures.signatures`), and the backends read the used range (`max_range`). Functions
take the DSP settings (`processing.dsp.config.DSPConfig`) as `cfg` and read only its fast-time fields
(range_window, range_bins, min_range_m, max_range_m, range_sum, coherent_offset_samples).

Both are linear maps of each chirp's N samples, given here as weight matrices so that a synthesiser can
produce them straight from paths, without raw IQ: for a path of gain a and delay tau (short-time stationary
over the chirp, as in `processing.synthesis.exact`), chirp c contributes a * `path_response(W, tau, wf)` to
`iq[c] @ W`. A `Projection` built that way goes through `processing.dsp.signatures.signatures_from_projection`
exactly like one from `project(iq, ...)`.

Range bins. Bin k of the N-point range FFT is the beat frequency k fs / N, i.e. range k dR (bistatic: half
the total path). The used bins run from 0 to the largest range `DSPConfig.max_range_m` (default: the
waveform's `max_range_m`); with `range_bins="positive_half"` only bins below N/2 are kept (the Glasgow
script's fftshifted positive half, for complex ADCs whose anti-alias filter cuts at fs/2).

Coherent range sum (seed eq. 6). The inner integral of eq. 6 sums the beat spectrum over the band of range
bins [min_range_m, max range]; over the chirp this collapses to one weight vector h over fast time. A
plain DFT is periodic in fast time, so the band sum would weight both ends of the chirp (whose carrier
phases differ by 2 pi B tau); the seed's integral runs over a non-periodic chirp, which the 2N-point
zero-padded DFT reproduces. The weights form a band-limited pulse of about R_unamb / max_range samples at
the start of the chirp (91 % of the weight on the first 8 of 128 samples at the seed's settings), so the
Doppler they see is that of the instantaneous frequency there, f0 - B/2 + gamma <t'>: the effective
carrier `coherent_weights` returns (0.4-0.5 % below the centre frequency at the seed's settings, ~3 % at
5.8 GHz / 400 MHz). `DSPConfig.coherent_offset_samples` = m0 (default N // 16) skips the first m0 samples
after the chirp reset, where real sawtooth hardware has its synthesiser's settling transient: eq. 6 is
then evaluated on the chirp from sample m0 on (N - m0 samples, 2(N - m0)-point DFT, the same band in
metres), the weights are exactly 0 on the skipped samples, the pulse starts at m0 and the effective
carrier moves up by about gamma m0 / fs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.radar.waveform import Waveform
from processing.windows import get_window
from processing.errors import InputError


@dataclass
class Projection:
    """Fast-time projection of one link: everything the slow-time stage needs.

    Attributes:
        profiles: range profiles [C, R] (complex) of the used range bins, before clutter removal.
        range: range axis [R] in metres (bistatic: half the total path).
        waveform: the waveform (PRI, carrier) of the recording.
        coherent: slow-time signal [C] of the coherent range sum (eq. 6), or None when
            `DSPConfig.range_sum` is not "coherent".
        coherent_carrier_hz: carrier [Hz] the coherent sum's Doppler refers to (see module docstring).
        t0: start time [s] of the first chirp.
    """

    profiles: np.ndarray
    range: np.ndarray
    waveform: Waveform
    coherent: np.ndarray | None = None
    coherent_carrier_hz: float = 0.0
    t0: float = 0.0


def max_range(wf: Waveform, cfg) -> float:
    """Largest used range [m]: `cfg.max_range_m` or the waveform's `max_range_m`."""
    return wf.max_range_m if cfg.max_range_m is None else cfg.max_range_m


def range_bins(wf: Waveform, cfg) -> np.ndarray:
    """Indices of the used range bins (0 .. the bin of the largest range; below N/2 for "positive_half")."""
    n = wf.samples_per_chirp
    k = np.arange(n)
    used = k * wf.range_resolution <= max_range(wf, cfg) + 0.5 * wf.range_resolution
    if cfg.range_bins == "positive_half":
        used &= k < n // 2
    return np.flatnonzero(used)


def doppler_band(rng: np.ndarray, wf: Waveform, cfg) -> np.ndarray:
    """Boolean mask over the used range axis `rng` [m] of the bins summed for p(v,t): those whose centre is
    at most half a bin below `min_range_m` (both ends of the band take the bin containing the limit)."""
    band = rng >= cfg.min_range_m - 0.5 * wf.range_resolution
    if not band.any():
        raise InputError(f"no range bin between {cfg.min_range_m} and {max_range(wf, cfg)} m (bin spacing "
                         f"{wf.range_resolution:.3f} m)")
    return band


def range_weights(wf: Waveform, cfg) -> tuple[np.ndarray, np.ndarray]:
    """(W [N, R] complex128, range [R] m): the range FFT (eq. 5, `range_window` taper, amplitude-normalised)
    restricted to the used bins, so that profiles = iq @ W."""
    n = wf.samples_per_chirp
    k = range_bins(wf, cfg)
    taper = get_window(cfg.range_window, n, fftbins=True)
    w = np.exp(-2j * np.pi * np.outer(np.arange(n), k) / n) * (taper / taper.sum())[:, None]
    return w, k * wf.range_resolution


def coherent_offset(wf: Waveform, cfg) -> int:
    """Fast-time samples m0 skipped by the coherent sum: `cfg.coherent_offset_samples`, default N // 16."""
    m0 = cfg.coherent_offset_samples
    return wf.samples_per_chirp // 16 if m0 is None else m0


def coherent_weights(wf: Waveform, cfg) -> tuple[np.ndarray, float]:
    """(h [N] complex128, effective carrier [Hz]) of the coherent range sum: slow-time signal = iq @ h.

    Eq. 6's band sum over [min_range_m, max range] evaluated on the chirp from sample
    m0 = `coherent_offset_samples` on (see the module docstring); h is 0 on samples 0..m0-1.
    """
    n = wf.samples_per_chirp
    m0 = coherent_offset(wf, cfg)
    if not 0 <= m0 <= n - 8:
        raise InputError(f"coherent_offset_samples = {m0} leaves fewer than 8 of the {n} samples per chirp")
    k_used = range_bins(wf, cfg)
    band = k_used[doppler_band(k_used * wf.range_resolution, wf, cfg)]
    n_seg = n - m0
    # band edges in beat frequency (units of fs / N) mapped onto the 2 n_seg-point grid of the segment
    lo = int(np.ceil(band.min() * 2 * n_seg / n - 1e-9))
    hi = int(np.floor(band.max() * 2 * n_seg / n + 1e-9))
    k2 = np.arange(lo, max(hi, lo) + 1)
    m = np.arange(n_seg)
    taper = get_window(cfg.range_window, n_seg, fftbins=True)
    seg = np.exp(-2j * np.pi * np.outer(m, k2) / (2 * n_seg)).sum(axis=1) * taper / taper.sum()
    h = np.zeros(n, np.complex128)
    h[m0:] = seg
    w2 = np.abs(h) ** 2
    f_eff = wf.start_hz + wf.slope * float(np.add.reduce(np.arange(n) / wf.fs * w2) / np.add.reduce(w2))
    return h, f_eff


def path_response(weights: np.ndarray, tau, wf: Waveform) -> np.ndarray:
    """Projection [..., K] of one chirp of a unit-gain path with delay `tau` [s] (array [...]) through
    `weights` [N, K] or [N]: exp(j 2 pi f_s tau) sum_m W[m] exp(j 2 pi gamma tau m / fs) (seed eq. 3)."""
    tau = np.asarray(tau, dtype=np.float64)[..., None]
    m = np.arange(wf.samples_per_chirp)
    tone = np.exp(2j * np.pi * (wf.start_hz * tau + wf.slope * tau * m / wf.fs))  # [..., N]
    return tone @ weights


_ROWS = 256  # chirps per block of `project`: its temporaries stay small (fresh MB-sized ones cost page faults)


def _rows_dot(iq: np.ndarray, h: np.ndarray) -> np.ndarray:
    """iq [C, N] @ h [N] in complex128 as a fixed-order sum per row (einsum over the contiguous axis, no
    buffering: same dtypes), so a row's value depends on that row alone: a BLAS matrix-vector product may
    split its sums by thread count, and the same seed must give the same bytes for any OPENBLAS_NUM_THREADS.
    Samples where h is exactly 0 (the coherent sum's skipped chirp start) are left out."""
    nz = np.flatnonzero(h)
    lo, hi = (int(nz[0]), int(nz[-1]) + 1) if nz.size else (0, 0)
    x = np.asarray(iq[:, lo:hi], dtype=np.complex128)
    return np.einsum("ij,j->i", x, np.ascontiguousarray(h[lo:hi], dtype=np.complex128))


def projector(wf: Waveform, cfg):
    """`project` with its weights made once: a callable (IQ [C, N], t0 [s] = 0) -> `Projection`, for projecting
    a recording chunk by chunk (row by row, so the chunks' projections are the whole IQ's, bitwise)."""
    # scipy's FFT of [C, 128] complex64 takes ~1/10 of numpy's (numpy 2.4): it computes in float32, whose rms
    # error, ~1e-8 of the row's largest bin (-160 dB), is of the order of the complex64 IQ's own rounding
    import scipy.fft

    n = wf.samples_per_chirp
    k = range_bins(wf, cfg)
    rng = k * wf.range_resolution
    doppler_band(rng, wf, cfg)
    taper = get_window(cfg.range_window, n, fftbins=True).astype(np.float32)
    scale = np.float32(taper.sum())
    plain = bool(np.all(taper == 1))  # boxcar: multiplying by 1 changes no bit
    cols = slice(int(k[0]), int(k[-1]) + 1) if k.size and np.all(np.diff(k) == 1) else k
    h, f_eff = coherent_weights(wf, cfg) if cfg.range_sum == "coherent" else (None, wf.carrier_hz)

    def apply(iq: np.ndarray, t0: float = 0.0) -> Projection:
        if iq.ndim != 2 or iq.shape[-1] != n:
            raise InputError(f"IQ must be [chirps, {n}] (the waveform's samples per chirp), got {iq.shape}")
        prof = np.empty((iq.shape[0], k.size), np.complex64)
        coh = None if h is None else np.empty(iq.shape[0], np.complex128)
        # the FFT is the same linear map as range_weights (to float rounding) and N log N instead of N R
        for a in range(0, iq.shape[0], _ROWS):
            x = iq[a:a + _ROWS]
            prof[a:a + _ROWS] = scipy.fft.fft(x if plain else x * taper, axis=-1)[:, cols] / scale
            if coh is not None and h is not None:  # coh exists exactly when h does
                coh[a:a + _ROWS] = _rows_dot(x, h)
        return Projection(profiles=prof, range=rng, waveform=wf, coherent=coh, coherent_carrier_hz=f_eff, t0=t0)

    return apply


def project(iq: np.ndarray, wf: Waveform, cfg, t0: float = 0.0) -> Projection:
    """Fast-time stage: raw IQ [C, N] whose first chirp starts at t0 [s] -> `Projection`."""
    n = wf.samples_per_chirp
    if iq.ndim != 2 or iq.shape[-1] != n:
        raise InputError(f"IQ must be [chirps, {n}] (the waveform's samples per chirp), got {iq.shape}")
    return projector(wf, cfg)(iq, t0)
