"""Preprocessed classifier inputs cached on disk, so a dataset is read and preprocessed once, not per training.

Loading the glasgow preset's 1280 items (HDF5 reads and `preprocess`) took 18 s of a training's start on the
2-core machine, more than an epoch; a study of many trainings paid it every time. The cache holds only X
[N, n_links, V, T] float32 (labels and groups come from the index, which is read anyway) in one ``.npy`` per
key, written atomically. The key is a sha256 over

- the selected items' ids and their stored arrays' checksums (each index entry's ``sha256`` per link: a
  rebuilt or resumed item with other arrays gets another key),
- the links, in order, and every field of the `PreprocessConfig`,
- the source of the code that turns stored arrays into X (`preprocess`, the dataset reader): an edit to it
  invalidates every entry, so a stale cache never outlives a change of the preprocessing.

A cached file is used only if it loads as a plain float32 array of the expected shape with finite values in
[0, 1]; anything else is recomputed and rewritten. Folder: ``$RTCHANNEL_CACHE_DIR/arrays``, else
``$XDG_CACHE_HOME/rtchannel/arrays`` (default ``~/.cache/rtchannel/arrays``), as the scene cache; deleting it
is always safe. The cached route gives the same arrays, bit for bit, as preprocessing again
(tests/test_train_speed.py).
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

VERSION = 1  # the file layout of an entry


def cache_dir() -> Path:
    """The cache folder (see the module docstring)."""
    root = os.environ.get("RTCHANNEL_CACHE_DIR")
    if root:
        return Path(root) / "arrays"
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "rtchannel" / "arrays"


CODE = ("processing.classifier.preprocess", "processing.io.dataset_reader")  # stored arrays -> X


def _code_digest(modules) -> str:
    """sha256 of the source files of `modules` (dotted names)."""
    import importlib
    import inspect

    h = hashlib.sha256()
    for name in modules:
        h.update(Path(inspect.getfile(importlib.import_module(name))).read_bytes())
    return h.hexdigest()


def cache_key(entries: list[dict], links, pre, extra_code=()) -> str:
    """The key of the inputs of `entries` (index entries, in order: ``item_id`` and ``sha256`` {link: checksum})
    on `links` under `pre` (a PreprocessConfig); `extra_code`: further modules whose source makes the inputs
    (e.g. the image reader for real images)."""
    links = list(links)
    h = hashlib.sha256()
    h.update(json.dumps({"version": VERSION, "links": links, "preprocess": pre.model_dump(mode="json"),
                         "code": _code_digest((*CODE, *extra_code))}, sort_keys=True).encode())
    for e in entries:
        sums = e.get("sha256") or {}
        h.update(f"\n{e['item_id']}|".encode() + "|".join(str(sums.get(link)) for link in links).encode())
    return h.hexdigest()


def load_inputs(key: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """The cached X of `key` if it exists and is valid (float32, `shape`, finite values in [0, 1]), else None."""
    path = cache_dir() / f"{key}.npy"
    if not path.is_file():
        return None
    try:
        x = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None
    if x.dtype != np.float32 or x.shape != tuple(shape) or not np.isfinite(x).all() or \
            (x.size and (x.min() < 0 or x.max() > 1)):
        return None
    return x


def store_inputs(key: str, x: np.ndarray) -> Path | None:
    """Write X under `key` (atomically); None when the cache folder cannot be written (the cache is optional)."""
    from processing.atomic import atomic_path

    path = cache_dir() / f"{key}.npy"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(x, dtype=np.float32), allow_pickle=False)
    except OSError:
        return None
    return path


__all__ = ["CODE", "VERSION", "cache_dir", "cache_key", "load_inputs", "store_inputs"]
