"""Validation splits: grouped by motion source (`split_indices`), and simulated deployments held out from
training (`holdout_split`: model selection without real images).

A random split of a deployment-randomised dataset validates on the same distribution the network trains on:
every room size, radar distance, antenna height, beam and body of the validation items has close neighbours
in training. Early stopping on it picks the epoch that fits the simulated distribution best, not the one that
carries over to a deployment nobody simulated. Here the validation side holds

- whole motion sources (procedural variants, motion-capture takes) held out as in `split_indices`, and
- every item whose deployment lies in a held-out *tail* of one or more deployment factors (e.g. the farthest
  12.5 % of radar distances, the lowest antennas, the heaviest bodies),

and the training side holds neither: no held-out motion and no held-out deployment region reaches training.
Validation accuracy then measures extrapolation to deployment regions the network never saw, which is what
a recording made elsewhere asks of it (the leave-domain-out model selection of Gulrajani & Lopez-Paz, "In
search of lost domain generalization", ICLR 2021, applied to the simulator's deployment parameters).

Which factors and which end of each are held out is drawn from the seed, so the members of a seed ensemble
extrapolate in different directions and together train on every region.

Factors come from each index entry's ``params["deployment"]`` (written by the dataset builder) or, for older
datasets, from the radar and motion parameters every entry records (`deployment_factors`).
"""
from __future__ import annotations

import math

import numpy as np

from processing.errors import InputError


def split_indices(labels, groups=None, val_fraction: float = 0.2, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(train, validation) index arrays: stratified by label and, if `groups` is given, grouped.

    Grouped splits use scikit-learn's StratifiedGroupKFold with round(1 / val_fraction) folds and take
    as validation the fold holding most classes (then nearest in size to `val_fraction`), so no group
    straddles the two sides and class shares stay close to the dataset's. Raises ValueError when there are
    too few groups or samples to split.
    """
    from sklearn.model_selection import StratifiedGroupKFold, train_test_split

    labels = np.asarray(labels)
    idx = np.arange(labels.size)
    n_splits = max(2, int(round(1 / val_fraction)))
    if groups is not None and len(set(groups)) < labels.size:
        groups = np.asarray([str(g) for g in groups])
        if np.unique(groups).size < n_splits:
            raise InputError(f"grouped split needs at least {n_splits} motion sources, got {np.unique(groups).size}"
                             " (use an ungrouped split)")
        skf = StratifiedGroupKFold(n_splits=n_splits, shuffle=True, random_state=seed)
        n_cls = np.unique(labels).size
        # the fold that holds most classes, then whose size is nearest the requested share
        tr, va = min(skf.split(idx, labels, groups), key=lambda f: (
            n_cls - np.unique(labels[f[1]]).size, abs(f[1].size / labels.size - val_fraction)))
        return np.sort(tr), np.sort(va)
    _, counts = np.unique(labels, return_counts=True)
    strat = labels if counts.min() >= 2 else None
    tr, va = train_test_split(idx, test_size=val_fraction, random_state=seed, stratify=strat)
    return np.sort(tr), np.sort(va)

# Deployment descriptors (units in the names). Absent values are NaN and never put an item in a tail.
FACTORS = ("distance_m", "antenna_height_m", "downtilt_deg", "hpbw_el_deg", "hpbw_az_deg", "room_area_m2",
           "stature_m", "bmi", "age_years", "body_muscle", "take")


def _room_area(name) -> float:
    """Floor area [m^2] of a generated box room ``room:X0,X1,Y0,Y1,H`` (NaN for any other scene)."""
    if not isinstance(name, str) or not name.startswith("room:"):
        return math.nan
    try:
        x0, x1, y0, y1 = (float(v) for v in name[5:].split(",")[:4])
    except ValueError:
        return math.nan
    return abs(x1 - x0) * abs(y1 - y0)


def entry_deployment(entry: dict) -> dict[str, float]:
    """Numeric deployment descriptors of one dataset index entry (NaN where the entry does not say).

    ``params["deployment"]`` wins where present; otherwise the first link's transmitter gives the horizontal
    distance to the person's spot (the origin) [m] and the antenna height [m], the radar's antenna its downtilt
    and beamwidths [deg], the room name its floor area [m^2], and the motion its stature [m] and, for a shaped
    body, its BMI [kg/m^2], age [years] and muscle (0..1).
    """
    params = entry.get("params", {}) or {}
    out = {k: math.nan for k in FACTORS if k != "take"}
    radar = params.get("radar") or {}
    links = radar.get("links") or []
    if links and links[0].get("tx") is not None:
        tx = links[0]["tx"]
        out["distance_m"] = float(math.hypot(tx[0], tx[1]))
        out["antenna_height_m"] = float(tx[2])
    ant = radar.get("antenna") or {}
    for key in ("downtilt_deg", "hpbw_el_deg", "hpbw_az_deg"):
        if ant.get(key) is not None:
            out[key] = float(ant[key])
    out["room_area_m2"] = _room_area(params.get("room"))
    motion = params.get("motion") or {}
    if motion.get("height") is not None:
        out["stature_m"] = float(motion["height"])
    body = motion.get("body") or {}
    for key, name in (("bmi", "bmi"), ("age_years", "age_years"), ("muscle", "body_muscle")):
        if body.get(key) is not None:
            out[name] = float(body[key])
    for key, value in (params.get("deployment") or {}).items():
        if key in out and value is not None:
            out[key] = float(value)
    return out


def deployment_factors(entries: list[dict]) -> dict[str, np.ndarray]:
    """Descriptor arrays [N] (float64, NaN where unknown) of `entries`, one per factor in `FACTORS` that varies
    across them (a constant factor cannot be held out), plus ``take``: the motion-capture take of items made
    from a file (its group), else an empty string."""
    rows = [entry_deployment(e) for e in entries]
    out = {}
    for key in FACTORS:
        if key == "take":
            continue
        v = np.array([r[key] for r in rows], dtype=np.float64)
        finite = v[np.isfinite(v)]
        if finite.size and np.ptp(finite) > 0:
            out[key] = v
    takes = np.array([str(e.get("group", "")) if str(e.get("group", "")).startswith("file:") else ""
                      for e in entries])
    if np.unique(takes[takes != ""]).size >= 2:
        out["take"] = takes
    return out


def holdout_split(labels, groups, factors: dict[str, np.ndarray], seed: int = 0, group_fraction: float = 0.15,
                  n_factors: int = 2, tail: float = 0.125) -> tuple[np.ndarray, np.ndarray, dict]:
    """(train, validation, description) index arrays holding out motion sources and deployment regions.

    Args:
        labels: class index per item [N].
        groups: motion source per item [N] (all items of one source stay on one side).
        factors: descriptor arrays [N] per factor (`deployment_factors`); ``take`` holds out whole takes.
        seed: draws the held-out sources, the factors and the end of each factor's range.
        group_fraction: share of motion sources held out (stratified by class, `split_indices`), 0 < f < 1.
        n_factors: how many deployment factors get a held-out tail (at most the number available).
        tail: share of the items (by the factor's quantile) in each held-out tail, 0 < tail < 0.5. For
            ``take``, whole takes until about this share of the take items is reached.

    Returns:
        (train [N_t], validation [N_v], description) where description names the held-out factors, ends and
        thresholds, and counts the items each rule moved to validation. Items of a held-out source or in a
        held-out tail are validation; all others train.

    Raises:
        InputError: no class left in training or validation, or bad fractions.
    """
    if not (0 < group_fraction < 1 and 0 < tail < 0.5 and n_factors >= 0):
        raise InputError("holdout_split needs 0 < group_fraction < 1, 0 < tail < 0.5 and n_factors >= 0")
    labels = np.asarray(labels)
    n = labels.size
    _, va_groups = split_indices(labels, groups, group_fraction, seed)
    val = np.zeros(n, bool)
    val[va_groups] = True
    rng = np.random.default_rng([seed, 0x5EED])
    names = sorted(factors)
    chosen = [names[i] for i in rng.permutation(len(names))[:min(n_factors, len(names))]]
    desc: dict = {"group_fraction": group_fraction, "tail": tail, "held_out_sources": int(val.sum()),
            "held_out_groups": sorted({str(g) for g in np.asarray(groups, dtype=object)[va_groups]}), "factors": []}
    for name in sorted(chosen):
        v = factors[name]
        if name == "take":
            takes = np.unique(v[v != ""])
            rng_t = np.random.default_rng([seed, 0x7A4E])
            picked, count, goal = [], 0, tail * np.count_nonzero(v != "")
            for t in takes[rng_t.permutation(takes.size)]:
                if count >= goal:
                    break
                picked.append(str(t))
                count += int(np.count_nonzero(v == t))
            mask = np.isin(v, picked)
            desc["factors"].append({"factor": "take", "takes": picked, "items": int(mask.sum())})
        else:
            finite = np.isfinite(v)
            high = bool(rng.random() < 0.5)
            q = float(np.quantile(v[finite], 1 - tail if high else tail))
            mask = finite & ((v >= q) if high else (v <= q))
            desc["factors"].append({"factor": name, "end": "high" if high else "low", "threshold": q,
                                    "items": int(mask.sum())})
        val |= mask
    tr, va = np.flatnonzero(~val), np.flatnonzero(val)
    for side, idx in (("training", tr), ("validation", va)):
        missing = sorted(set(np.unique(labels).tolist()) - set(np.unique(labels[idx]).tolist()))
        if missing:
            raise InputError(f"held-out deployment split left no item of class(es) {missing} for {side}: use "
                             "fewer held-out factors or a smaller tail")
    desc.update(n_train=int(tr.size), n_val=int(va.size))
    return tr, va, desc


__all__ = ["FACTORS", "deployment_factors", "entry_deployment", "holdout_split", "split_indices"]
