"""Reading a dataset folder lazily (`DatasetReader`): the index in memory, arrays from the shards on demand,
counts and selections, and a torch Dataset. The folder layout and the writers are `dataset_store`'s."""
from __future__ import annotations

import os
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import h5py
import numpy as np

from processing.errors import DatasetFormatError, one_line
from processing.io.dataset_store import (_SHARD_NAME, ENTRY_KEYS, ERRORS, INDEX, MAX_ARRAY_BYTES, SHARDS, checksum,
                                         read_jsonl, scan_shards)


class DatasetReader:
    """Read a dataset folder lazily: the index in memory, arrays from the shards on demand.

    Attributes:
        root: the dataset folder.
        entries: one dict per finished item, sorted by item_id (keys: item_id, activity, label,
            direction_deg, direction, backend, group, source, shard, links, params, sha256, ...).
        errors: items that kept failing (item_id, activity, error, ...).
    """

    def __init__(self, root: str | Path):
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(f"dataset folder not found: {self.root}")
        if (self.root / INDEX).is_file():
            by_id = {e["item_id"]: e for e in read_jsonl(self.root / INDEX, ENTRY_KEYS)}
            self.entries = [by_id[k] for k in sorted(by_id)]
            for e in self.entries:
                if not _SHARD_NAME.match(e["shard"]):  # entries name files inside shards/ only
                    raise DatasetFormatError(f"{self.root / INDEX}: item {e['item_id'][:60]!r}: shard "
                                             f"{e['shard'][:60]!r} is not a file name in {SHARDS}/")
        elif (self.root / SHARDS).is_dir():
            self.entries, _ = scan_shards(self.root)
        else:
            raise FileNotFoundError(f"{self.root} holds no dataset (no {INDEX} and no {SHARDS}/)")
        try:
            self.errors = read_jsonl(self.root / ERRORS)
        except DatasetFormatError:
            self.errors = []  # failures are informational: a damaged errors.jsonl must not block reading

    def __len__(self) -> int:
        return len(self.entries)

    def counts(self, by: str = "activity") -> dict[str, int]:
        """Number of entries per value of the entry key `by` (sorted by value; missing key -> 'None')."""
        c = Counter(str(e.get(by)) for e in self.entries)
        return dict(sorted(c.items(), key=lambda kv: _sort_key(kv[0])))

    def select(self, **criteria) -> list[int]:
        """Indices of entries whose keys equal the given values (a list/tuple/set value means any of)."""
        def ok(e):
            for k, v in criteria.items():
                vals = v if isinstance(v, (list, tuple, set, frozenset)) else (v,)
                if e.get(k) not in vals:
                    return False
            return True
        return [i for i, e in enumerate(self.entries) if ok(e)]

    def shard_path(self, i: int) -> Path:
        return self.root / SHARDS / self.entries[i]["shard"]

    def load(self, i: int, links: Sequence[str] | None = None) -> dict[str, dict[str, np.ndarray]]:
        """Arrays of entry `i`: {link: {"p_vt" [V, T], "velocity" [V], "time" [T], "mean_velocity" [T],
        "range_distribution" [R, T], "range" [R], "valid" [T], "power" [T], ("iq")}}."""
        e = self.entries[i]
        names = list(e["links"]) if links is None else list(links)
        missing = [n for n in names if n not in e["links"]]
        if missing:
            raise KeyError(f"item {e['item_id']} has no link {missing[0]!r} (links: {', '.join(e['links'])})")
        try:
            with h5py.File(self.shard_path(i), "r") as f:
                g = f[e["item_id"]]
                if any(g[n][k].nbytes > MAX_ARRAY_BYTES for n in names for k in g[n]):
                    raise OSError("an array is larger than any valid one (corrupt metadata)")
                return {n: {k: g[n][k][()] for k in g[n]} for n in names}
        except (OSError, KeyError) as exc:
            raise DatasetFormatError(f"{self.shard_path(i)}: item {e['item_id'][:60]!r} cannot be read "
                                     f"({one_line(exc, 120)}); re-run the dataset command to repair") from None

    def verify(self, i: int) -> bool:
        """True if the stored arrays of entry `i` can be read and match its recorded checksums."""
        try:
            data = self.load(i)
        except DatasetFormatError:
            return False
        return all(checksum({k: v for k, v in a.items() if k != "iq"}) == self.entries[i]["sha256"][n]
                   for n, a in data.items())

    def torch_dataset(self, indices: Sequence[int] | None = None, links: Sequence[str] = ("radar1", "radar2"),
                      transform=None):
        """A `torch.utils.data.Dataset` over `indices` (default all): item k -> (x, label) where x is
        ``transform({link: p_vt float32 [V, T]})`` or, without a transform, a float32 tensor [n_links, V, T].
        Shards are opened lazily, once per process (safe with DataLoader workers)."""
        import torch

        reader = self

        class _SignatureDataset(torch.utils.data.Dataset):
            def __init__(self):
                self.indices = list(range(len(reader))) if indices is None else [int(i) for i in indices]
                self.links = tuple(links)
                self._files: dict[str, h5py.File] = {}
                self._pid = None

            def __len__(self):
                return len(self.indices)

            def __reduce__(self):  # picklable (spawned DataLoader workers): rebuilt from the reader
                return reader.torch_dataset, (self.indices, self.links, transform)

            def _file(self, shard: str) -> h5py.File:
                if self._pid != os.getpid():  # handles opened before a fork must not be shared
                    self._files, self._pid = {}, os.getpid()
                if shard not in self._files:
                    self._files[shard] = h5py.File(reader.root / SHARDS / shard, "r")
                return self._files[shard]

            def __getitem__(self, k):
                e = reader.entries[self.indices[k]]
                g = self._file(e["shard"])[e["item_id"]]
                maps = {n: np.asarray(g[n]["p_vt"][()], dtype=np.float32) for n in self.links}
                if transform is not None:
                    return transform(maps), int(e["label"])
                return torch.from_numpy(np.stack([maps[n] for n in self.links])), int(e["label"])

        return _SignatureDataset()

    def summary(self) -> str:
        """Counts per activity, direction, backend, link set and source kind, plus errors (text)."""
        lines = [f"{self.root}: {len(self)} items ({sum(len(e['links']) for e in self.entries)} signatures), "
                 f"{len({e['shard'] for e in self.entries})} shards, {len(self.errors)} failed items"]
        for key in ("activity", "direction_deg", "backend", "link_set", "gain_set"):
            c = self.counts(key)
            lines.append(f"  by {key}: " + ", ".join(f"{k}={v}" for k, v in c.items()))
        lines.append(f"  motion groups: {len({e.get('group') for e in self.entries})}")
        for err in self.errors[:10]:
            lines.append(f"  failed {err.get('item_id')}: {err.get('error')}")
        if len(self.errors) > 10:
            lines.append(f"  ... and {len(self.errors) - 10} more failed items in {ERRORS}")
        return "\n".join(lines)


def _sort_key(s: str):
    try:
        return (0, float(s), "")
    except ValueError:
        return (1, 0.0, s)
