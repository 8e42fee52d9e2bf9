"""Dataset storage: HDF5 shards written atomically, a JSON-lines index, and a lazy reader (+ torch Dataset).

Folder layout::

    DIR/plan.json          the normalised plan (a re-run must use the same plan)
    DIR/shards/<hash>.h5   one shard per finished task: group /<item_id> with attribute `entry` (JSON) and
                           one subgroup per link holding p_vt [V, T], velocity [V], time [T],
                           mean_velocity [T], range_distribution [R, T], range [R], valid [T], power [T]
                           (float32; valid bool) and optionally iq [C, N] (complex64)
    DIR/index.jsonl        one JSON entry per finished item, sorted by item_id (rebuilt from the shards,
                           which are the source of truth)
    DIR/errors.jsonl       items that kept failing: item_id, activity, error

A shard is written to a temporary name, fsynced and renamed, so a shard either exists complete or not at
all. Each entry carries `sha256` {link: checksum of its stored arrays}: datasets compare bit for bit, and
a resumed run re-reads every shard and checks every array against it (`scan_shards(verify=True)`). A
shard that cannot be read, is not a shard, or holds an array that fails its checksum is never deleted:
it is renamed ``*.bad`` (`quarantine`), its verified items are copied into a new shard of the same name
and the failed ones are computed again. Index lines are checked when read (`read_jsonl`): a malformed
line other than a torn last one, or an entry without `item_id`, is a `DatasetFormatError` naming the
file and line.
This module is the lower layer: it never imports `rtchannel`.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from processing.atomic import atomic_path, write_text_atomic
from processing.labels import ACTIVITIES  # noqa: F401 - class order = label index; re-exported
from processing.errors import DatasetFormatError, InputError

SHARD_FORMAT = "rtchannel-dataset-shard/1"
SIGNATURE_ARRAYS = ("p_vt", "velocity", "time", "mean_velocity", "range_distribution", "range", "valid", "power")
INDEX, ERRORS, PLAN, SHARDS = "index.jsonl", "errors.jsonl", "plan.json", "shards"
MAX_ARRAY_BYTES = 1 << 30  # one stored array; a p_vt of a 1 h item is ~60 MB: larger means corrupt metadata
ENTRY_KEYS = {"item_id": str, "shard": str, "links": list, "label": int, "sha256": dict}  # what readers rely on
_SHARD_NAME = re.compile(r"^[A-Za-z0-9_.\-]+\.h5$")  # a plain file name inside shards/ (no path)


def signature_arrays(sig) -> dict[str, np.ndarray]:
    """The stored arrays of a `processing.dsp.signatures.Signature` (float32; `valid` bool)."""
    out = {}
    for key in SIGNATURE_ARRAYS:
        a = np.asarray(getattr(sig, key))
        out[key] = a.astype(bool) if key == "valid" else np.ascontiguousarray(a, dtype=np.float32)
    return out


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """sha256 over names, dtypes, shapes and bytes of `arrays` (sorted by name)."""
    h = hashlib.sha256()
    for key in sorted(arrays):
        a = np.ascontiguousarray(arrays[key])
        h.update(f"{key}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()




def check_record(rec: dict) -> dict:
    """`rec` unchanged if every link has at least one time bin and only finite arrays, else `InputError`
    (an item whose motion is shorter than one DSP window, or a NaN from upstream, is never stored)."""
    for link, arrays in rec["links"].items():
        p_vt = np.asarray(arrays.get("p_vt"))
        if p_vt.ndim != 2 or p_vt.shape[1] == 0:
            raise InputError(f"item {rec['entry'].get('item_id')}: link {link}: no complete DSP window "
                             "(motion shorter than window_chirps chirps)")
        for key, a in arrays.items():
            a = np.asarray(a)
            if a.dtype.kind in "fc" and not np.isfinite(a).all():
                raise InputError(f"item {rec['entry'].get('item_id')}: link {link}: {key} holds non-finite values")
    return rec


def write_shard(path: str | Path, records: Sequence[dict], attrs: dict | None = None) -> Path:
    """Write one shard atomically. `records`: [{"entry": dict with "item_id", "links": {link: {name: array}}}].

    Each entry gets ``sha256`` {link: checksum} and ``links`` [names] before it is stored.
    """
    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = SHARD_FORMAT
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
        for rec in records:
            entry = dict(rec["entry"])
            g = f.create_group(entry["item_id"])
            entry["links"] = list(rec["links"])
            entry["sha256"] = {}
            for link, arrays in rec["links"].items():
                lg = g.create_group(link)
                stored = {k: v for k, v in arrays.items() if k != "iq"}
                entry["sha256"][link] = checksum(stored)
                for key, a in arrays.items():
                    big = a.ndim == 2
                    lg.create_dataset(key, data=a, compression="gzip" if big else None,
                                      compression_opts=1 if big else None, shuffle=big)
            g.attrs["entry"] = json.dumps(entry, sort_keys=True, default=_json_default)
    return path


def read_shard_entries(path: str | Path, verify: bool = False) -> tuple[list[dict], list[str]]:
    """(entries stored in one shard, each with "shard" set to the file name; ids of entries that failed).

    With `verify`, every stored array is read and compared with the entry's sha256 (an entry whose data
    cannot be read or does not match is returned in the second list, not the first). Raises OSError,
    KeyError or ValueError if the file is not a readable shard at all.
    """
    path = Path(path)
    good, failed = [], []
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != SHARD_FORMAT:
            raise OSError(f"{path.name}: not a dataset shard")
        for name, g in f.items():
            entry = {**json.loads(g.attrs["entry"]), "shard": path.name}
            if entry.get("item_id") != name or not isinstance(entry.get("sha256"), dict):
                raise InputError(f"{path.name}: group {name[:40]!r} holds an inconsistent entry")
            if verify and not _verified(g, entry):
                failed.append(name)
            else:
                good.append(entry)
    return good, failed


def _verified(g, entry: dict) -> bool:
    """True if every link's stored arrays (iq excluded) read back and match the entry's sha256."""
    try:
        links = list(entry["links"])
        if set(links) != set(entry["sha256"]) or set(links) != set(g):
            return False
        for link in links:
            if any(g[link][k].nbytes > MAX_ARRAY_BYTES for k in g[link]):  # corrupt dims must not allocate
                return False
            arrays = {k: g[link][k][()] for k in g[link] if k != "iq"}
            if checksum(arrays) != entry["sha256"][link]:
                return False
            if "iq" in g[link]:
                g[link]["iq"][()]  # readable (iq carries no checksum: it is optional raw data)
        return True
    except (OSError, KeyError, ValueError, TypeError):  # h5py raises OSError for a corrupt chunk
        return False


def quarantine(path: str | Path) -> Path:
    """Rename `path` to ``<name>.bad`` (or ``.bad.1``, ... if taken) and return the new path; never deletes."""
    path = Path(path)
    target, k = path.with_name(path.name + ".bad"), 0
    while target.exists():
        k += 1
        target = path.with_name(f"{path.name}.bad.{k}")
    os.replace(path, target)
    return target


def _salvage(path: Path, keep: list[str]) -> Path:
    """Quarantine shard `path` and write its verified items `keep` into a new shard of the same name."""
    bad = quarantine(path)
    if keep:
        with h5py.File(bad, "r") as src, atomic_path(path) as tmp, h5py.File(tmp, "w") as dst:
            for k, v in src.attrs.items():
                dst.attrs[k] = v
            for name in keep:
                src.copy(src[name], dst, name=name)
    return bad


def remove_orphans(root: str | Path) -> int:
    """Delete temporary files left by an interrupted writer; returns how many."""
    n = 0
    for p in list(Path(root).glob("*.tmp")) + list((Path(root) / SHARDS).glob("*.tmp")):
        p.unlink(missing_ok=True)
        n += 1
    return n


def scan_shards(root: str | Path, verify: bool = False, repair: bool = False) -> tuple[list[dict], list[str]]:
    """(entries of every readable shard, deduplicated and sorted by item_id; names of bad shards).

    A shard is bad if it cannot be read as a shard or (with `verify`) holds an item whose arrays fail
    their checksum; its verified entries are still returned. With `repair`, a bad shard is renamed
    ``*.bad`` (never deleted) and, if some of its items verified, they are copied into a new shard of
    the original name, so only the failed items are missing (and get computed again by the runner).
    An item found in two shards (never produced by the runner) is kept once, from the first shard by name.
    """
    seen: dict[str, dict] = {}
    bad = []
    for p in sorted((Path(root) / SHARDS).glob("*.h5")):
        try:
            entries, failed = read_shard_entries(p, verify=verify)
        except (OSError, KeyError, ValueError, TypeError):
            entries, failed = [], None
        if failed is None or failed:
            bad.append(p.name)
            if repair:
                _salvage(p, [e["item_id"] for e in entries])
        for e in entries:
            seen.setdefault(e["item_id"], e)
    return [seen[k] for k in sorted(seen)], bad


def write_index(root: str | Path, entries: Sequence[dict]) -> Path:
    """Write DIR/index.jsonl atomically (entries sorted by item_id)."""
    path = Path(root) / INDEX
    ordered = sorted(entries, key=lambda e: e["item_id"])
    lines = [json.dumps(e, sort_keys=True, default=_json_default) for e in ordered]
    write_text_atomic(path, "".join(line + "\n" for line in lines))
    return path


def append_jsonl(path: str | Path, rows: Sequence[dict]) -> None:
    """Append rows to a JSON-lines file (flushed; a torn last line is ignored by the readers)."""
    with open(path, "a") as f:
        f.write("".join(json.dumps(r, sort_keys=True, default=_json_default) + "\n" for r in rows))
        f.flush()


def read_jsonl(path: str | Path, required: dict[str, type] | None = None) -> list[dict]:
    """Rows of a JSON-lines file ([] if missing); a torn last line (killed writer) and blank lines are skipped.

    Raises `DatasetFormatError` naming the file and line for any other line that is not a JSON object
    or lacks one of the `required` keys {name: type}.
    """
    p = Path(path)
    if not p.is_file():
        return []
    try:
        lines = p.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as e:
        raise DatasetFormatError(f"{p}: cannot read: {e.strerror or e}") from None
    last = max((i for i, ln in enumerate(lines) if ln.strip()), default=-1)
    rows = []
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            rows.append(parse_jsonl_line(line, required))
        except (json.JSONDecodeError, RecursionError):
            if i == last:
                continue
            raise DatasetFormatError(f"{p}: line {i + 1}: not valid JSON") from None
        except DatasetFormatError as e:
            raise DatasetFormatError(f"{p}: line {i + 1}: {e}") from None
    return rows


def parse_jsonl_line(line: str, required: dict[str, type] | None = None) -> dict:
    """One JSON-lines row: a JSON object holding the `required` keys {name: type}. Raises the JSON error
    for text that is not JSON, DatasetFormatError (without a location) for anything else wrong."""
    row = json.loads(line)
    if not isinstance(row, dict):
        raise DatasetFormatError(f"expected a JSON object, got {type(row).__name__}")
    for key, typ in (required or {}).items():
        v: Any = row.get(key)
        ok = isinstance(v, typ) and isinstance(v, bool) == (typ is bool)
        if ok and typ is list:  # lists and maps of the index hold names (links) and checksums
            ok = all(isinstance(x, str) for x in v)
        elif ok and typ is dict:
            ok = all(isinstance(k, str) and isinstance(x, str) for k, x in v.items())
        if not ok:
            raise DatasetFormatError(f"entry lacks a valid {key!r} ({typ.__name__})")
    return row


def index_health(root: str | Path) -> dict:
    """What `dataset --info` reports beyond the counts: the index's unreadable lines and what the shards hold.

    Returns {"index_lines": lines with an entry, "bad_lines": [1-based numbers of lines that are not valid
    entries, a torn last line included], "shard_items": items the readable shards hold, "bad_shards": [names],
    "missing_from_index": items in shards the index does not list}.
    """
    root = Path(root)
    good, bad = set(), []
    index = root / INDEX
    if index.is_file():
        for i, line in enumerate(index.read_text(encoding="utf-8", errors="replace").splitlines()):
            if not line.strip():
                continue
            try:
                good.add(parse_jsonl_line(line, ENTRY_KEYS)["item_id"])
            except (DatasetFormatError, json.JSONDecodeError, RecursionError):
                bad.append(i + 1)
    in_shards, bad_shards = scan_shards(root) if (root / SHARDS).is_dir() else ([], [])
    ids = {e["item_id"] for e in in_shards}
    return {"index_lines": len(good), "bad_lines": bad, "shard_items": len(ids), "bad_shards": bad_shards,
            "missing_from_index": len(ids - good)}


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, (Path, tuple, set)):
        return str(o) if isinstance(o, Path) else list(o)
    return str(o)
