"""`signature.h5`: one simulation's signatures, written atomically, carrying the parameters that made it.

Layout (DESIGN.md): root attributes `activity`, `backend`, `seed`, `direction_deg`, `version`, `config`
(JSON); one group per radar link holding `p_vt` [n_velocity, n_time], `velocity` [m/s], `time` [s],
`mean_velocity` [n_time], `range_distribution` [n_range, n_time], `range` [m], `valid` [n_time] and
optionally `iq` [n_chirps, n_samples]; group attributes `tx`, `rx` (m).
"""
from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path

import h5py
import numpy as np

from processing.atomic import atomic_path
from processing.dsp import Signature
from processing.errors import InputError

FORMAT_VERSION = "1"
_ARRAYS = ("p_vt", "velocity", "time", "mean_velocity", "range_distribution", "range", "valid", "power")


def write_signature_file(path: str | Path, signatures: dict[str, Signature], *, activity: str, backend: str,
                         seed: int, direction_deg: float, config: dict, iq: dict[str, np.ndarray] | None = None,
                         link_attrs: dict[str, dict] | None = None) -> Path:
    """Write `signatures` ({link: Signature}) to `path` atomically (temporary file, fsync, rename).

    Raises `InputError` for a signature without time bins and ValueError for non-finite arrays (a bug)."""
    path = Path(path)
    for name, sig in signatures.items():  # last guard: an empty or NaN signature is never written
        if np.asarray(sig.p_vt).ndim != 2 or np.asarray(sig.p_vt).shape[1] == 0:
            raise InputError(f"{path}: link {name}: no complete DSP window (the recording is shorter than "
                             "window_chirps chirps); nothing written")
        for key in _ARRAYS:
            if not np.isfinite(np.asarray(getattr(sig, key), dtype=float)).all():
                raise ValueError(f"{path}: link {name}: {key} holds non-finite values; nothing written")
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs.update(activity=activity, backend=backend, seed=int(seed), direction_deg=float(direction_deg),
                       version=FORMAT_VERSION, config=json.dumps(config, sort_keys=True, default=str))
        for name, sig in signatures.items():
            g = f.create_group(name)
            for key in _ARRAYS:
                g.create_dataset(key, data=np.asarray(getattr(sig, key)), compression="gzip", compression_opts=4)
            if iq is not None and name in iq:
                g.create_dataset("iq", data=iq[name], compression="gzip", compression_opts=1)
            for key, value in (link_attrs or {}).get(name, {}).items():
                g.attrs[key] = value
    return path


def read_signature_file(path: str | Path) -> tuple[dict, dict[str, Signature]]:
    """(root attributes with `config` parsed, {link: Signature}) of a `signature.h5`."""
    with h5py.File(path, "r") as f:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        attrs["config"] = json.loads(attrs.get("config", "{}"))
        sigs = {}
        for name, g in f.items():
            kw = {fl.name: g[fl.name][()] for fl in fields(Signature) if fl.name in g}
            sigs[name] = Signature(**kw)
    return attrs, sigs
