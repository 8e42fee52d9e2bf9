"""Settings of the radar DSP (`DSPConfig`) and the ready-made Glasgow preset (`GLASGOW_DSP`).

Defaults follow the seed (64-chirp rectangular window, hop 32, coherent range sum, eq. 8 mean velocity)
with a local slow-time MTI filter for static returns instead of the whole-recording mean (see
`processing.dsp.mti`; the choice of filter and cut-off is justified at `DEFAULT_MTI_CUTOFF_MPS`).
"""
from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from processing.summary import settings_repr
from processing.windows import is_window_name
from processing.errors import InputError

# Default MTI: centred moving-average subtraction with its -3 dB point at 0.02 m/s (3.2 Hz at 24.125 GHz:
# L = 469 chirps = 0.23 s at PRF 2 kHz; 0.77 Hz and ~1 s at 5.8 GHz / 1 kHz). Chosen by measurement
# (procedural walk, fall, sit, stand, pick; points backend, Radar 1; eq.-8 mean velocity against the
# pelvis's and against the scatterers' power-weighted radial velocity; numbers in the project notes):
# every local filter fixed the walk (slope 0.53 -> 1.00, RMSE 0.67 -> 0.14 m/s), and among them the
# causal Butterworth and the moving average at 0.02-0.05 m/s were within 0.01-0.02 of each other on every
# activity. Lower cut-offs keep more of the slow body motion of sit/stand/pick (slope against the
# power-weighted velocity 1.03 at 0.02 m/s, 1.18 at 0.05, 1.32 at 0.1 for sit); higher ones empty the
# zero bin faster. The centred average is zero-phase, removes a static return exactly from the first
# chirp to the last (no start transient, no settling) and lets a return that comes to rest fade within
# L/2 (0.12 s) either side; a causal Butterworth (what real-time hardware runs) is the option
# `static_removal="butterworth"`. At a tenth of a velocity bin (0.19 m/s for 64 chirps) the cut-off only
# touches the zero-velocity bin.
DEFAULT_MTI_CUTOFF_MPS = 0.02

# COHERENT_OFFSET_NOTE. The coherent range sum (seed eq. 6) weights the first ~R_unamb / max_range samples
# of each chirp (91 % of its weight on the first 8 of 128 at the seed's settings). On real sawtooth
# hardware those samples carry the synthesiser's settling transient after the frequency reset, and the
# default DSP is also what real `.dat` recordings go through (`processing.realdata.ancortek`). Skipping N // 16
# samples (31 us of the seed's 0.5 ms chirp) moves the weights past it; on simulated IQ, which has no
# transient, it changes nothing but the effective carrier the velocity axis refers to (walk slope 1.00 and
# RMSE 0.142 vs 0.144 m/s with no offset, measured), and the Doppler stays right (tests/test_dsp_axes.py).

# Range-Doppler maps are stored about 10 per second by default (a 5 s walk at the seed's settings: 53 maps
# of 18 x 64 float32 per link, ~0.2 MB; every non-overlapping window would be 158 maps, 1.6 MB per file):
# enough to follow a body through the room, small next to p(v,t). `range_doppler_stride` overrides it.
RD_MIN_INTERVAL_S = 0.1


class DSPConfig(BaseModel):
    """Signal-processing settings (SI units: m, s, Hz, m/s). Window names are scipy.signal window names."""

    # Bounds (reasons): a slow-time window of at most 65536 chirps (33 s at the seed's PRI; longer windows
    # average a body's whole motion into one spectrum) and an FFT of at most 2^20 points keep one window's
    # arrays (range bins x FFT points) within a few hundred MB; non-finite values are refused everywhere.
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    # slow-time STFT
    window_chirps: int = Field(64, ge=4, le=65536, description="slow-time window W of the micro-Doppler STFT "
                               "[chirps]")
    hop_chirps: int = Field(32, ge=1, le=65536, description="hop between successive windows [chirps] (<= window)")
    fft_points: int | None = Field(None, ge=4, le=2 ** 20, description="slow-time FFT length (zero padding, "
                                   ">= window); default: window_chirps")
    doppler_window: str = Field("boxcar", description="slow-time taper (scipy name); the seed's is boxcar")
    doppler_window_symmetric: bool = Field(False, description="symmetric taper (MATLAB's hamming(n)) "
                                           "instead of scipy's periodic (DFT-even) one")
    # fast time
    range_window: str = Field("boxcar", description="fast-time taper before the range FFT (scipy name)")
    range_bins: Literal["all", "positive_half"] = Field(
        "all", description="all: every range bin up to the largest range; positive_half: bins below N/2 only")
    min_range_m: float = Field(0.0, ge=0, le=1e4, description="lowest range summed for p(v,t) [m] (from the bin "
                               "containing it)")
    max_range_m: float | None = Field(None, gt=0, le=1e6, description="highest range used [m]; default: waveform's")
    range_sum: Literal["coherent", "incoherent", "magnitude"] = Field(
        "coherent", description="how the range bins of the Doppler band make p(v,t): coherent = seed eq. 6 "
        "(sum bins, then STFT); incoherent = sum of per-bin |STFT|^2; magnitude = (sum of per-bin |STFT|)^2 "
        "(the Glasgow script's sum of magnitudes)")
    coherent_offset_samples: int | None = Field(
        None, ge=0, le=16384, description="coherent sum: skip this many fast-time samples after the chirp reset; "
        "default N // 16 (8 of 128), see COHERENT_OFFSET_NOTE")
    # slow-time clutter removal (processing.dsp.mti)
    static_removal: Literal["moving_average", "butterworth", "mean", "none"] = Field(
        "moving_average", description="slow-time clutter filter per range bin (see processing.dsp.mti)")
    mti_cutoff_mps: float = Field(DEFAULT_MTI_CUTOFF_MPS, gt=0, le=100, description="MTI -3 dB cut-off as a radial "
                                  "velocity [m/s] (f_c = 2 v / lambda of the waveform's carrier)")
    mti_cutoff_hz: float | None = Field(None, gt=0, le=1e6, description="MTI cut-off in Hz; overrides mti_cutoff_mps")
    mti_order: int = Field(4, ge=1, le=10, description="Butterworth order")
    mti_zero_phase: bool = Field(False, description="Butterworth forward-backward (sosfiltfilt) instead of "
                                 "causal (sosfilt)")
    mti_initial: Literal["steady", "zero"] = Field(
        "steady", description="causal Butterworth start: steady state of the first chirp, or at rest (MATLAB "
        "filter; static returns ring for ~1/f_c)")
    # outputs
    velocity_crop_mps: float | None = Field(None, gt=0, le=1e4, description="keep |v| <= this in p(v,t) and the "
                                            "range-Doppler map [m/s]; default: the whole Doppler period")
    empty_floor: float = Field(1e-12, ge=0, description="time bins below this fraction of the recording's "
                               "peak power before clutter removal are empty")
    mean_velocity: Literal["unwrapped", "seed"] = Field(
        "unwrapped", description="seed: eq. 8 over the fixed axis [-v_max, v_max); unwrapped: eq. 8 over "
        "the Doppler ambiguity interval centred on the distribution's circular mean")
    unwrap_min_concentration: float = Field(
        0.2, ge=0, le=1, description="circular resultant length below which 'unwrapped' falls back to 'seed'")
    detection_snr_db: float = Field(6.0, ge=0, le=60, description="a window carries signal when its power "
                                    "exceeds the receiver's expected noise-only power by this [dB] (when the "
                                    "noise level is known; 6 dB is >10 standard deviations of a 64-bin noise "
                                    "column's power)")
    range_doppler: bool = Field(True, description="compute the range-Doppler map")
    range_doppler_stride: int | None = Field(
        None, ge=1, le=10 ** 6, description="keep the range-Doppler map of every k-th window; default: the smallest k "
        "whose maps neither overlap nor come closer than RD_MIN_INTERVAL_S")

    @field_validator("doppler_window", "range_window")
    @classmethod
    def _window_exists(cls, name: str) -> str:
        if not is_window_name(name):
            raise InputError(f"unknown window {name!r}; use a scipy.signal.get_window name such as boxcar, "
                             "hann, hamming, blackman")
        return name

    @model_validator(mode="after")
    def _consistent(self) -> "DSPConfig":
        if self.hop_chirps > self.window_chirps:
            raise InputError(f"hop_chirps ({self.hop_chirps}) must not exceed window_chirps "
                             f"({self.window_chirps}): chirps between windows would be skipped")
        if self.fft_points is not None and self.fft_points < self.window_chirps:
            raise InputError(f"fft_points ({self.fft_points}) must be at least window_chirps "
                             f"({self.window_chirps}); zero padding cannot shorten the window")
        # a dumped config carries both fields (the m/s one at its default): only a non-default m/s value
        # next to a Hz value is a contradiction, so model_dump -> model_validate round-trips
        if ({"mti_cutoff_hz", "mti_cutoff_mps"} <= self.model_fields_set and self.mti_cutoff_hz is not None
                and self.mti_cutoff_mps != DEFAULT_MTI_CUTOFF_MPS):
            raise InputError("give the MTI cut-off either in Hz (mti_cutoff_hz) or in m/s (mti_cutoff_mps), "
                             "not both")
        if self.max_range_m is not None and self.max_range_m < self.min_range_m:
            raise InputError(f"max_range_m ({self.max_range_m}) is below min_range_m ({self.min_range_m})")
        return self

    def __repr__(self) -> str:
        return settings_repr(self)  # the fields set away from their defaults

    @property
    def nfft(self) -> int:
        """Slow-time FFT length (window plus zero padding)."""
        return self.window_chirps if self.fft_points is None else self.fft_points

    def rd_stride(self, pri_s: float) -> int:
        """Windows between stored range-Doppler maps (see `range_doppler_stride`).

        Args:
            pri_s: the chirp interval [s].
        """
        if self.range_doppler_stride is not None:
            return self.range_doppler_stride
        no_overlap = -(-self.window_chirps // self.hop_chirps)
        return max(no_overlap, int(round(RD_MIN_INTERVAL_S / (self.hop_chirps * pri_s))))

    @classmethod
    def glasgow(cls) -> "DSPConfig":
        """The processing of the University of Glasgow "Radar signatures of human activities" dataset's
        example MATLAB script (Ancortek, 5.8 GHz, 400 MHz, 1 ms chirp, 128 samples), value by value.

        Display steps stay with the plotting: the script's image is 20 log10(sum_r |S_r|) relative to its
        global maximum with a 40 dB colour span, i.e. 10 log10(p_vt * power) here (p(v,t) itself is
        normalised per column, eq. 7). Differences kept on purpose: `time` holds the true window centres
        (the script stretches linspace(0, duration, n) over them); the velocity axis is the true one (the
        script's flipud of an fftshifted even-length spectrum labels every row one bin off); bin 0, which
        the script drops after the MTI, is outside the summed band anyway.
        """
        return cls(
            range_window="boxcar",           # win = ones(NTS, nc) before fft
            range_bins="positive_half",      # Data_range(1:NTS/2,:) = tmp(NTS/2+1:NTS,:): bins 0..N/2-1
            min_range_m=3.75,                # bin_indl = 10: row 10 once row 1 (bin 0) is dropped = bin 10, at
                                             # c/2B = 0.375 m (the band takes the bin containing each limit)
            max_range_m=11.25,               # bin_indu = 30. The dataset's README puts people 1-4 m from the
                                             # radar, so the hardware seems to add a range offset (cable/IF
                                             # delay, undocumented): for simulated scenes set the band to
                                             # where the body is (model_copy(update={...}))
            static_removal="butterworth",    # [b,a] = butter(4, 0.0075, 'high'); filter(b, a, ...) per range bin
            mti_order=4,                     # butter(4, ...)
            mti_cutoff_hz=3.75,              # 0.0075 x PRF/2 = 0.0075 x 500 Hz (MATLAB normalises to Nyquist)
            mti_zero_phase=False,            # filter() is causal
            mti_initial="zero",              # filter() starts at rest
            window_chirps=200,               # MD.TimeWindowLength = 200 (spectrogram's scalar window: hamming(200))
            doppler_window="hamming",        # spectrogram(x, 200, ...) uses hamming(200)
            doppler_window_symmetric=True,   # MATLAB's hamming(n) is symmetric
            hop_chirps=10,                   # MD.OverlapLength = round(200 x 0.95) = 190 -> hop 10
            fft_points=800,                  # MD.FFTPoints = Pad_Factor 4 x 200
            range_sum="magnitude",           # Data_spec_MTI2 = sum over RBin of abs(spectrogram(...))
            velocity_crop_mps=6.0,           # ylim([-6 6]) of the published images
            mean_velocity="seed",            # eq. 8 over the cropped axis (the crop is not a Doppler period)
        )


GLASGOW_DSP = DSPConfig.glasgow()


# A simulation's arrays (per link: IQ if kept, range profiles, spectrogram, range-Doppler maps) beyond
# this are refused before any work: 8 GiB is a third of the reference machine's memory.
MAX_SIGNATURE_BYTES = 8 * 2 ** 30


def recording_bytes(n_chirps: int, wf, cfg: DSPConfig, keep_iq: bool = False) -> int:
    """Estimated peak memory [bytes] of one link's IQ (if kept) and DSP arrays for `n_chirps` chirps."""
    n = wf.samples_per_chirp
    bins = min(n, int(((wf.max_range_m if cfg.max_range_m is None else cfg.max_range_m) / wf.range_resolution)) + 2)
    windows = max(0, (n_chirps - cfg.window_chirps) // cfg.hop_chirps + 1)
    profiles = n_chirps * bins * 8 * 3  # complex64 profiles, MTI output and one temporary
    spectra = windows * cfg.nfft * 8 * 4  # spectrogram, p(v,t), power and a temporary (float64)
    rd = (windows // max(1, cfg.rd_stride(wf.pri_s))) * bins * cfg.nfft * 4 if cfg.range_doppler else 0
    return profiles + spectra + rd + (n_chirps * n * 8 if keep_iq else 0)


def check_recording(duration_s: float, wf, cfg: DSPConfig, n_links: int = 1, keep_iq: bool = False) -> int:
    """Refuse, before any simulation, a recording of `duration_s` seconds that is shorter than one DSP
    window or whose arrays would exceed `MAX_SIGNATURE_BYTES`; returns the number of chirps.

    Raises `processing.errors.InputError` with one line naming the setting at fault."""
    from processing.errors import InputError

    n_chirps = int(duration_s / wf.pri_s + 1e-9) + 1
    if n_chirps < cfg.window_chirps:
        raise InputError(f"dsp.window_chirps = {cfg.window_chirps} chirps ({cfg.window_chirps * wf.pri_s:g} s) is "
                         f"longer than the recording ({duration_s:.3g} s = {n_chirps} chirps of {wf.pri_s:g} s): "
                         "no complete DSP window; shorten the window or lengthen the motion")
    need = n_links * recording_bytes(n_chirps, wf, cfg, keep_iq)
    if need > MAX_SIGNATURE_BYTES:
        raise InputError(f"{n_links} link(s) x {n_chirps} chirps (waveform.pri_s = {wf.pri_s:g} s over "
                         f"{duration_s:.3g} s) would need ~{need / 2 ** 30:.1f} GiB of signal arrays "
                         f"(limit {MAX_SIGNATURE_BYTES / 2 ** 30:g} GiB); use a longer PRI, a shorter motion, "
                         "fewer links or no --keep-iq")
    return n_chirps
