"""The dataset query language: a dataset is named by a *spec*, ``DIR`` or ``DIR:FILTER``, where FILTER is
comma-separated conditions on index entries: ``key=v1|v2`` (any of), ``key!=v1|v2`` (none of) or
``key~text`` (substring, case-insensitive); keys may be dotted into nested fields (``params.motion.kind=file``);
numbers compare numerically (within 1e-9), ``none``/``null`` match a missing key.

Example: ``out/seed:direction=1|3|5|7|9|11|13|15|17,backend=points``. Used by the CLI (`train`, `evaluate`,
`crossval`, `compare --data`) and from Python::

    from processing.io.dataset_query import open_spec
    reader, indices = open_spec("out/seed:activity=walk|fall,direction=1")
"""
from __future__ import annotations

import re
from pathlib import Path

from processing.errors import InputError

_COND = re.compile(r"^\s*([A-Za-z0-9_.]+)\s*(!=|=|~)\s*(.*?)\s*$")

Condition = tuple[str, str, list[str]]


class QueryError(InputError):
    """A dataset spec that cannot be parsed, names no dataset, or selects nothing."""


def parse_spec(spec: str) -> tuple[Path, list[Condition]]:
    """(dataset folder, [(key, op, values)]) of ``DIR[:key=v1|v2,key!=v,key~text]``; QueryError on a bad
    condition."""
    path, conds = spec, []
    head, sep, tail = spec.rpartition(":")
    if sep and head and re.search(r"(!=|=|~)", tail):
        path = head
        for part in filter(None, (p.strip() for p in tail.split(","))):
            m = _COND.match(part)
            if not m:
                raise QueryError(f"bad filter condition {part!r} in {spec!r} (use key=v1|v2, key!=v or key~text)")
            conds.append((m.group(1), m.group(2), m.group(3).split("|")))
    return Path(path), conds


def lookup(entry: dict, key: str):
    """The value of a dotted `key` in a nested index entry, or None when any part is missing."""
    v = entry
    for k in key.split("."):
        if not isinstance(v, dict) or k not in v:
            return None
        v = v[k]
    return v


def _equal(value, text: str) -> bool:
    if value is None:
        return text.lower() in ("none", "null", "")
    try:
        return abs(float(value) - float(text)) < 1e-9
    except (TypeError, ValueError):
        return str(value).lower() == text.lower()


def matches(entry: dict, conds: list[Condition]) -> bool:
    """Whether an index entry meets every condition."""
    for key, op, vals in conds:
        v = lookup(entry, key)
        if op == "~" and not any(t.lower() in str(v).lower() for t in vals):
            return False
        if op == "=" and not any(_equal(v, t) for t in vals):
            return False
        if op == "!=" and any(_equal(v, t) for t in vals):
            return False
    return True


def select(reader, conds: list[Condition]) -> list[int]:
    """Indices of `reader.entries` meeting every condition of a parsed spec."""
    return [i for i, e in enumerate(reader.entries) if matches(e, conds)]


def open_spec(spec: str):
    """(DatasetReader, selected indices) of a dataset spec; QueryError if it is missing or selects nothing."""
    from processing.io.dataset_reader import DatasetReader

    path, conds = parse_spec(spec)
    try:
        reader = DatasetReader(path)
    except FileNotFoundError as e:
        raise QueryError(str(e)) from None
    idx = select(reader, conds)
    if not idx:
        raise QueryError(f"no dataset entries match {spec!r} ({len(reader)} entries in {path})")
    return reader, idx


__all__ = ["QueryError", "parse_spec", "lookup", "matches", "select", "open_spec"]
