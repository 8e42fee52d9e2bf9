"""Radar DSP: range profiles, slow-time clutter removal, micro-Doppler p(v,t), mean velocity, range
distribution and range-Doppler map (seed eqs. 5-10).

Two stages. The fast-time stage (`processing.fast_time.project`) turns raw IQ [C, N] into range profiles
of the used bins and the coherent range-sum slow-time signal; the slow-time stage
(`signatures_from_projection`) does everything else: MTI clutter filter (`processing.dsp.mti`), STFT over
`window_chirps` chirps every `hop_chirps`, p(v,t), eq.-8 mean velocity, range distribution, range-Doppler
map. `signatures(iq, ...)` is exactly the two in a row; a synthesiser may build the `Projection` itself.

Sign convention: positive radial velocity means the scatterer approaches the radar (its range, half the
total path for bistatic links, decreases), i.e. a positive Doppler shift, as in the seed's figures. The
IQ phase exp(+j 2 pi f tau) of an approaching target falls, so its slow-time frequency f_D is negative:
v = -f_D c / (2 f_ref).

Velocity axes (`Signature.velocity`, `Signature.range_doppler_velocity`): ascending, v_k = k dv for
k = -nfft/2 .. nfft/2 - 1 with dv = c / (2 f_ref nfft PRI), i.e. [-v_max, v_max) with
v_max = c / (4 f_ref PRI) = lambda_ref / (4 PRI). Index 0 holds the Nyquist bin (slow-time frequency
+-PRF/2, ambiguous between -v_max and +v_max) and is labelled -v_max; the last bin is v_max - dv. (With an
odd FFT length there is no Nyquist bin and the axis is symmetric.) f_ref, the carrier the Doppler refers
to, is stored as `Signature.carrier_hz`, and `Signature.v_max` is v_max above. For per-range-bin
processing (range_sum "incoherent"/"magnitude", and always for the range-Doppler map) a range bin's phase
refers to mid-chirp, so f_ref = `Waveform.carrier_hz` and v_max = `Waveform.v_max` exactly. The coherent
range sum's phase refers to where its fast-time weights sit (`processing.fast_time.coherent_weights`),
so its f_ref is that instantaneous frequency, 0.4-0.5 % below the centre at the seed's radar: labelling it
with the centre frequency would scale every velocity by that much. With a velocity crop the axes keep
only |v| <= `velocity_crop_mps`.

Empty windows: a time bin whose total power is zero or below `empty_floor` times the largest power the
recording had before clutter removal (i.e. numerically nothing left, such as the rounding residue of a
removed static scene) gets p(v,t) = 0 for every v and mean velocity 0; its range distribution is likewise
0. Nothing is ever NaN. `Signature.valid` marks the bins that had signal.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.dsp.config import DEFAULT_MTI_CUTOFF_MPS, GLASGOW_DSP, DSPConfig
from processing.fast_time import Projection, coherent_weights, doppler_band, project, range_weights
from processing.dsp.mti import mti_filter
from processing.radar.waveform import C0, Waveform
from processing.windows import get_window

__all__ = ["DEFAULT_MTI_CUTOFF_MPS", "DSPConfig", "GLASGOW_DSP", "Projection", "Signature", "column_sums",
           "mean_velocity", "project", "signatures", "signatures_from_projection"]

_CHUNK = 1 << 22  # complex STFT values computed at once (64 MB): bounds memory for long, heavily overlapped runs


@dataclass
class Signature:
    """Radar signatures of one link.

    Attributes:
        time: window centre times [T] in seconds.
        velocity: radial velocity axis [V] in m/s (ascending, [-v_max, v_max) or the crop; positive =
            approaching; see the module docstring for the Nyquist bin).
        p_vt: velocity distribution p(v, t) [V, T] (eq. 7), each column sums to 1 (or 0 if empty). For
            range_sum "magnitude" it is (sum_r |S_r|)^2 normalised, so 10 log10(p_vt * power) is the
            Glasgow script's 20 log10(sum_r |S_r|) (up to the taper's scale).
        mean_velocity: mean radial velocity [T] in m/s (eq. 8).
        range: range axis [R] in metres (bistatic: half the total path).
        range_distribution: p'(r, t) [R, T] (eq. 10), columns sum to 1 (or 0 if empty).
        valid: [T] bool, True where the window carried signal (above the receiver noise by
            `detection_snr_db` when the noise level is known; mean velocity is 0 elsewhere).
        power: [T] total power of each p(v,t) column before normalisation (arbitrary units).
        carrier_hz: carrier f_ref [Hz] that `velocity` refers to (v = -f_D c / (2 f_ref)).
        v_max: c / (4 f_ref PRI) [m/s], the Doppler ambiguity limit of `velocity` (0: unknown, old files).
        range_doppler: range-Doppler power [R, V_rd, T_rd] (float32, arbitrary units: |STFT|^2 per range bin
            with the unit-energy slow-time taper) of every `range_doppler_stride`-th window after clutter
            removal, over `range`; None when switched off.
        range_doppler_time: [T_rd] centre times [s] of those windows.
        range_doppler_velocity: [V_rd] velocity axis [m/s] of the map (refers to the waveform's carrier).
    """

    time: np.ndarray
    velocity: np.ndarray
    p_vt: np.ndarray
    mean_velocity: np.ndarray
    range: np.ndarray
    range_distribution: np.ndarray
    valid: np.ndarray
    power: np.ndarray = field(default_factory=lambda: np.zeros(0))
    carrier_hz: float = 0.0
    v_max: float = 0.0
    range_doppler: np.ndarray | None = None
    range_doppler_time: np.ndarray | None = None
    range_doppler_velocity: np.ndarray | None = None

    def __repr__(self) -> str:
        v, t, r = np.asarray(self.velocity), np.asarray(self.time), np.asarray(self.range)

        def span(x, unit, fmt=".3g"):
            return f"{x[0]:{fmt}}..{x[-1]:{fmt}} {unit}" if x.size else "empty"

        rd = "" if self.range_doppler is None else f"; range-Doppler {'x'.join(map(str, np.shape(self.range_doppler)))}"
        valid = int(np.count_nonzero(self.valid))
        return (f"<Signature: p(v,t) [{v.size} velocity x {t.size} time] over {span(v, 'm/s')}, {span(t, 's')}; "
                f"range distribution [{r.size} range x {t.size} time] over {span(r, 'm')}; {valid}/{t.size} windows "
                f"with signal; carrier {self.carrier_hz / 1e9:.4g} GHz, v_max {self.v_max:.3g} m/s{rd}>")

    def __eq__(self, other) -> bool:
        """Equal when every field is: arrays of one dtype and shape with the same values (NaN never occurs)."""
        if not isinstance(other, Signature):
            return NotImplemented
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if (a is None) != (b is None):
                return False
            if a is not None and not (np.shape(a) == np.shape(b) and np.asarray(a).dtype == np.asarray(b).dtype
                                      and np.array_equal(a, b)):
                return False
        return True

    # not hashable (mutable arrays): @dataclass with eq=True and frozen=False sets __hash__ = None

    def to_xarray(self):
        """The signatures as an `xarray.Dataset` with coordinates ``velocity`` [m/s], ``time`` [s], ``range``
        [m] (and ``rd_velocity`` [m/s], ``rd_time`` [s] of the range-Doppler map when present): ``p_vt``
        (velocity, time), ``mean_velocity``, ``valid``, ``power`` (time), ``range_distribution`` (range, time),
        ``range_doppler`` (range, rd_velocity, rd_time); ``carrier_hz`` and ``v_max`` as attributes."""
        import xarray as xr

        data = {"p_vt": (("velocity", "time"), self.p_vt, {"long_name": "p(v,t), seed eq. 7", "units": "1"}),
                "mean_velocity": ("time", self.mean_velocity, {"long_name": "mean radial velocity, eq. 8",
                                                               "units": "m/s"}),
                "range_distribution": (("range", "time"), self.range_distribution, {"long_name": "p'(r,t), eq. 10",
                                                                                    "units": "1"}),
                "valid": ("time", np.asarray(self.valid, bool), {"long_name": "window carries signal"})}
        coords: dict[str, tuple]  # the range-Doppler axes may join below
        coords = {"velocity": ("velocity", self.velocity, {"units": "m/s", "long_name": "radial velocity, "
                                                                                         "+ = approaching"}),
                  "time": ("time", self.time, {"units": "s", "long_name": "window centre"}),
                  "range": ("range", self.range, {"units": "m"})}
        if np.shape(self.power) == np.shape(self.time):
            data["power"] = ("time", self.power, {"long_name": "column power before normalisation", "units": "a.u."})
        if self.range_doppler is not None:
            data["range_doppler"] = (("range", "rd_velocity", "rd_time"), self.range_doppler, {"units": "a.u."})
            coords["rd_velocity"] = ("rd_velocity", self.range_doppler_velocity, {"units": "m/s"})
            coords["rd_time"] = ("rd_time", self.range_doppler_time, {"units": "s"})
        return xr.Dataset(data, coords=coords, attrs={"carrier_hz": float(self.carrier_hz), "v_max": float(self.v_max)})


def column_sums(weights: np.ndarray, p: np.ndarray) -> np.ndarray:
    """sum_v weights[v] p[v, t] for every column t of p [V, T] (weights [V], real or complex), summed in an
    order fixed by the shapes alone: `np.add.reduce` over axis 0 of a C-contiguous product.

    Not `weights @ p`: OpenBLAS splits a matrix-vector product's work by its thread count, so the complex
    product of the unwrapped mean velocity gave different last bits with OPENBLAS_NUM_THREADS=1 and 2
    (measured, T = 500 windows), and its result also depends on p's memory layout.
    """
    return np.add.reduce(np.ascontiguousarray(np.asarray(weights)[:, None] * p), axis=0)


def mean_velocity(p_vt: np.ndarray, velocity: np.ndarray, v_max: float, cfg: DSPConfig = DSPConfig(),
                  periodic: bool = True) -> np.ndarray:
    """Mean radial velocity [T] in m/s of p(v,t) [V, T] on the axis `velocity` [V] (seed eq. 8).

    The sampled Doppler spectrum is periodic in v with period 2 v_max, so eq. 8's integral over all v
    has to pick one period. 'seed' takes [-v_max, v_max); 'unwrapped' takes the period centred on the
    distribution's circular mean, which is the same for any signature away from +-v_max but removes the
    bias that the rectangular window's sidelobes, wrapping round the band edge, give a fast target.
    `periodic=False` (a cropped axis, not a whole period) always uses 'seed'.
    """
    mean = column_sums(velocity, p_vt)
    if cfg.mean_velocity == "seed" or not periodic or p_vt.size == 0:
        return mean
    z = column_sums(np.exp(1j * np.pi * velocity / v_max), p_vt)
    centre = np.angle(z) * v_max / np.pi
    use = np.abs(z) >= cfg.unwrap_min_concentration
    v = centre[None, :] + np.mod(velocity[:, None] - centre[None, :] + v_max, 2 * v_max) - v_max
    return np.where(use, np.add.reduce(np.ascontiguousarray(v * p_vt), axis=0), mean)


def _normalise(power: np.ndarray, floor: float, reference: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column-normalised distribution of power [X, T], with columns below `floor` times the larger of the
    strongest column and `reference` set to 0 (never NaN). Sums in a fixed order (C layout, see `column_sums`)."""
    power = np.ascontiguousarray(power)
    total = np.add.reduce(power, axis=0)
    peak = max(total.max() if total.size else 0.0, reference)
    valid = total > max(floor * peak, np.finfo(np.float64).tiny)
    dist = np.zeros_like(power)
    dist[:, valid] = power[:, valid] / total[valid]
    return dist, valid, total


def _doppler_taper(cfg: DSPConfig) -> np.ndarray:
    taper = get_window(cfg.doppler_window, cfg.window_chirps, fftbins=not cfg.doppler_window_symmetric)
    return taper / np.sqrt((taper ** 2).sum())  # unit energy: a tone's power is the same for every taper


def _stft(x: np.ndarray, starts: np.ndarray, cfg: DSPConfig, reduce) -> np.ndarray:
    """reduce(S) over chunks of windows, S [t, ..., nfft] the slow-time FFT of x [C, ...] in velocity order
    (index i <-> FFT bin (nfft // 2 - i) mod nfft: ascending velocity, see the module docstring)."""
    w, nfft = cfg.window_chirps, cfg.nfft
    taper = _doppler_taper(cfg)
    order = (nfft // 2 - np.arange(nfft)) % nfft
    per_window = nfft * max(1, int(np.prod(x.shape[1:])))
    step = max(1, _CHUNK // per_window)
    out = []
    for i in range(0, starts.size, step):
        seg = x[starts[i:i + step, None] + np.arange(w)]  # [t, W, ...]
        seg = np.moveaxis(seg, 1, -1) * taper
        out.append(reduce(np.fft.fft(seg, n=nfft, axis=-1)[..., order]))
    return np.concatenate(out) if out else reduce(np.zeros((0,) + x.shape[1:] + (nfft,), complex))


def _velocity_axis(carrier_hz: float, pri_s: float, nfft: int) -> np.ndarray:
    dv = C0 / (2 * carrier_hz * nfft * pri_s)
    return (np.arange(nfft) - nfft // 2) * dv


def noise_column_power(wf: Waveform, cfg: DSPConfig, noise_power: float, n_velocity: int) -> float:
    """Expected total power of one p(v,t) column (before normalisation) for white receiver noise of
    `noise_power` per complex IQ sample, over `n_velocity` kept velocity bins.

    The unit-energy slow-time taper keeps a slow-time sample's noise variance s^2 in every Doppler bin, so a
    column holds n_velocity s^2: coherent sum s^2 = P_n sum |h|^2; per range bin s_r^2 = P_n sum_m |W_mr|^2,
    summed over the band for `incoherent`; for `magnitude` E[(sum_r |S_r|)^2] = (sum_r s_r sqrt(pi)/2)^2 +
    sum_r s_r^2 (1 - pi/4) (Rayleigh magnitudes, bins taken as independent). The MTI filter changes white
    noise by its stop band's share, below 1 % here (ignored).
    """
    if cfg.range_sum == "coherent":
        h, _ = coherent_weights(wf, cfg)
        return float(n_velocity * noise_power * np.sum(np.abs(h) ** 2))
    w, rng = range_weights(wf, cfg)
    s2 = noise_power * np.sum(np.abs(w) ** 2, axis=0)[doppler_band(rng, wf, cfg)]
    if cfg.range_sum == "incoherent":
        return float(n_velocity * s2.sum())
    s = np.sqrt(s2)
    return float(n_velocity * ((s.sum() * np.sqrt(np.pi) / 2) ** 2 + s2.sum() * (1 - np.pi / 4)))


def signatures_from_projection(proj: Projection, cfg: DSPConfig = DSPConfig(),
                               noise_power: float | None = None) -> Signature:
    """Slow-time stage: all signatures of one link from its fast-time `Projection`.

    `noise_power`: the receiver's noise power per complex IQ sample (IQ units), when known. A window then
    counts as carrying signal (`valid`) only when its power exceeds the expected noise-only power
    (`noise_column_power`) by `cfg.detection_snr_db`; its p(v,t) still shows what was received (the noise
    spectrum), but its mean velocity is 0, never the mean of noise.

    Clutter removal (`cfg.static_removal`) on the range profiles and on the coherent sum's slow-time
    signal; p(v,t) over `cfg.window_chirps`-chirp windows every `cfg.hop_chirps` chirps (seed eqs. 6-8)
    from the range bins at or above `cfg.min_range_m`; the range distribution over the same windows from
    every used bin (eqs. 9-10; the power is averaged over each window, i.e. eq. 9 with the magnitude taken
    per Doppler bin, by Parseval); the range-Doppler map over those bins every `cfg.rd_stride(PRI)`-th window.
    """
    wf: Waveform = proj.waveform
    prf, w, hop, nfft = 1.0 / wf.pri_s, cfg.window_chirps, cfg.hop_chirps, cfg.nfft
    prof = mti_filter(proj.profiles, prf, wf.carrier_hz, cfg)
    band = doppler_band(proj.range, wf, cfg)
    raw = np.abs(proj.profiles).astype(np.float64) ** 2  # before clutter removal: the empty-window reference
    raw_peak = float(raw.sum(axis=1).max()) if raw.size else 0.0
    n_c = prof.shape[0]
    n_win = (n_c - w) // hop + 1 if n_c >= w else 0
    starts = np.arange(n_win) * hop
    time = proj.t0 + (starts + w / 2) * wf.pri_s

    if cfg.range_sum == "coherent":
        if proj.coherent is None:
            raise ValueError("range_sum 'coherent' needs the projection's coherent slow-time signal")
        x = mti_filter(proj.coherent, prf, wf.carrier_hz, cfg)
        f_ref = proj.coherent_carrier_hz
        # unit-energy taper: a window's total power nfft sum |x w|^2 is at most nfft max |x|^2
        ref = nfft * float(np.max(np.abs(proj.coherent) ** 2)) if n_c else 0.0
        spec = _stft(x, starts, cfg, lambda s: np.abs(s) ** 2)
    else:
        f_ref = wf.carrier_hz
        red = (lambda s: (np.abs(s) ** 2).sum(axis=1)) if cfg.range_sum == "incoherent" else \
            (lambda s: np.abs(s).sum(axis=1) ** 2)
        spec = _stft(prof[:, band], starts, cfg, red)
        # (sum of R magnitudes)^2 <= R sum of squares
        ref = nfft * float(raw[:, band].sum(axis=1).max()) * (band.sum() if cfg.range_sum == "magnitude" else 1)
    velocity = _velocity_axis(f_ref, wf.pri_s, nfft)
    v_max = C0 / (4 * f_ref * wf.pri_s)
    keep = np.ones(nfft, bool) if cfg.velocity_crop_mps is None else \
        np.abs(velocity) <= cfg.velocity_crop_mps * (1 + 1e-12)
    p_vt, valid, total = _normalise(spec.T[keep].astype(np.float64), cfg.empty_floor, ref)
    mean_v = mean_velocity(p_vt, velocity[keep], v_max, cfg, periodic=bool(keep.all()))
    if noise_power is not None and noise_power > 0:
        floor = noise_column_power(wf, cfg, noise_power, int(keep.sum())) * 10 ** (cfg.detection_snr_db / 10)
        valid = valid & (total > floor)
        mean_v = np.where(valid, mean_v, 0.0)

    rpow = np.abs(prof).astype(np.float64) ** 2
    rwin = sliding_window_view(rpow, w, axis=0)[::hop].mean(axis=2) if n_win else np.zeros((0, rpow.shape[1]))
    rdist, _, _ = _normalise(rwin.T, cfg.empty_floor, raw_peak)  # rwin: mean power per bin and window [T, R]

    rd = rd_t = rd_v = None
    if cfg.range_doppler:
        sel = np.arange(0, n_win, cfg.rd_stride(wf.pri_s))
        rd_v_full = _velocity_axis(wf.carrier_hz, wf.pri_s, nfft)
        rd_keep = np.ones(nfft, bool) if cfg.velocity_crop_mps is None else \
            np.abs(rd_v_full) <= cfg.velocity_crop_mps * (1 + 1e-12)
        rd = _stft(prof, starts[sel], cfg, lambda s: (np.abs(s[..., rd_keep]) ** 2).astype(np.float32))
        rd = np.ascontiguousarray(rd.transpose(1, 2, 0))  # [R, V, T_rd]
        rd_t, rd_v = time[sel], rd_v_full[rd_keep]
    return Signature(time=time, velocity=velocity[keep], p_vt=p_vt, mean_velocity=mean_v, range=proj.range,
                     range_distribution=rdist, valid=valid, power=total, carrier_hz=float(f_ref),
                     v_max=float(v_max), range_doppler=rd, range_doppler_time=rd_t, range_doppler_velocity=rd_v)


def signatures(iq: np.ndarray, wf: Waveform, cfg: DSPConfig = DSPConfig(), t0: float = 0.0,
               noise_power: float | None = None) -> Signature:
    """All signatures of one link from raw IQ [C, N] whose first chirp starts at t0 seconds:
    `signatures_from_projection(project(iq, wf, cfg, t0), cfg, noise_power)`."""
    return signatures_from_projection(project(iq, wf, cfg, t0), cfg, noise_power)
