"""Real labelled spectrogram images as classifier training data: the dataset spec ``images:DIR[:FILTER]``.

Real recordings reach training only through this explicit path (fine-tuning, transfer studies); every real
image a model saw is recorded in its checkpoint (`seen_images`) so that an evaluation on real images can
leave those out (`processing.classifier.images.split_seen`).

Spec: ``images:DIR`` takes every image under DIR whose activity is one of the model's classes (labels from
Glasgow file names like ``1P36A01R01.png``, or from a labels CSV ``file,activity[,subject]``); a filter after
a last colon selects people and activities, conditions separated by commas, alternatives by ``|``:
``images:DIR:people=P36-P45|P50,activity=walk|fall``. Images of other activities (drink) are left out and
counted. Each image is an item of the model's one link: its p(v,t) goes through the model's
`PreprocessConfig` exactly as in `rtchannel evaluate --images` (`processing.classifier.images`), and its
group is its person (``subject:P36``), so grouped splits keep a person on one side. The preprocessed inputs
go through the on-disk cache (`array_cache`), keyed by the images' sha256.
"""
from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

import numpy as np

from processing.labels import ACTIVITIES
from processing.realdata.real_images import RealImageError, parse_people

PREFIX = "images:"
_FILTER_KEYS = ("people", "activity")
# the code that turns an image file into a classifier input besides `preprocess` (part of the cache key)
IMAGE_CODE = ("processing.realdata.real_images", "processing.realdata.spectrogram_image",
              "processing.realdata.colormaps")


def is_image_spec(spec) -> bool:
    """True for a dataset spec naming real images (``images:DIR[:FILTER]``)."""
    return isinstance(spec, (str, Path)) and str(spec).startswith(PREFIX)


def parse_image_spec(spec: str) -> tuple[Path, frozenset[int] | None, frozenset[str] | None]:
    """(folder, people or None, activities or None) of ``images:DIR[:people=P36-P45|P50,activity=walk|fall]``."""
    body = str(spec)[len(PREFIX):]
    folder, people, acts = body, None, None
    head, sep, tail = body.rpartition(":")
    if sep and "=" in tail and not Path(body).exists():
        folder = head
        for cond in tail.split(","):
            key, eq, value = (s.strip() for s in cond.partition("="))
            if not eq or key not in _FILTER_KEYS or not value:
                raise RealImageError(f"{spec}: bad filter {cond.strip()!r} (use people=P36-P45|P50 or "
                                     "activity=walk|fall)")
            if key == "people":
                people = parse_people(value.replace("|", ","))
            else:
                acts = frozenset(v.strip().lower() for v in value.split("|") if v.strip())
    if not folder:
        raise RealImageError(f"{spec}: no folder after '{PREFIX}'")
    return Path(folder), people, acts


def file_sha256(path: str | Path) -> str:
    """sha256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def image_arrays(spec: str, links, pre, labels: dict | None = None, classes=ACTIVITIES, cache: bool = True):
    """Classifier inputs of the real images a spec names.

    Args:
        spec: ``images:DIR[:FILTER]`` (module docstring).
        links: the model's links; exactly one (an image is one radar).
        pre: the `PreprocessConfig`.
        labels: {file name: (activity, subject)} for names that are not Glasgow names (`read_labels_csv`).
        classes: the model's classes; images of other activities are left out.
        cache: use the on-disk cache of preprocessed inputs.

    Returns:
        (x [N, 1, V, T] float32, y [N] int64, groups [N], names [N], entries [N], left_out) where entries
        describe each image (``item_id`` ``images:REL``, label, activity, group, subject, ``image``: folder,
        file relative to it, sha256) and left_out counts the images not used by reason.

    Raises:
        RealImageError: more than one link, a missing or empty folder, an image without a usable label, no
            image left.
    """
    from processing.classifier import array_cache
    from processing.classifier.preprocess import preprocess_links
    from processing.realdata.real_images import image_label, list_images, read_real_image
    from processing.realdata.spectrogram_image import ContradictoryNameError

    links = list(links)
    if len(links) != 1:
        raise RealImageError(f"{spec}: an image is one radar but the model has {len(links)} links "
                             f"({', '.join(links)}); train a single-radar model (--links radar1)")
    folder, people, acts = parse_image_spec(spec)
    left_out: dict[str, int] = {}
    entries: list[dict] = []
    for path in list_images(folder):
        rel = path.relative_to(folder).as_posix()
        try:
            act, subj = image_label(path, labels)
        except ContradictoryNameError as bad:
            warnings.warn(f"{rel}: skipped, its name contradicts itself ({str(bad).split(': ', 1)[-1]})", stacklevel=2)
            left_out["name contradicts itself"] = left_out.get("name contradicts itself", 0) + 1
            continue
        if (people is not None and (subj is None or subj not in people)) or (acts is not None and act not in acts):
            continue
        if act not in classes:
            left_out[f"{act}: not a class"] = left_out.get(f"{act}: not a class", 0) + 1
            continue
        sha = file_sha256(path)
        group = f"subject:P{subj}" if subj is not None else f"image:{rel}"
        entries.append({"item_id": f"{PREFIX}{rel}", "label": list(classes).index(act), "activity": act,
                        "group": group, "subject": None if subj is None else f"P{subj}", "links": links,
                        "sha256": {links[0]: sha}, "source": "real",
                        "image": {"folder": str(folder), "file": rel, "sha256": sha}, "path": path})
    if not entries:
        raise RealImageError(f"{spec}: no image of the classes {', '.join(classes)} selected")
    shape = (len(entries), 1, pre.n_velocity, pre.n_time)
    key = array_cache.cache_key(entries, links, pre, extra_code=IMAGE_CODE) if cache else None
    x = array_cache.load_inputs(key, shape) if key is not None else None
    if x is None:
        rows, kept = [], []  # type: list[np.ndarray], list[dict]
        for e in entries:
            try:
                sig = read_real_image(e["path"])
            except RealImageError as err:
                warnings.warn(f"skipping unreadable image {err}", stacklevel=2)
                left_out["unreadable"] = left_out.get("unreadable", 0) + 1
                continue
            rows.append(preprocess_links({links[0]: {"p_vt": sig.p_vt, "velocity": sig.velocity, "time": sig.time,
                                                     "valid": sig.valid, "power": sig.power}}, links, pre))
            kept.append(e)
        if not kept:
            raise RealImageError(f"{spec}: none of the {len(entries)} images could be read")
        x = np.stack(rows).astype(np.float32)
        if key is not None and len(kept) == len(entries):  # a partly unreadable folder is read again next time
            array_cache.store_inputs(key, x)
        entries = kept
    for e in entries:
        e.pop("path")
    y = np.array([e["label"] for e in entries], np.int64)
    return (x, y, [e["group"] for e in entries], [e["item_id"][len(PREFIX):] for e in entries], entries, left_out)


def seen_images(entries: list[dict], train_idx, val_idx) -> list[dict]:
    """The real images among `entries` that a training used: [{"file", "sha256", "folder", "role"}] with role
    "train" (fitted) or "validation" (early stopping, model selection)."""
    out = []
    for role, idx in (("train", train_idx), ("validation", val_idx)):
        for i in np.asarray(idx, dtype=np.int64):
            img = entries[int(i)].get("image")
            if img:
                out.append({"file": img["file"], "sha256": img["sha256"], "folder": img["folder"], "role": role})
    return out


__all__ = ["IMAGE_CODE", "PREFIX", "file_sha256", "image_arrays", "is_image_spec", "parse_image_spec", "seen_images"]
