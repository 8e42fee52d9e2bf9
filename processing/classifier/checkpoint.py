"""Classifier checkpoints: written atomically, read with every field checked before anything is built.

A checkpoint is a `torch.save` of plain dicts/lists/tensors, read with ``weights_only=True`` (no code
runs while loading): format version, model config, preprocessing config, class names, link names
(branch order), state dict, training history and metadata. Version 2 is a seed ensemble
(`processing.classifier.ensemble`): an empty state dict and a list "members" of state dicts of the same
network; version 1 files are still read, and version-1 readers refuse version 2 instead of using one member.
Loading checks, in this order, so that a damaged or hostile file gives one line naming the file and the field
and never allocates more than the limits of `ModelConfig`: file size, the blob's keys and types, both
configurations (pydantic bounds, including the parameter and activation limits), classes/links against the
configuration, the preprocessing size against the network input, the members' total parameters, then every
state-dict key, shape, dtype and value (finite) against a freshly built network.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

import torch
from pydantic import ValidationError

from processing.atomic import atomic_path
from processing.classifier.ensemble import MAX_MEMBERS, SoftVote, members_of
from processing.classifier.model import MAX_PARAMETERS, ModelConfig, build_model
from processing.classifier.predictor import Classifier
from processing.classifier.preprocess import PreprocessConfig
from processing.errors import CheckpointError, one_line

CHECKPOINT_VERSION = 1
ENSEMBLE_VERSION = 2
MAX_CHECKPOINT_BYTES = 1 << 30  # the largest allowed network (5e7 float32 parameters) is 0.2 GB
# Preprocessing fields added after checkpoints were already written, with the value that reproduces what
# those models were trained on (a missing field must not silently switch an old model to new behaviour).
LEGACY_PREPROCESS = {"active_valid_only": False, "window_valid_only": False, "window_power": False}
_REQUIRED = {"version": int, "model_config": dict, "preprocess": dict, "classes": list, "links": list,
             "state_dict": dict}


def save_checkpoint(path: str | Path, clf, history: dict | None = None, extra: dict | None = None) -> Path:
    """Write `clf` (weights, configs, class and link names) plus history/metadata to `path` atomically.

    Raises CheckpointError (nothing written) if a weight is not finite: a diverged model is never saved.
    """
    path = Path(path)
    states = [m.state_dict() for m in members_of(clf.model)]
    for state in states:
        for key, t in state.items():
            if t.is_floating_point() and not bool(torch.isfinite(t).all()):
                raise CheckpointError(f"{path}: weight {key} holds non-finite values; the model was not saved")
    vote = isinstance(clf.model, SoftVote)
    blob = {"version": ENSEMBLE_VERSION if vote else CHECKPOINT_VERSION,
            "model_config": clf.model.cfg.model_dump(mode="json"),
            "preprocess": clf.preprocess.model_dump(mode="json"), "classes": list(clf.classes),
            "links": list(clf.links), "state_dict": {} if vote else states[0], "history": history or {},
            "meta": {**clf.meta, **(extra or {})}}
    if vote:
        blob["members"] = states
    with atomic_path(path) as tmp:
        torch.save(blob, tmp)
    return path


def _config(path: Path, cls, data: dict, field: str):
    try:
        return cls(**data)
    except ValidationError as e:
        first = e.errors()[0]
        loc = ".".join(str(x) for x in first.get("loc", ())) or "(root)"
        raise CheckpointError(f"{path}: {field}.{loc}: {one_line(first.get('msg', 'invalid'))}") from None
    except TypeError as e:  # keys that are not strings
        raise CheckpointError(f"{path}: {field}: {one_line(e)}") from None


def _names(path: Path, value, field: str, n: int) -> list[str]:
    if not all(isinstance(v, str) and v for v in value) or len(set(value)) != len(value):
        raise CheckpointError(f"{path}: {field} must be distinct non-empty names")
    if len(value) != n:
        raise CheckpointError(f"{path}: {field} has {len(value)} names but the network has {n}")
    return list(value)


def _check_state(path: Path, state, model, field: str = "state_dict") -> None:
    if not isinstance(state, dict):
        raise CheckpointError(f"{path}: {field} is a {type(state).__name__}, not a dict")
    want = model.state_dict()
    missing = [k for k in want if k not in state]
    extra = [k for k in state if k not in want]
    if missing:
        raise CheckpointError(f"{path}: {field} lacks {missing[0]!r}" + (f" (and {len(missing) - 1} more)"
                                                                        if len(missing) > 1 else ""))
    if extra:
        raise CheckpointError(f"{path}: {field} has unexpected {str(extra[0])[:60]!r}"
                              + (f" (and {len(extra) - 1} more)" if len(extra) > 1 else ""))
    for key, ref in want.items():
        t = state[key]
        if not isinstance(t, torch.Tensor):
            raise CheckpointError(f"{path}: {field} {key!r} is a {type(t).__name__}, not a tensor")
        if tuple(t.shape) != tuple(ref.shape):
            raise CheckpointError(f"{path}: {field} {key!r} has shape {list(t.shape)} but the network needs "
                                  f"{list(ref.shape)}")
        if t.is_floating_point() != ref.is_floating_point() or t.is_complex():
            raise CheckpointError(f"{path}: {field} {key!r} has dtype {t.dtype}, expected {ref.dtype}")
        if t.is_floating_point() and not bool(torch.isfinite(t).all()):
            raise CheckpointError(f"{path}: {field} {key!r} holds non-finite values")


def _member_states(path: Path, blob: dict) -> list:
    """The state dicts a blob holds: its state dict (version 1) or its members (version 2)."""
    if blob["version"] == CHECKPOINT_VERSION:
        return [blob["state_dict"]]
    members = blob.get("members")
    if not isinstance(members, list) or not 2 <= len(members) <= MAX_MEMBERS:
        raise CheckpointError(f"{path}: an ensemble checkpoint needs a list 'members' of 2 to {MAX_MEMBERS} "
                              "state dicts")
    return members


def _networks(path: Path, cfg: ModelConfig, states: list):
    """The network (or `SoftVote` of networks) holding `states`, each checked before it is loaded."""
    nets = [build_model(cfg)]
    n_params = sum(p.numel() for p in nets[0].parameters())
    if len(states) * n_params > MAX_PARAMETERS:  # checked before the other members are allocated
        raise CheckpointError(f"{path}: {len(states)} members of {n_params:.3g} parameters exceed the limit of "
                              f"{MAX_PARAMETERS:.3g}")
    nets += [build_model(cfg) for _ in states[1:]]
    for k, (net, state) in enumerate(zip(nets, states)):
        _check_state(path, state, net, "state_dict" if len(states) == 1 else f"members[{k}]")
        net.load_state_dict(state)
        net.eval()
    return nets[0] if len(nets) == 1 else SoftVote(nets)


def load_checkpoint(path: str | Path):
    """The `Classifier` stored by `save_checkpoint`.

    Raises:
        FileNotFoundError: no such file.
        CheckpointError: anything else wrong with it (one line naming the file and the field).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"model file not found: {path}")
    try:
        size = path.stat().st_size
        if zipfile.is_zipfile(path):  # torch's format: a compressed member could unpack to anything
            with zipfile.ZipFile(path) as z:
                size = max(size, sum(info.file_size for info in z.infolist()))
        if size > MAX_CHECKPOINT_BYTES:
            raise CheckpointError(f"{path}: {size / 2**20:.0f} MiB is larger than any valid checkpoint "
                                  f"({MAX_CHECKPOINT_BYTES >> 20} MiB)")
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except CheckpointError:
        raise
    except Exception as e:  # noqa: BLE001 - unpickling failures come in many types
        raise CheckpointError(f"{path} is not a classifier checkpoint ({type(e).__name__})") from None
    if not isinstance(blob, dict) or blob.get("version") not in (CHECKPOINT_VERSION, ENSEMBLE_VERSION):
        raise CheckpointError(f"{path} is not a version-{CHECKPOINT_VERSION} or -{ENSEMBLE_VERSION} classifier "
                              "checkpoint")
    for key, typ in _REQUIRED.items():
        if not isinstance(blob.get(key), typ):
            raise CheckpointError(f"{path}: {'missing' if key not in blob else 'invalid'} field {key!r} "
                                  f"(expected {typ.__name__})")
    cfg = _config(path, ModelConfig, blob["model_config"], "model_config")  # bounds sizes before allocating
    pre = _config(path, PreprocessConfig, {**LEGACY_PREPROCESS, **blob["preprocess"]}, "preprocess")
    if (pre.n_velocity, pre.n_time) != tuple(cfg.input_size):
        raise CheckpointError(f"{path}: preprocess makes {pre.n_velocity} x {pre.n_time} images but the network "
                              f"takes {cfg.input_size[0]} x {cfg.input_size[1]}")
    classes = _names(path, blob["classes"], "classes", cfg.n_classes)
    links = _names(path, blob["links"], "links", cfg.n_branches)
    model = _networks(path, cfg, _member_states(path, blob))
    model.eval()
    meta = dict(blob["meta"]) if isinstance(blob.get("meta"), dict) else {}
    meta["history"] = blob["history"] if isinstance(blob.get("history"), dict) else {}
    return Classifier(model=model, preprocess=pre, classes=classes, links=links, meta=meta)


__all__ = ["CHECKPOINT_VERSION", "ENSEMBLE_VERSION", "MAX_CHECKPOINT_BYTES", "load_checkpoint", "save_checkpoint"]
