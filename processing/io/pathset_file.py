"""`channel.h5`: a channel (one `PathSet` per radar link) with the parameters that made it, bit for bit.

Layout: root attributes `kind` ("rtchannel channel"), `version`, and JSON strings given by the caller (the
radar, the tracing parameters, the timing); one group per link holding `times` [K] float64 (s), `delays`
[K, P] float64 (s, NaN where absent), `gains` [K, P] complex128 (|a|^2 = P_r/P_t), optionally `ids` [P]
int64 and `delay_rates` [K, P] float64 (s/s); the group attribute `link` is the link name. Arrays are
stored in their own dtype with lossless gzip, so a channel reads back bit-identical.
"""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from processing.atomic import atomic_path
from processing.errors import InputError
from processing.pathset import PathSet

KIND = "rtchannel channel"
FORMAT_VERSION = "1"
_OPTIONAL = ("ids", "delay_rates")


def write_pathsets(path: str | Path, paths: dict[str, PathSet], attrs: dict[str, object]) -> Path:
    """Write `paths` ({link name: PathSet}) to `path` atomically (temporary file, rename).

    Args:
        path: the HDF5 file to write.
        paths: the channel, one path set per link.
        attrs: root attributes; dicts and lists are stored as JSON strings (read back as such by
            `read_pathsets`), scalars and strings as they are.

    Returns:
        `path`.
    """
    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=True) as f:
        f.attrs.update(kind=KIND, version=FORMAT_VERSION)
        for key, value in attrs.items():
            f.attrs[key] = json.dumps(value, sort_keys=True, default=str) if isinstance(value, (dict, list)) else value
        for name, ps in paths.items():
            g = f.create_group(name)
            g.attrs["link"] = ps.link
            for key in ("times", "delays", "gains") + _OPTIONAL:
                value = getattr(ps, key)
                if value is not None:
                    value = np.asarray(value)
                    opts = {"compression": "gzip", "compression_opts": 4, "shuffle": True} if value.ndim else {}
                    g.create_dataset(key, data=value, **opts)
    return path


def read_pathsets(path: str | Path, json_attrs: tuple[str, ...] = ()) -> tuple[dict, dict[str, PathSet]]:
    """Read a file written by `write_pathsets`.

    Args:
        path: the file.
        json_attrs: root attributes to parse from JSON.

    Returns:
        (root attributes, {link name: PathSet}) in the order the links were written.

    Raises:
        processing.errors.InputError: the file is not a channel file (one line naming it).
    """
    with h5py.File(path, "r") as f:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        if attrs.get("kind") != KIND:
            raise InputError(f"{path}: not a channel file (written by PathSets.save)")
        for key in json_attrs:
            attrs[key] = json.loads(attrs.get(key, "null"))
        paths = {}
        for name in f:  # creation order (written with track_order)
            g = f[name]
            kw = {key: g[key][()] for key in ("times", "delays", "gains") + _OPTIONAL if key in g}
            link = g.attrs.get("link", name)
            paths[name] = PathSet(link=link.decode() if isinstance(link, bytes) else str(link), **kw)
    return attrs, paths
