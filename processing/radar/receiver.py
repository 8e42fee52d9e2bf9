"""Absolute receiver noise from the radar equation, transmit power and the receiver chain.

Units. The synthesiser's IQ is in units of the transmit power: with |a|^2 = P_r / P_t per path (antenna
gains included, see `processing.radar.antenna`), a tone of IQ amplitude A means P_r = |A|^2 P_t. `scale_to_receiver`
multiplies by sqrt(P_t [W] * G_chain); afterwards |iq|^2 is a power in watts: the received power at the
antenna port times the chain gain (`chain_gain_db`, antenna port -> ADC output; 0 dB, the default, keeps
the IQ referred to the receiver input). Volts across a reference resistance R are iq * sqrt(R).

Thermal noise. Referred to the receiver input, the noise power spectral density is
N0 = k (T_a + (F - 1) T0), T0 = 290 K, T_a the antenna (scene) temperature, F the noise factor
(10^(NF/10), defined at T0); for T_a = T0 this is the familiar k T0 F. Quadrature (complex) sampling at
rate fs sees a complex baseband band of width fs ([-fs/2, fs/2): unlike real sampling, a complex signal
needs no mirror half, so the Nyquist band of complex sampling is fs, not fs/2), and the anti-alias
filter passes exactly that band in this model. The complex envelope carries the same noise density N0
(its power N0 B equals that of the real band-pass noise of bandwidth B), so each complex sample has

    P_n = k (T_a + (F - 1) T0) fs G_chain     [W]   (`noise_power_per_sample`),

white from sample to sample, circular complex Gaussian (P_n / 2 in I and in Q). A real kit's filter may
be narrower than fs; the noise then is coloured but the per-bin level inside the pass band is the same.

After the FFTs (`processing.dsp.signatures` normalisations): the range FFT divides by sum(w) of the fast-time taper w,
so a range bin holds noise P_n sum(w^2) / sum(w)^2 (= P_n / N for the rectangular window) while an on-bin
tone keeps its power |A|^2: an SNR gain of sum(w)^2 / sum(w^2) (= N). The Doppler FFT uses a taper u of
unit energy (sum(u^2) = 1): a Doppler bin keeps the range bin's noise and a constant-velocity on-bin
target gains sum(u)^2 (= W chirps for the rectangular window). Both together: SNR x N W (+39.1 dB at
N = 128, W = 64); see `range_bin_noise` and `processing_gain_db`.

Transmitter leakage (optional, off by default): a static return at range `range_m` with power
`coupling_db` relative to P_t, whose phase jitters from chirp to chirp by the residual (after dechirping)
phase noise of the oscillator: white phase phi_c with variance L * PRF, so each slow-time sideband has
density L [dBc/Hz] relative to the leakage carrier. Static-return removal cancels the carrier; the jitter
leaves a floor of L * PRF / W relative to the leakage (per Doppler bin) in the leakage's range bin and its
range-FFT side lobes. `residual_phase_noise_dbc_hz` is the level after range correlation (oscillator phase
noise times |2 sin(pi f tau)|^2), a documented free parameter, not a data-sheet value.

Randomness. `receive` / `receiver_noise` draw noise keyed by absolute chirp index (blocks of
NOISE_BLOCK_CHIRPS chirps, each from its own SeedSequence(seed, spawn_key=(block, stream))), so any chunking,
in any order, gives the same bytes as one call. Each complex sample is made from one 64-bit word of the
block's PCG64 stream (`gaussian_from_words`, Box-Muller). `add_receiver_noise(iq, cfg, fs, rng)` is the simple
sequential form: chunks fed in order to one dedicated Generator equal one call on the whole array.
"""
from __future__ import annotations

import math
import operator
from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from processing.radar.propagation import received_power_ratio
from processing.radar.antenna import AntennaPattern, GaussianBeam, YagiBeam
from processing.radar.waveform import C0, Waveform
from processing.summary import settings_repr
from processing.windows import get_window
from processing.errors import InputError
from processing.constants import K_BOLTZMANN_J_K as K_BOLTZMANN, T0_K  # J/K, K (re-exported names)

NOISE_BLOCK_CHIRPS = 256  # part of the reproducibility contract: changing it changes every noise realisation


class LeakageConfig(BaseModel):
    """Transmitter-to-receiver leakage with residual phase noise (see the module docstring)."""

    __repr__ = settings_repr  # the fields set away from their defaults

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    coupling_db: float = Field(-40.0, ge=-150.0, le=0.0, description="leakage power / transmit power [dB]; "
                               "<= 0 (passive coupling); horn pairs a few cm apart: about -30 to -60 dB")
    range_m: float = Field(0.05, ge=0.0, le=100.0, description="range equivalent c tau / 2 of the leakage "
                           "path [m] (antenna spacing plus cables)")
    residual_phase_noise_dbc_hz: float = Field(-110.0, ge=-200.0, le=-40.0, description="slow-time sideband "
                                               "density after dechirping [dBc/Hz]; > -40 would be no radar")


class ReceiverConfig(BaseModel):
    """Transmit power and receiver noise of one radar. Values SI except the logarithmic ones."""

    __repr__ = settings_repr  # the fields set away from their defaults

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    transmit_power_dbm: float = Field(ge=-40.0, le=40.0, description="power into the transmit antenna "
                                      "[dBm]; -40..40 (below: no usable radar; above 10 W: not a room sensor)")
    noise_figure_db: float = Field(ge=0.0, le=30.0, description="receiver noise figure at T0 = 290 K [dB]; "
                                   ">= 0 because F >= 1; > 30 dB is a broken receiver")
    antenna_temperature_k: float = Field(290.0, gt=0.0, le=5000.0, description="noise temperature the "
                                         "antenna sees [K]; a room is ~290 K")
    chain_gain_db: float = Field(0.0, ge=-60.0, le=150.0, description="power gain antenna port -> ADC output "
                                 "[dB]; 0 keeps the IQ referred to the receiver input")
    leakage: LeakageConfig | None = Field(None, description="optional Tx->Rx leakage with phase noise")


class RadarHardware(BaseModel):
    """A radar kit: its receiver and the pattern shared by its transmit and receive antennas."""

    __repr__ = settings_repr  # the fields set away from their defaults

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    receiver: ReceiverConfig
    antenna: AntennaPattern
    source: str = ""


def transmit_power_w(cfg: ReceiverConfig) -> float:
    """Transmit power P_t [W]."""
    return 10.0 ** ((cfg.transmit_power_dbm - 30.0) / 10.0)


def noise_psd_w_per_hz(cfg: ReceiverConfig) -> float:
    """Input-referred noise density N0 = k (T_a + (F - 1) T0) [W/Hz]."""
    f = 10.0 ** (cfg.noise_figure_db / 10.0)
    return K_BOLTZMANN * (cfg.antenna_temperature_k + (f - 1.0) * T0_K)


def noise_power_per_sample(cfg: ReceiverConfig, fs: float) -> float:
    """Noise power of one complex ADC sample, N0 fs G_chain [W] (the scaled IQ's unit), fs in Hz."""
    if not (fs > 0 and math.isfinite(fs)):
        raise InputError(f"sampling rate fs must be a positive finite number of Hz, got {fs!r}")
    return noise_psd_w_per_hz(cfg) * fs * 10.0 ** (cfg.chain_gain_db / 10.0)


def scale_to_receiver(iq: np.ndarray, cfg: ReceiverConfig) -> np.ndarray:
    """IQ in units of P_t (synthesiser output) -> sqrt(W) at the ADC: times sqrt(P_t G_chain). complex64."""
    s = math.sqrt(transmit_power_w(cfg) * 10.0 ** (cfg.chain_gain_db / 10.0))
    return (np.asarray(iq) * s).astype(np.complex64)


_PHASE_BITS = 24  # low bits of a noise word: the phase; the 40 high bits: the magnitude


def gaussian_from_words(words: np.ndarray, power: float) -> np.ndarray:
    """Circular complex Gaussian samples (complex64, mean |z|^2 = `power`), one per 64-bit word of `words`
    (uint64, any shape; the result has its shape), by Box-Muller in polar form.

    The 40 high bits give u = (j + 1) 2^-40 in (0, 1] and |z|^2 = -power ln u, the 24 low bits the phase
    k 2 pi 2^-24: |z|^2 is exponential (the exact law of a circular Gaussian's power) up to u's 2^-40 steps,
    i.e. cut off at 27.7 x power (probability e^-27.7 = 1e-12 per sample), and the phase is uniform on 2^24
    angles, independent of the magnitude, so I and Q are independent N(0, power / 2). One word per sample
    and a few vectorised passes, ~4x faster than numpy's ziggurat for two normals (float32 trig: the same
    bytes for the same words on one machine and numpy build)."""
    words = np.asarray(words, dtype=np.uint64)
    bits = words >> np.uint64(_PHASE_BITS)
    u = bits.view(np.float64)  # the passes reuse two scratch arrays: fresh MB-sized ones cost page faults
    np.add(bits.view(np.int64), 1.0, out=u)  # < 2^40 + 1: exact
    u *= 2.0 ** (_PHASE_BITS - 64)
    np.log(u, out=u)
    u *= -power
    mag = u.astype(np.float32)
    np.sqrt(mag, out=mag)
    np.bitwise_and(words, np.uint64((1 << _PHASE_BITS) - 1), out=bits)
    phase = bits.view(np.int64).astype(np.float32)
    phase *= np.float32(2.0 * math.pi * 2.0 ** -_PHASE_BITS)
    out = np.empty(words.shape + (2,), np.float32)
    trig = np.cos(phase)
    np.multiply(trig, mag, out=out[..., 0])
    np.sin(phase, out=trig)
    np.multiply(trig, mag, out=out[..., 1])
    return out.view(np.complex64)[..., 0]


def _complex_gaussian(rng: np.random.Generator, shape: tuple, power: float) -> np.ndarray:
    shape = tuple(shape)
    return gaussian_from_words(rng.bit_generator.random_raw(math.prod(shape)).reshape(shape), power)


def add_receiver_noise(iq: np.ndarray, cfg: ReceiverConfig, fs: float, rng: np.random.Generator) -> np.ndarray:
    """Scaled IQ [..., N] (sqrt(W)) plus thermal noise of `noise_power_per_sample` per sample, complex64.

    Sequential form: feeding consecutive chunks to the same Generator (used for nothing else in between)
    gives the same bytes as one call on the whole array. For random access use `receive`.
    """
    iq = np.asarray(iq)
    return (iq + _complex_gaussian(rng, iq.shape, noise_power_per_sample(cfg, fs))).astype(np.complex64)


def _block_rng(seed, block: int, stream: int) -> np.random.Generator:
    try:
        entropy = [operator.index(s) for s in (seed if isinstance(seed, (Sequence, np.ndarray)) else [seed])]
    except TypeError:
        entropy = []
    if not entropy or min(entropy) < 0:
        raise InputError(f"seed must be a non-negative integer or a non-empty sequence of them, got {seed!r}")
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy, spawn_key=(block, stream))))


def _blocks(seed, stream: int, first_chirp: int, n_chirps: int):
    """(Generator of the block, first row wanted in the block, number of rows, first output row) of every
    NOISE_BLOCK_CHIRPS block holding chirps first_chirp .. first_chirp + n_chirps - 1."""
    if first_chirp < 0 or n_chirps < 0:
        raise InputError("first_chirp and n_chirps must be >= 0")
    _block_rng(seed, 0, stream)  # reject a bad seed even when no block is drawn
    end = first_chirp + n_chirps
    for b in range(first_chirp // NOISE_BLOCK_CHIRPS, (end - 1) // NOISE_BLOCK_CHIRPS + 1 if n_chirps else 0):
        lo, hi = max(first_chirp, b * NOISE_BLOCK_CHIRPS), min(end, (b + 1) * NOISE_BLOCK_CHIRPS)
        yield _block_rng(seed, b, stream), lo - b * NOISE_BLOCK_CHIRPS, hi - lo, lo - first_chirp


def _keyed(seed, stream: int, first_chirp: int, n_chirps: int, draw) -> np.ndarray:
    """Rows first_chirp .. first_chirp + n_chirps of a per-chirp random array built block by block."""
    parts = [draw(g, NOISE_BLOCK_CHIRPS)[s:s + k] for g, s, k, _ in _blocks(seed, stream, first_chirp, n_chirps)]
    return np.concatenate(parts) if parts else draw(np.random.default_rng(0), 0)


def _add_noise(out: np.ndarray, p: float, seed, first_chirp: int) -> None:
    """out [C, N] (complex64) += the keyed thermal noise (power p [W] per sample) of chirps first_chirp..,
    block by block (no [C, N] temporaries)."""
    n = out.shape[1]
    for g, s, k, o in _blocks(seed, 0, first_chirp, out.shape[0]):
        words = g.bit_generator.random_raw(NOISE_BLOCK_CHIRPS * n).reshape(NOISE_BLOCK_CHIRPS, n)
        out[o:o + k] += gaussian_from_words(words[s:s + k], p)


def receiver_noise(cfg: ReceiverConfig, fs: float, n_samples: int, seed, first_chirp: int, n_chirps: int
                   ) -> np.ndarray:
    """Thermal noise [n_chirps, n_samples] (complex64, sqrt(W)) of chirps first_chirp.. of one link.

    `seed`: an int or a sequence of ints, e.g. (simulation seed, link index); the same seed and chirp
    index always give the same noise, whatever the chunking."""
    out = np.zeros((n_chirps, n_samples), np.complex64)
    _add_noise(out, noise_power_per_sample(cfg, fs), seed, first_chirp)
    return out


def leakage_iq(cfg: ReceiverConfig, wf: Waveform, seed, first_chirp: int, n_chirps: int) -> np.ndarray:
    """The leakage return [n_chirps, N] (complex64, sqrt(W) at the ADC) of chirps first_chirp..; zeros if
    `cfg.leakage` is None. Its phase jitter is keyed by chirp index like `receiver_noise`."""
    n = wf.samples_per_chirp
    if cfg.leakage is None:
        return np.zeros((n_chirps, n), np.complex64)
    lk = cfg.leakage
    tau = 2.0 * lk.range_m / C0
    amp = math.sqrt(transmit_power_w(cfg) * 10.0 ** ((lk.coupling_db + cfg.chain_gain_db) / 10.0))
    cycles = wf.slope * tau * np.arange(n) / wf.fs + math.fmod(wf.start_hz * tau, 1.0)
    tone = amp * np.exp(1j * 2 * np.pi * cycles)
    sigma = math.sqrt(10.0 ** (lk.residual_phase_noise_dbc_hz / 10.0) / wf.pri_s)
    phi = _keyed(seed, 1, first_chirp, n_chirps, lambda g, k: sigma * g.standard_normal(k))
    return (np.exp(1j * phi)[:, None] * tone[None, :]).astype(np.complex64)


def _add_terms(out: np.ndarray, cfg: ReceiverConfig, wf: Waveform, seed, first_chirp: int) -> np.ndarray:
    """out (scaled IQ, complex64 [C, N]) += leakage (if configured) + thermal noise, in place."""
    if cfg.leakage is not None:
        out += leakage_iq(cfg, wf, seed, first_chirp, out.shape[0])
    _add_noise(out, noise_power_per_sample(cfg, wf.fs), seed, first_chirp)
    return out


def receive_inplace(iq: np.ndarray, cfg: ReceiverConfig, wf: Waveform, seed, first_chirp: int = 0) -> np.ndarray:
    """`receive` of complex64 IQ [C, N] written into `iq` itself (e.g. the synthesiser's own chunk): the same
    bytes as `receive(iq, ...)` without its copies. Returns `iq`."""
    if iq.dtype != np.complex64 or iq.ndim != 2 or iq.shape[1] != wf.samples_per_chirp:
        raise InputError(f"IQ must be complex64 [chirps, {wf.samples_per_chirp}], got {iq.dtype} {iq.shape}")
    iq *= math.sqrt(transmit_power_w(cfg) * 10.0 ** (cfg.chain_gain_db / 10.0))  # as scale_to_receiver
    return _add_terms(iq, cfg, wf, seed, first_chirp)


def receive(iq: np.ndarray, cfg: ReceiverConfig, wf: Waveform, seed, first_chirp: int = 0) -> np.ndarray:
    """What the ADC records for synthesiser IQ [C, N] (units of P_t) of chirps first_chirp..first_chirp+C-1:
    scaled to sqrt(W), plus leakage (if configured) plus thermal noise. complex64; chunk-independent."""
    iq = np.asarray(iq)
    if iq.ndim != 2 or iq.shape[1] != wf.samples_per_chirp:
        raise InputError(f"IQ must be [chirps, {wf.samples_per_chirp}], got {iq.shape}")
    return _add_terms(scale_to_receiver(iq, cfg), cfg, wf, seed, first_chirp)


def _taper(name: str, n: int) -> np.ndarray:
    return get_window(name, n, fftbins=True).astype(np.float64)


def range_bin_noise(p_sample: float, n_samples: int, range_window: str = "boxcar") -> float:
    """Noise power [W] per range bin, P_n sum(w^2) / sum(w)^2, for white noise of `p_sample` per complex
    sample under the DSP's range-FFT normalisation (`processing.fast_time.project`) (divide by sum(w)). A
    range-Doppler bin holds the same level: the DSP's Doppler taper has unit energy, which leaves white noise
    unchanged."""
    w = _taper(range_window, n_samples)
    return p_sample * float((w ** 2).sum() / w.sum() ** 2)


def processing_gain_db(n_samples: int, n_chirps: int, range_window: str = "boxcar",
                       doppler_window: str = "boxcar") -> float:
    """SNR gain [dB] of the range and Doppler FFTs for an on-bin, constant-velocity point target."""
    w, u = _taper(range_window, n_samples), _taper(doppler_window, n_chirps)
    return 10 * math.log10(w.sum() ** 2 / (w ** 2).sum() * u.sum() ** 2 / (u ** 2).sum())


def received_power_w(cfg: ReceiverConfig, rcs_m2: float, r_tx_m: float, r_rx_m: float, wavelength_m: float,
                     gain_tx_dbi: float = 0.0, gain_rx_dbi: float = 0.0) -> float:
    """Radar equation at the ADC: P_t G_tx G_rx lambda^2 sigma / ((4 pi)^3 R_tx^2 R_rx^2) x G_chain [W]."""
    g_tx, g_rx = 10.0 ** (gain_tx_dbi / 10.0), 10.0 ** (gain_rx_dbi / 10.0)
    ratio = received_power_ratio(rcs_m2, r_tx_m, r_rx_m, wavelength_m, g_tx, g_rx)
    return transmit_power_w(cfg) * 10.0 ** (cfg.chain_gain_db / 10.0) * float(ratio)


# Presets. No Ancortek data sheet was found in the sources searched, so each value says where it comes from
# (recalled vendor/user figures are marked unverified); replace them when a data sheet is at hand.
ANCORTEK_2400T2R4 = RadarHardware(
    receiver=ReceiverConfig(transmit_power_dbm=19.0, noise_figure_db=12.0),
    antenna=GaussianBeam(hpbw_az_deg=30.0, hpbw_el_deg=30.0, floor_db=30.0, look_at=(0.0, 0.0, 1.1)),
    source="Ancortek SDR-KIT 2400T2R4 (24 GHz, 2 Tx / 4 Rx, horns). Not a data sheet: P_t 19 dBm recalled "
           "from the vendor's kit pages (unverified); NF 12 dB typical of 24 GHz SiGe transceivers; 30 deg "
           "horns as in the project's issue, gain = Gaussian-beam directivity 16.0 dBi, -30 dB floor; the "
           "seed's radars (3, 0, 1.1) and (0, -3, 1.1) look horizontally at the room centre (0, 0, 1.1).")
ANCORTEK_580AD = RadarHardware(
    receiver=ReceiverConfig(transmit_power_dbm=18.0, noise_figure_db=8.0),
    antenna=YagiBeam(hpbw_az_deg=24.0, hpbw_el_deg=24.0, peak_gain_dbi=17.0, front_to_back_db=20.0,
                     floor_db=25.0, look_at=(0.0, 0.0, 1.1)),
    source="Ancortek SDR-KIT 580AD (5.8 GHz, Yagi antennas; Glasgow dataset). Not a data sheet: P_t about "
           "18 dBm and Yagi gain about 17 dBi as quoted (from memory, unverified) in the Glasgow group's "
           "papers; HPBW 24 deg makes the model's directivity 17 dBi; F/B 20 dB, floor -25 dB and NF 8 dB "
           "typical values; look_at is a placeholder (horizontal boresight at 1.1 m).")
