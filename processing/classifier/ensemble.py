"""Seed ensembles: networks trained alike (same data and settings, other seeds) voting with their mean class
probability (soft voting).

Why (issue 27): models trained on the same simulated Glasgow dataset with different seeds agree on simulated
validation (88-98 %) but disagree on real recordings by up to 24 points. The classes are separable in
simulation, and where the real images lie, between the simulated clusters, each seed puts the boundary
elsewhere. Averaging the members' probabilities averages over those placements, the variance reduction of
deep ensembles (Lakshminarayanan, Pritzel and Blundell, NeurIPS 2017). It costs one training per member and
one forward pass per member at inference; nothing in it is fitted to real data.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from processing.classifier.predictor import Classifier
from processing.errors import InputError

MAX_MEMBERS = 16  # bounds what a checkpoint may ask to allocate (members x the network's parameters)


class SoftVote(nn.Module):
    """Input [B, n_branches, V, T] -> log of the members' mean class probability [B, n_classes].

    The logarithm makes it a drop-in for a network's logits: softmax of it is the mean probability again.
    """

    def __init__(self, members: Sequence[nn.Module]):
        super().__init__()
        if not 2 <= len(members) <= MAX_MEMBERS:
            raise InputError(f"an ensemble needs 2 to {MAX_MEMBERS} members, got {len(members)}")
        self.members = nn.ModuleList(members)
        self.cfg = members[0].cfg

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p = torch.stack([torch.softmax(m(x), dim=1) for m in self.members]).mean(dim=0)
        return torch.log(p.clamp_min(torch.finfo(p.dtype).tiny))


def members_of(model: nn.Module) -> list[nn.Module]:
    """The networks of `model`: its members if it is a `SoftVote`, else the model itself."""
    return list(model.members) if isinstance(model, SoftVote) else [model]


def weights_digest(model: nn.Module) -> str:
    """sha256 of a network's parameters and buffers (names, shapes, dtypes and bytes): equal for the same weights."""
    import hashlib

    h = hashlib.sha256()
    for name, t in sorted(model.state_dict().items()):
        t = t.detach().cpu().contiguous()
        h.update(f"{name}:{tuple(t.shape)}:{t.dtype}".encode())
        h.update(t.numpy().tobytes() if t.dtype != torch.bfloat16 else t.float().numpy().tobytes())
    return h.hexdigest()


def ensemble(classifiers: list[Classifier], names: list[str] | None = None, *, distinct: bool = True) -> Classifier:
    """One classifier voting with the mean class probability of `classifiers` (ensembles are flattened).

    They must share the network configuration, the preprocessing, the classes (in order) and the links; the
    ensemble keeps each member's training metadata (seed, dataset, validation accuracy) under meta["members"].
    With `distinct` (default), two members with equal weights (`weights_digest`; e.g. an ensemble given
    together with one of its own members) are refused: one network would count twice in the vote.

    Raises:
        InputError: fewer than 2 or more than `MAX_MEMBERS` networks, members that differ in one of the
            shared fields (named, with the member), or (`distinct`) a network given twice.
    """
    names = [f"member {i}" for i in range(len(classifiers))] if names is None else list(names)
    if not classifiers:
        raise InputError(f"an ensemble needs 2 to {MAX_MEMBERS} networks, got none")
    first = classifiers[0]
    nets, info = [], []
    for clf, name in zip(classifiers, names):
        for field, mine, ref in (("network configuration", clf.model.cfg, first.model.cfg),
                                 ("preprocessing", clf.preprocess, first.preprocess),
                                 ("classes", clf.classes, first.classes), ("links", clf.links, first.links)):
            if mine != ref:
                raise InputError(f"{name} differs from {names[0]} in its {field}: an ensemble's members must be "
                                 "trained alike (same settings, other seeds)")
        nets += members_of(clf.model)
        own = clf.meta.get("members") or [{key: clf.meta.get(key) for key in ("train_spec", "val_accuracy")}
                                          | {"seed": (clf.meta.get("train_config") or {}).get("seed")}]
        info += [{"source": name, **m} for m in own]
    seen: dict[str, int] = {}
    for k, net in enumerate(nets if distinct else []):  # an ensemble given with one of its members
        first_k = seen.setdefault(weights_digest(net), k)
        if first_k != k:
            raise InputError(f"{info[k]['source']} holds the same network as {info[first_k]['source']} (equal "
                             "weights): a member would count twice in the vote")
    model = SoftVote(nets)
    model.eval()
    dsps = [clf.meta.get("dsp") for clf in classifiers]
    # the DSP settings travel with the model for `evaluate --recordings`; members made from other data keep none
    meta = {"members": info, "dsp": dsps[0] if all(d == dsps[0] for d in dsps) else None}
    # every real image any member saw, so that an evaluation of the vote leaves them out as well
    real = {(r.get("sha256"), r.get("role")): r for clf in classifiers for r in clf.meta.get("real_images") or []}
    if real:
        meta["real_images"] = list(real.values())
    return Classifier(model=model, preprocess=first.preprocess, classes=list(first.classes),
                      links=list(first.links), meta=meta)


__all__ = ["MAX_MEMBERS", "SoftVote", "ensemble", "members_of", "weights_digest"]
