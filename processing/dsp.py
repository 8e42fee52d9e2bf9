"""Radar DSP: range FFT, static-return removal, micro-Doppler signature, p(v,t), mean velocity, range
distribution (seed eqs. 5-10).

Sign convention: positive radial velocity means the scatterer approaches the radar (its range, half
the total path for bistatic links, decreases), i.e. a positive Doppler shift, as in the seed's figures.

Empty windows: a time bin whose total power is zero (or below `empty_floor` times the strongest bin of
the recording, i.e. numerically no signal) gets p(v,t) = 0 for every v and mean velocity 0; its range
distribution is likewise 0. Nothing is ever NaN. `Signature.valid` marks the bins that had signal.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from pydantic import BaseModel, ConfigDict, Field
from scipy.signal import get_window

from processing.waveform import C0, Waveform


class DSPConfig(BaseModel):
    """Signal-processing settings. Defaults follow the seed (64-chirp rectangular window, coherent sum)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    window_chirps: int = Field(64, ge=4, description="slow-time window W of the micro-Doppler STFT [chirps]")
    hop_chirps: int = Field(32, ge=1, description="hop between successive windows [chirps]")
    doppler_window: str = Field("boxcar", description="slow-time taper (scipy name); the seed's is boxcar")
    range_window: str = Field("boxcar", description="fast-time taper before the range FFT")
    range_sum: Literal["coherent", "incoherent"] = Field(
        "coherent", description="coherent: the seed's eq. 6 (sum range bins, then FFT); incoherent: "
        "sum of per-bin spectrograms")
    static_removal: Literal["mean", "none"] = Field(
        "mean", description="subtract each range bin's mean over the recording (removes static returns)")
    min_range_m: float = Field(0.0, ge=0, description="lowest range bin used for p(v,t) [m]")
    max_range_m: float | None = Field(None, gt=0, description="highest range used [m]; default: waveform's")
    empty_floor: float = Field(1e-12, ge=0, description="bins below this fraction of the peak are empty")
    mean_velocity: Literal["unwrapped", "seed"] = Field(
        "unwrapped", description="seed: eq. 8 over the fixed axis [-v_max, v_max); unwrapped: eq. 8 over "
        "the Doppler ambiguity interval centred on the distribution's circular mean")
    unwrap_min_concentration: float = Field(
        0.2, ge=0, le=1, description="circular resultant length below which 'unwrapped' falls back to 'seed'")


@dataclass
class Signature:
    """Radar signatures of one link.

    Attributes:
        time: window centre times [T] in seconds.
        velocity: radial velocity axis [V] in m/s (ascending; positive = approaching).
        p_vt: velocity distribution p(v, t) [V, T] (eq. 7), each column sums to 1 (or 0 if empty).
        mean_velocity: mean radial velocity [T] in m/s (eq. 8).
        range: range axis [R] in metres (bistatic: half the total path).
        range_distribution: p'(r, t) [R, T] (eq. 10), columns sum to 1 (or 0 if empty).
        valid: [T] bool, True where the window carried signal.
        power: [T] total power of the window (arbitrary units, before normalisation).
    """

    time: np.ndarray
    velocity: np.ndarray
    p_vt: np.ndarray
    mean_velocity: np.ndarray
    range: np.ndarray
    range_distribution: np.ndarray
    valid: np.ndarray
    power: np.ndarray = field(default_factory=lambda: np.zeros(0))


def range_profiles(iq: np.ndarray, wf: Waveform, cfg: DSPConfig = DSPConfig()) -> tuple[np.ndarray, np.ndarray]:
    """Range FFT of raw IQ [C, N] (eq. 5): (profiles [C, N] complex64, range axis [N] in m).

    The IQ is complex, so all N bins are positive beat frequencies k fs / N, i.e. ranges k * dR.
    """
    n = wf.samples_per_chirp
    if iq.shape[-1] != n:
        raise ValueError(f"IQ has {iq.shape[-1]} samples per chirp, waveform says {n}")
    taper = get_window(cfg.range_window, n, fftbins=True).astype(np.float32)
    prof = np.fft.fft(iq * taper, axis=-1).astype(np.complex64) / np.float32(taper.sum())
    return prof, np.arange(n) * wf.range_resolution


def remove_static(profiles: np.ndarray, cfg: DSPConfig = DSPConfig()) -> np.ndarray:
    """Range profiles with each bin's slow-time mean removed (static walls and furniture vanish)."""
    if cfg.static_removal == "none" or profiles.shape[0] == 0:
        return profiles
    return profiles - profiles.mean(axis=0, keepdims=True)


def coherent_range_sum(iq: np.ndarray, wf: Waveform, cfg: DSPConfig, sel: np.ndarray) -> tuple[np.ndarray, float]:
    """Seed eq. 6's inner integral over beat frequency: the selected band of range bins summed coherently.

    A plain DFT is periodic in fast time, so summing a band of its bins weights both the start *and*
    the end of the chirp, whose carrier phases differ by 2 pi B tau: the sum then beats as the target
    moves and biases the Doppler. The seed's integral runs over a non-periodic chirp, which the
    2N-point zero-padded DFT reproduces; the band sum collapses to one weight vector over fast time.

    Returns (slow-time signal [C], effective carrier [Hz]): the weights sit near the start of the chirp,
    so the Doppler they see is that of the instantaneous frequency there, f0 - B/2 + gamma * <t'>,
    not the centre frequency (a 0.5 % velocity-scale difference at the seed's settings).
    """
    n = wf.samples_per_chirp
    k = np.flatnonzero(sel) * 2  # bins of the N-point FFT sit at even bins of the 2N-point one
    k = np.arange(k.min(), k.max() + 1)
    taper = get_window(cfg.range_window, n, fftbins=True)
    h = np.exp(-2j * np.pi * np.outer(np.arange(n), k) / (2 * n)).sum(axis=1) * taper / taper.sum()
    x = iq.astype(np.complex128) @ h
    w2 = np.abs(h) ** 2
    f_eff = wf.start_hz + wf.slope * float((np.arange(n) / wf.fs) @ w2 / w2.sum())
    return (x - x.mean() if cfg.static_removal == "mean" and x.size else x), f_eff


def mean_velocity(p_vt: np.ndarray, velocity: np.ndarray, v_max: float, cfg: DSPConfig = DSPConfig()) -> np.ndarray:
    """Mean radial velocity [T] in m/s of p(v,t) [V, T] on the axis `velocity` [V] (seed eq. 8).

    The sampled Doppler spectrum is periodic in v with period 2 v_max, so eq. 8's integral over all v
    has to pick one period. 'seed' takes [-v_max, v_max); 'unwrapped' takes the period centred on the
    distribution's circular mean, which is the same for any signature away from +-v_max but removes the
    bias that the rectangular window's sidelobes, wrapping round the band edge, give a fast target.
    """
    mean = velocity @ p_vt
    if cfg.mean_velocity == "seed" or p_vt.size == 0:
        return mean
    z = np.exp(1j * np.pi * velocity / v_max) @ p_vt
    centre = np.angle(z) * v_max / np.pi
    use = np.abs(z) >= cfg.unwrap_min_concentration
    v = centre[None, :] + np.mod(velocity[:, None] - centre[None, :] + v_max, 2 * v_max) - v_max
    return np.where(use, (v * p_vt).sum(axis=0), mean)


def _normalise(power: np.ndarray, floor: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column-normalised distribution of power [X, T], with empty columns set to 0 (never NaN)."""
    total = power.sum(axis=0)
    peak = total.max() if total.size else 0.0
    valid = total > max(floor * peak, np.finfo(np.float64).tiny)
    dist = np.zeros_like(power)
    dist[:, valid] = power[:, valid] / total[valid]
    return dist, valid, total


def signatures(iq: np.ndarray, wf: Waveform, cfg: DSPConfig = DSPConfig(), t0: float = 0.0) -> Signature:
    """All signatures of one link from raw IQ [C, N] whose first chirp starts at t0 seconds.

    Returns a `Signature` with p(v,t) over `cfg.window_chirps`-chirp windows every `cfg.hop_chirps`
    chirps (seed eqs. 6-8) and the range distribution over the same windows (eqs. 9-10; the power is
    averaged over each window, i.e. eq. 9 with the magnitude taken per Doppler bin, by Parseval).
    """
    w, hop = cfg.window_chirps, cfg.hop_chirps
    prof, rng = range_profiles(iq, wf, cfg)
    prof = remove_static(prof, cfg)
    r_max = wf.max_range_m if cfg.max_range_m is None else cfg.max_range_m
    sel = (rng >= cfg.min_range_m) & (rng <= r_max + 0.5 * wf.range_resolution)
    if not sel.any():
        raise ValueError(f"no range bin between {cfg.min_range_m} and {r_max} m (bin spacing "
                         f"{wf.range_resolution:.3f} m)")
    n_win = (prof.shape[0] - w) // hop + 1 if prof.shape[0] >= w else 0
    starts = np.arange(n_win) * hop
    time = t0 + (starts + w / 2) * wf.pri_s

    taper = get_window(cfg.doppler_window, w, fftbins=True)
    taper = taper / np.sqrt((taper ** 2).sum())
    nb = int(sel.sum())
    if cfg.range_sum == "coherent":
        x, f_eff = coherent_range_sum(iq, wf, cfg, sel)
        win = sliding_window_view(x, w)[::hop] if n_win else np.zeros((0, w), complex)
        power = np.abs(np.fft.fft(win * taper, axis=1)) ** 2  # [T, W]
    else:
        f_eff = wf.carrier_hz  # a range bin's phase refers to mid-chirp, i.e. the centre frequency
        win = sliding_window_view(prof[:, sel], w, axis=0)[::hop] if n_win else np.zeros((0, nb, w), complex)
        power = (np.abs(np.fft.fft(win * taper, axis=2)) ** 2).sum(axis=1)
    # Phase exp(+j 2 pi f0 tau) falls as an approaching target's delay shrinks, so its Doppler
    # frequency is negative: v = -f lambda / 2. Reversing the shifted FFT axis makes v ascending.
    fd = np.fft.fftshift(np.fft.fftfreq(w, wf.pri_s))
    velocity = (-fd * C0 / (2 * f_eff))[::-1]
    spec = np.fft.fftshift(power, axes=1)[:, ::-1].T  # [V, T]
    p_vt, valid, total = _normalise(spec.astype(np.float64), cfg.empty_floor)
    mean_v = mean_velocity(p_vt, velocity, (velocity[1] - velocity[0]) * w / 2, cfg)

    rsel = rng <= r_max + 0.5 * wf.range_resolution
    rpow = np.abs(prof[:, rsel]) ** 2
    rwin = sliding_window_view(rpow, w, axis=0)[::hop].mean(axis=2) if n_win else np.zeros((0, rsel.sum()))
    rdist, _, _ = _normalise(rwin.T.astype(np.float64), cfg.empty_floor)
    return Signature(time=time, velocity=velocity, p_vt=p_vt, mean_velocity=mean_v, range=rng[rsel],
                     range_distribution=rdist, valid=valid, power=total)
