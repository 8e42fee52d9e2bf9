"""Fixed-size classifier input from variable-size velocity distributions p(v,t).

A p(v,t) from `processing.dsp.signatures.signatures` has V velocity bins (64 for the seed's 64-chirp window) over
[-v_max, v_max) and T time bins that depend on the recording length (62.5 bins/s at the seed's 0.5 ms
PRI and hop of 32 chirps; activities last 2-6 s). The network needs one size, and a model trained on
one radar should accept another radar's recordings, so the input is built on *physical* axes:

1. Velocity: each column is rebinned (mass-conserving: each output bin integrates the input bins it
   overlaps) onto `n_velocity` bins spanning [-v_range_mps, +v_range_mps] (default 6.2 m/s, the seed
   radar's v_max; velocities outside the recorded band are 0). With the defaults and the seed's radar
   this is the identity up to a sub-bin shift. `v_range_mps=None` keeps the recorded span.
2. Time: `time_mode="resample"` rebins the whole recording to `n_time` bins
   (the seed's "resized image"; activity durations are normalised away). `time_mode="window"` takes
   a fixed `window_s` seconds centred on the recording's motion centroid (zero-padded where the
   recording is shorter; with `window_valid_only` only valid, above-noise time bins count for the
   centroid, with `window_power` each weighted by its power), then rebins that to `n_time` bins, keeping
   absolute time scale.
   `time_mode="active"` (default) first crops the recording to its active span (time bins whose motion, the
   p-weighted distance from zero velocity, exceeds `active_fraction` of its peak, plus `active_margin_s`
   either side), then rebins that: standing still before and after an activity (a 14 s mocap take that
   walks for 4 s) no longer decides the image's time scale. With `active_valid_only` (default for new
   models) only time bins marked valid (carrying signal above the noise, `Signature.valid`) can be
   active: a noise-only column's p(v,t) is spread evenly over v, so its p-weighted |v| is about a
   quarter of the axis and would mark the whole recording active.
3. Intensity: `intensity="p"` (default) shows the column-normalised p(v,t) of seed eq. 7, in which every
   column sums to 1, so a column of pure noise is as bright overall as one holding the body: its noise,
   spread evenly over V bins, sits about 10 log10(V) dB under a column's peak bin whatever the SNR.
   `intensity="power"` shows the spectrogram of seed eq. 6, S(v,t) = p(v,t) power(t), on one scale per sample, as a
   radar display (and the published Glasgow images) shows it: noise stays as far below the body as the
   recording's SNR puts it, and a noise floor some dB higher changes the image by that much, not by filling
   every quiet column. The time crop is found from p(v,t) in both cases (the same columns).
4. Scale: `scale="db"` (default) takes 10 log10 p, clips it `floor_db` below the sample's maximum and
   maps [max - floor_db, max] to [0, 1] (per-sample normalisation: the received power level carries
   range and body size, not activity); `scale="linear"` divides by the sample's maximum.

The `PreprocessConfig` is stored inside every checkpoint so evaluation repeats exactly these steps.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from processing.errors import InputError

MAX_WINDOW_BINS = 1_000_000  # time bins of a 'window' crop (16 ms bins: 4.4 h)


class PreprocessConfig(BaseModel):
    """How p(v,t) [V, T] becomes a fixed [n_velocity, n_time] image (units: m/s, s, dB)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    n_velocity: int = Field(64, ge=8, le=1024, description="velocity bins of the network input")
    n_time: int = Field(64, ge=8, le=4096, description="time bins of the network input")
    v_range_mps: float | None = Field(6.2, gt=0, le=1000, description="input spans [-v, v] m/s; None: recorded bins")
    # "active" is the default: with "resample" a 14 s mocap walk that mostly stands still was called
    # "sit" (90.9 % on the mocap walks); with "active" 100 % (measured, see README)
    time_mode: Literal["resample", "window", "active"] = Field("active", description="how T becomes n_time")
    active_fraction: float = Field(0.1, gt=0, lt=1, description="time_mode='active': motion threshold re peak")
    active_margin_s: float = Field(0.25, ge=0, le=600, description="time_mode='active': kept either side [s]")
    # checkpoints written before this field existed load with False (see checkpoint.LEGACY_PREPROCESS)
    active_valid_only: bool = Field(True, description="time_mode='active': only valid (above-noise) time bins "
                                    "can be active, when the sample has a `valid` mask")
    # checkpoints written before this field existed load with False (see checkpoint.LEGACY_PREPROCESS)
    window_valid_only: bool = Field(True, description="time_mode='window': centre on the valid (above-noise) time "
                                    "bins only, when the sample has a `valid` mask")
    # checkpoints written before this field existed load with False (see checkpoint.LEGACY_PREPROCESS)
    window_power: bool = Field(True, description="time_mode='window': weight each time bin's motion by its power "
                               "when the sample has a column `power` (the power centroid of the motion)")
    # bounded like a motion (MAX_DURATION_S): the window is allocated as window_s / dt columns
    window_s: float = Field(6.0, gt=0, le=3600, description="time span of time_mode='window' [s]")
    scale: Literal["db", "linear"] = Field("db", description="dB with floor, or linear, per-sample max = 1")
    floor_db: float = Field(40.0, gt=0, le=300,
                            description="dynamic range kept by scale='db' [dB] (float64 spans ~300 dB)")
    # the seed's p(v,t) is the default so that checkpoints written before this field existed load unchanged
    intensity: Literal["p", "power"] = Field("p", description="'p': the column-normalised p(v,t) (seed eq. 7); "
                                             "'power': the power spectrogram p(v,t) power(t), one scale per sample")


def _rebin(x: np.ndarray, src_edges: np.ndarray, dst_edges: np.ndarray, axis: int) -> np.ndarray:
    """Mass-conserving rebinning along `axis`: each output bin gets the integral of the piecewise-constant
    input over it (so a narrow peak is never lost between output samples, unlike point interpolation)."""
    x = np.moveaxis(x, axis, -1)
    cum = np.concatenate([np.zeros(x.shape[:-1] + (1,)), np.cumsum(x, axis=-1)], axis=-1)
    # cumulative mass at the output edges; outside the input's span the mass is 0 / total
    at = np.stack([np.interp(dst_edges, src_edges, c) for c in cum.reshape(-1, cum.shape[-1])])
    out = np.diff(at, axis=-1).reshape(x.shape[:-1] + (dst_edges.size - 1,))
    return np.moveaxis(out, -1, axis)


def _resample_axis(x: np.ndarray, n: int, axis: int) -> np.ndarray:
    """`x` rebinned to `n` equal bins over the same span along `axis` (bin means kept)."""
    m = x.shape[axis]
    if m == n:
        return x
    return _rebin(x, np.linspace(0, 1, m + 1), np.linspace(0, 1, n + 1), axis) * (n / m)


def _velocity_grid(p_vt: np.ndarray, velocity: np.ndarray | None, cfg: PreprocessConfig) -> np.ndarray:
    if cfg.v_range_mps is None or velocity is None:
        return _resample_axis(p_vt, cfg.n_velocity, axis=0)
    order = np.argsort(velocity)
    v, p = np.asarray(velocity, float)[order], p_vt[order]
    dv = float(np.median(np.diff(v))) if v.size > 1 else 1.0
    src = np.concatenate([v - dv / 2, [v[-1] + dv / 2]])
    dst = np.linspace(-cfg.v_range_mps, cfg.v_range_mps, cfg.n_velocity + 1)
    return _rebin(p, src, dst, axis=0)


def _motion(p_vt: np.ndarray) -> np.ndarray:
    """Per time bin: p-weighted distance of the velocity distribution from zero (bins) - how much moves."""
    v_idx = np.abs(np.arange(p_vt.shape[0]) - (p_vt.shape[0] - 1) / 2)
    total = p_vt.sum(axis=0)
    return np.where(total > 0, (p_vt * v_idx[:, None]).sum(axis=0) / np.where(total > 0, total, 1.0), 0.0)


def _active_span(p_vt: np.ndarray, time: np.ndarray | None, cfg: PreprocessConfig,
                 valid: np.ndarray | None = None, shown: np.ndarray | None = None) -> np.ndarray:
    """The active columns of `shown` (default p_vt; the same grid), found from p_vt."""
    shown = p_vt if shown is None else shown
    dt = float(np.median(np.diff(time))) if time is not None and len(time) > 1 else 0.016
    motion = _motion(p_vt)
    if valid is not None and cfg.active_valid_only:
        motion = np.where(valid, motion, 0.0)
    if motion.max() <= 0:
        return shown
    on = np.flatnonzero(motion >= cfg.active_fraction * motion.max())
    margin = int(round(cfg.active_margin_s / dt))
    return shown[:, max(0, on[0] - margin):on[-1] + margin + 1]


def _time_window(p_vt: np.ndarray, time: np.ndarray | None, cfg: PreprocessConfig,
                 valid: np.ndarray | None = None, power: np.ndarray | None = None,
                 shown: np.ndarray | None = None) -> np.ndarray:
    """The window of `shown` (default p_vt; the same grid) centred as found from p_vt."""
    shown = p_vt if shown is None else shown
    t = p_vt.shape[1]
    dt = float(np.median(np.diff(time))) if time is not None and len(time) > 1 else 0.016
    n_win = max(1, int(round(cfg.window_s / dt))) if dt > 0 else 0
    if not 1 <= n_win <= MAX_WINDOW_BINS:  # a corrupt time axis (dt ~ 0 or negative) must not allocate
        raise InputError(f"time_mode 'window': {cfg.window_s} s at a time step of {dt:g} s gives {n_win} bins "
                         f"(limit 1..{MAX_WINDOW_BINS}): is the time axis valid?")
    mass = p_vt.sum(axis=0)  # 1 per column for normalised p(v,t), less where the velocity grid cuts it
    # centre on where the motion is: spread of the velocity distribution away from zero. A noise-only column
    # is spread evenly over v, so it looks like much motion; with normalised columns (power 1 each) a few
    # seconds of noise outweighed the activity and the window followed them (a recording shifted by 1 s moved
    # its window the other way), hence only valid columns count
    activity = _motion(p_vt) * mass
    if valid is not None and cfg.window_valid_only and (activity * valid).sum() > 0:
        activity = activity * valid
    # and weighted by the column power: with a higher noise floor (a weaker radar, a person farther away) noise
    # columns pass the valid threshold, and by motion alone they would outweigh the activity again
    if power is not None and cfg.window_power and (activity * power).sum() > 0:
        activity = activity * power
    centre = int(round(np.average(np.arange(t), weights=activity))) if activity.sum() > 0 else t // 2
    start = centre - n_win // 2
    out = np.zeros((shown.shape[0], n_win), shown.dtype)
    lo, hi = max(0, start), min(t, start + n_win)
    if hi > lo:
        out[:, lo - start:hi - start] = shown[:, lo:hi]
    return out


def preprocess(p_vt: np.ndarray, velocity: np.ndarray | None = None, time: np.ndarray | None = None,
               cfg: PreprocessConfig = PreprocessConfig(), valid: np.ndarray | None = None,
               power: np.ndarray | None = None) -> np.ndarray:
    """One fixed-size input image [n_velocity, n_time] (float32, values in [0, 1]) from p(v,t) [V, T].

    Args:
        p_vt: velocity distribution [V, T] (any non-negative scale; columns need not sum to 1).
        velocity: its velocity axis [V] in m/s (needed for `v_range_mps`; None: bins taken as they are).
        time: its time axis [T] in s (needed for `time_mode='window'`; None: 16 ms bins assumed).
        cfg: the preprocessing settings.
        valid: [T] bool, time bins carrying signal above the noise (`Signature.valid`); with
            `cfg.active_valid_only` only these can be active. None: every bin may be.
        power: [T] column power (`Signature.power`, any scale); with `cfg.window_power` it weights the
            window's centroid; with `cfg.intensity='power'` it scales each column (required then). None:
            unweighted.
    """
    p = np.nan_to_num(np.asarray(p_vt, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    if p.ndim != 2 or p.shape[1] == 0:
        raise InputError(f"p_vt must be a non-empty [V, T] array, got shape {p.shape}")
    p = np.maximum(p, 0.0)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool).reshape(-1)
        if valid.size != p.shape[1]:
            raise InputError(f"valid has {valid.size} time bins, p_vt {p.shape[1]}")
    if power is not None:
        power = np.nan_to_num(np.asarray(power, dtype=np.float64).reshape(-1), nan=0.0, posinf=0.0, neginf=0.0)
        if power.size != p.shape[1]:
            raise InputError(f"power has {power.size} time bins, p_vt {p.shape[1]}")
        power = np.maximum(power, 0.0)
    if cfg.intensity == "power" and power is None:
        raise InputError("intensity 'power' needs the sample's column power (Signature.power)")
    p = _velocity_grid(p, velocity, cfg)
    # the crop is found from p(v,t) whatever is shown: the same columns for both intensities
    shown = p * power[None, :] if cfg.intensity == "power" and power is not None else p
    if cfg.time_mode == "window":
        p = _time_window(p, time, cfg, valid, power, shown)
    elif cfg.time_mode == "active":
        p = _active_span(p, time, cfg, valid, shown)
    else:
        p = shown
    p = _resample_axis(p, cfg.n_time, axis=1)
    peak = p.max()
    if peak <= 0:
        return np.zeros((cfg.n_velocity, cfg.n_time), np.float32)
    if cfg.scale == "linear":
        return (p / peak).astype(np.float32)
    db = 10 * np.log10(np.maximum(p / peak, 10 ** (-cfg.floor_db / 10)))
    return (1.0 + db / cfg.floor_db).astype(np.float32)


def preprocess_links(links: dict[str, dict], names, cfg: PreprocessConfig) -> np.ndarray:
    """Stacked inputs [len(names), n_velocity, n_time] from {link: {"p_vt", "velocity", "time", ("valid",
    "power")}}."""
    missing = [n for n in names if n not in links]
    if missing:
        raise InputError(f"sample has no link {missing[0]!r} (has {', '.join(links)})")
    return np.stack([preprocess(links[n]["p_vt"], links[n].get("velocity"), links[n].get("time"), cfg,
                                links[n].get("valid"), links[n].get("power"))
                     for n in names])
