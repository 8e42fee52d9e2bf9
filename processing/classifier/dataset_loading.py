"""Simulated datasets and real image folders loaded into one preprocessed training or test set.

`load_dataset` reads dataset specs of the query language (`processing.io.dataset_query`:
``DIR[:key=v1|v2,...]``) and ``images:DIR`` folders of labelled real images, one after another, into a
`Dataset` (arrays preprocessed with the model's settings, cached on disk by `array_cache`). Split from
`processing.classifier.experiment`, which re-exports these names.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.classifier.preprocess import PreprocessConfig
from processing.classifier.training import dataset_arrays
from processing.errors import InputError
from processing.labels import ACTIVITIES

DEFAULT_LINKS = ("radar1", "radar2")


@dataclass
class Dataset:
    """Classifier inputs loaded from dataset specs.

    Attributes:
        x: preprocessed inputs [N, n_links, V, T] float32.
        y: labels [N] int64 (indices into `processing.labels.ACTIVITIES`).
        groups: motion-source group of each item [N] (grouped splits keep a group on one side).
        names: item ids [N].
        entries: the index entries [N] (every parameter that made each item).
        spec: the specs, joined by " + ".
        seconds: loading time [s].
        sources: index of the spec each item came from [N] (for per-dataset weights); None: one source.
        left_out: real images not used, counted by reason (e.g. an activity that is not a class).
    """

    x: np.ndarray
    y: np.ndarray
    groups: list[str]
    names: list[str]
    entries: list[dict]
    spec: str
    seconds: float = 0.0
    sources: np.ndarray | None = None
    left_out: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        counts = ", ".join(f"{ACTIVITIES[k]}={n}" for k, n in zip(*np.unique(self.y, return_counts=True)))
        return f"<Dataset {self.spec!r}: {len(self.y)} items ({counts}), inputs [{' x '.join(map(str, self.x.shape))}]>"


def _specs(data) -> list[str]:
    if isinstance(data, (str, Path)):
        return [str(data)]
    specs = [str(d) for d in data]
    if not specs:
        raise InputError("no dataset given")
    return specs


def load_dataset(data, links=DEFAULT_LINKS, preprocess: PreprocessConfig | None = None,
                 progress: bool = False, cache: bool = True, labels: dict | str | Path | None = None) -> Dataset:
    """Load and preprocess the items of one or several dataset specs into one `Dataset`.

    Args:
        data: a spec ``DIR[:FILTER]`` (str or Path), a spec of real labelled images ``images:DIR[:FILTER]``
            (`processing.classifier.real_data`; single-link models), or a sequence of them.
        links: the radar links to load (one network branch each).
        preprocess: the preprocessing (default `PreprocessConfig()`).
        progress: show a progress bar.
        cache: read the preprocessed inputs from the on-disk cache when they are there, and write them there
            after preprocessing (`processing.classifier.array_cache`; the same arrays either way).
        labels: for ``images:`` specs whose file names are not Glasgow names: {file name: (activity, subject)}
            or the path of a CSV ``file,activity[,subject]``.
    """
    from processing.classifier.real_data import image_arrays, is_image_spec
    from processing.io.dataset_query import open_spec

    pre = PreprocessConfig() if preprocess is None else preprocess
    if isinstance(labels, (str, Path)):
        from processing.realdata.real_images import read_labels_csv

        labels = read_labels_csv(labels)
    t0 = time.perf_counter()
    parts, names, entries = [], [], []
    left_out: dict[str, int] = {}
    for spec in _specs(data):
        if is_image_spec(spec):
            x, y, groups, img_names, img_entries, skipped = image_arrays(spec, links, pre, labels, cache=cache)
            parts.append((x, y, groups))
            names += img_names
            entries += img_entries
            for why, n in skipped.items():
                left_out[why] = left_out.get(why, 0) + n
            continue
        reader, idx = open_spec(spec)
        try:
            parts.append(_cached_arrays(reader, idx, list(links), pre, progress) if cache else
                         dataset_arrays(reader, idx, list(links), pre, progress=progress))
        except (KeyError, ValueError) as e:
            raise InputError(f"{spec}: {str(e).strip(chr(39) + chr(34))}") from None
        names += [reader.entries[i]["item_id"] for i in idx]
        entries += [reader.entries[i] for i in idx]
    x = np.concatenate([p[0] for p in parts])
    y = np.concatenate([p[1] for p in parts])
    groups = [g for p in parts for g in p[2]]
    sources = np.concatenate([np.full(len(p[1]), k, np.int64) for k, p in enumerate(parts)])
    return Dataset(x=x, y=y, groups=groups, names=names, entries=entries, spec=" + ".join(_specs(data)),
                   seconds=time.perf_counter() - t0, sources=sources, left_out=left_out)


def _cached_arrays(reader, idx, links, pre: PreprocessConfig, progress: bool):
    """`dataset_arrays` through the on-disk cache of preprocessed inputs (labels and groups from the index)."""
    from processing.classifier import array_cache

    chosen = [reader.entries[i] for i in idx]
    if any(link not in e["links"] for e in chosen for link in links):  # dataset_arrays names the missing link
        return dataset_arrays(reader, idx, links, pre, progress=progress)
    key = array_cache.cache_key(chosen, links, pre)
    x = array_cache.load_inputs(key, (len(chosen), len(links), pre.n_velocity, pre.n_time))
    if x is None:
        x, y, groups = dataset_arrays(reader, idx, links, pre, progress=progress)
        array_cache.store_inputs(key, x)
        return x, y, groups
    y = np.array([int(e["label"]) for e in chosen], np.int64)
    return x, y, [str(e.get("group", e.get("item_id", i))) for i, e in zip(idx, chosen)]


__all__ = ["DEFAULT_LINKS", "Dataset", "load_dataset"]
