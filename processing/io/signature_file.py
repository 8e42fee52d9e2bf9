"""`signature.h5`: one simulation's signatures, written atomically, carrying the parameters that made it.

Layout (DESIGN.md): root attributes `activity`, `backend`, `seed`, `direction_deg`, `version`, `config`
(JSON); one group per radar link holding `p_vt` [n_velocity, n_time], `velocity` [m/s], `time` [s],
`mean_velocity` [n_time], `range_distribution` [n_range, n_time], `range` [m], `valid` [n_time], `power`
[n_time], the scalars `carrier_hz` (the carrier `velocity` refers to) and `v_max` [m/s], optionally the
range-Doppler map `range_doppler` [n_range, n_rd_velocity, n_rd_time] (float32) with its axes
`range_doppler_velocity` [m/s] and `range_doppler_time` [s] (the range axis is `range`), and optionally
`iq` [n_chirps, n_samples] and `chirp_times` [n_chirps] (s, start of each chirp); group attributes `tx`, `rx`
(m). The root attribute `timing` (JSON, seconds per stage) is optional too.

Size. The range-Doppler map is the largest array: one map per `DSPConfig.rd_stride(PRI)`-th window
(default: about 10 maps per second and never overlapping, `processing.dsp.config.RD_MIN_INTERVAL_S`),
float32, gzip with byte shuffling; a 5 s walk at the seed's settings adds ~0.2 MB per link to ~0.2 MB of
the rest. `DSPConfig(range_doppler=False)` leaves it out. Files of version 1 (no `carrier_hz`, `v_max`,
map) still read: those fields keep their defaults (0, None).
"""
from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from processing.atomic import atomic_path
from processing.dsp.signatures import Signature
from processing.errors import InputError

FORMAT_VERSION = "2"
_ARRAYS = ("p_vt", "velocity", "time", "mean_velocity", "range_distribution", "range", "valid", "power",
           "range_doppler_velocity", "range_doppler_time")
_SCALARS = ("carrier_hz", "v_max")


def write_signature_file(path: str | Path, signatures: dict[str, Signature], *, activity: str, backend: str,
                         seed: int, direction_deg: float, config: dict, iq: dict[str, np.ndarray] | None = None,
                         link_attrs: dict[str, dict] | None = None, chirp_times: dict[str, np.ndarray] | None = None,
                         timing: dict[str, float] | None = None) -> Path:
    """Write `signatures` ({link: Signature}) to `path` atomically (temporary file, fsync, rename).

    Args:
        path: the file to write.
        signatures: {link name: Signature}.
        activity, backend, seed, direction_deg, config: the root attributes (config as JSON).
        iq: {link name: raw IQ [n_chirps, n_samples] complex} of the links whose IQ is kept.
        link_attrs: {link name: {attribute: value}} (e.g. tx, rx positions [3] in m).
        chirp_times: {link name: chirp start times [n_chirps] float64 in s}.
        timing: seconds per stage (root attribute `timing`, JSON).

    Raises `InputError` for a signature without time bins and ValueError for non-finite arrays (a bug)."""
    path = Path(path)
    for name, sig in signatures.items():  # last guard: an empty or NaN signature is never written
        if np.asarray(sig.p_vt).ndim != 2 or np.asarray(sig.p_vt).shape[1] == 0:
            raise InputError(f"{path}: link {name}: no complete DSP window (the recording is shorter than "
                             "window_chirps chirps); nothing written")
        for key in _ARRAYS + (("range_doppler",) if sig.range_doppler is not None else ()):
            value = getattr(sig, key)
            if value is not None and not np.isfinite(np.asarray(value, dtype=float)).all():
                raise ValueError(f"{path}: link {name}: {key} holds non-finite values; nothing written")
    if not -2 ** 63 <= int(seed) < 2 ** 63:  # HDF5 attributes hold 64-bit integers
        raise InputError(f"seed {seed} does not fit a 64-bit integer (use 0..2^63-1)")
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs.update(activity=activity, backend=backend, seed=int(seed), direction_deg=float(direction_deg),
                       version=FORMAT_VERSION, config=json.dumps(config, sort_keys=True, default=str))
        if timing is not None:
            f.attrs["timing"] = json.dumps(timing, sort_keys=True)
        for name, sig in signatures.items():
            g = f.create_group(name)
            for key in _ARRAYS:
                if getattr(sig, key) is not None:
                    g.create_dataset(key, data=np.asarray(getattr(sig, key)), compression="gzip", compression_opts=4)
            for key in _SCALARS:
                g.create_dataset(key, data=np.float64(getattr(sig, key)))
            if sig.range_doppler is not None:
                g.create_dataset("range_doppler", data=np.asarray(sig.range_doppler, np.float32),
                                 compression="gzip", compression_opts=4, shuffle=True)
            if iq is not None and name in iq:
                g.create_dataset("iq", data=iq[name], compression="gzip", compression_opts=1)
            if chirp_times is not None and name in chirp_times:
                g.create_dataset("chirp_times", data=np.asarray(chirp_times[name], np.float64), compression="gzip",
                                 compression_opts=4, shuffle=True)
            for key, value in (link_attrs or {}).get(name, {}).items():
                g.attrs[key] = value
    return path


def read_signature_file(path: str | Path) -> tuple[dict, dict[str, Signature]]:
    """Read a `signature.h5` (DESIGN.md layout) written by `write_signature_file` / `SimulationResult.save`.

    Args:
        path: the file.

    Returns:
        (root attributes with `config` parsed from JSON, {link name: Signature}).
    """
    parts = read_signature_parts(path)
    return parts["attrs"], parts["signatures"]


def read_signature_parts(path: str | Path) -> dict:
    """Everything a `signature.h5` holds (what `SimulationResult.load` rebuilds a result from).

    Args:
        path: the file.

    Returns:
        {"attrs": root attributes with `config` (and `timing`, if stored) parsed from JSON, "signatures":
        {link: Signature}, "iq": {link: IQ [n_chirps, n_samples]} of the links that stored it, "chirp_times":
        {link: chirp start times [n_chirps] s} of the links that stored them, "link_attrs": {link: {name:
        value}}}.
    """
    out: dict[str, Any] = {"signatures": {}, "iq": {}, "chirp_times": {}, "link_attrs": {}}
    with h5py.File(path, "r") as f:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        attrs["config"] = json.loads(attrs.get("config", "{}"))
        if "timing" in attrs:
            attrs["timing"] = json.loads(attrs["timing"])
        for name, g in f.items():
            kw = {fl.name: g[fl.name][()] for fl in fields(Signature) if fl.name in g}
            kw.update({k: float(kw[k]) for k in _SCALARS if k in kw})
            out["signatures"][name] = Signature(**kw)
            for key in ("iq", "chirp_times"):
                if key in g:
                    out[key][name] = g[key][()]
            out["link_attrs"][name] = dict(g.attrs)
    out["attrs"] = attrs
    return out
