"""Validation on held-out simulated deployments (`processing.classifier.splits`)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from processing.classifier.splits import deployment_factors, entry_deployment, holdout_split
from processing.errors import InputError


def _entries(n=400, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        d, h = rng.uniform(1.2, 5.0), rng.uniform(0.5, 1.6)
        group = f"file:take{i % 8}.bvh" if i % 5 == 0 else f"procedural:x#{i // 4}"
        out.append({"label": i % 5, "group": group, "params": {
            "radar": {"links": [{"tx": [d * math.cos(0.3), d * math.sin(0.3), h]}],
                      "antenna": {"downtilt_deg": rng.uniform(-5, 15), "hpbw_el_deg": 24.0}},
            "room": f"room:-2,{rng.uniform(3, 8):.2f},-3,3,2.8", "motion": {"height": rng.uniform(1.45, 1.95)},
            "deployment": {"bmi": rng.uniform(17, 40)}}})
    return out


def test_entry_deployment_reads_the_radar_room_motion_and_recorded_factors():
    e = {"params": {"radar": {"links": [{"tx": [3.0, 4.0, 1.2]}], "antenna": {"downtilt_deg": 7.0}},
                    "room": "room:-1,4,-2,3,2.5", "motion": {"height": 1.7}, "deployment": {"bmi": 31.0}}}
    d = entry_deployment(e)
    assert d["distance_m"] == pytest.approx(5.0) and d["antenna_height_m"] == pytest.approx(1.2)
    assert d["room_area_m2"] == pytest.approx(25.0) and d["stature_m"] == 1.7 and d["bmi"] == 31.0
    assert d["downtilt_deg"] == 7.0 and math.isnan(d["hpbw_az_deg"])


def test_constant_factors_are_not_offered_and_takes_are():
    f = deployment_factors(_entries())
    assert "hpbw_el_deg" not in f  # the same beam everywhere cannot be held out
    assert {"distance_m", "antenna_height_m", "room_area_m2", "stature_m", "bmi", "take"} <= set(f)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_no_held_out_source_or_deployment_region_reaches_training(seed):
    entries = _entries()
    labels = np.array([e["label"] for e in entries])
    groups = [e["group"] for e in entries]
    f = deployment_factors(entries)
    tr, va, desc = holdout_split(labels, groups, f, seed=seed, group_fraction=0.15, n_factors=2, tail=0.125)
    assert np.intersect1d(tr, va).size == 0 and tr.size + va.size == len(entries)
    assert desc["held_out_groups"] and not set(desc["held_out_groups"]) & set(np.asarray(groups)[tr])
    held = desc["factors"]
    assert len(held) == 2
    for d in held:
        v = f[d["factor"]]
        if d["factor"] == "take":
            assert not np.isin(v[tr], d["takes"]).any()
            continue
        # every training item lies strictly inside the kept side of the threshold
        assert (v[tr] < d["threshold"]).all() if d["end"] == "high" else (v[tr] > d["threshold"]).all()
        # and the tail holds about `tail` of the items (quantile of continuous draws: within 2 items)
        assert abs(d["items"] - 0.125 * len(entries)) <= 2


def test_the_seed_chooses_the_held_out_factors():
    entries = _entries()
    labels = np.array([e["label"] for e in entries])
    groups = [e["group"] for e in entries]
    f = deployment_factors(entries)
    chosen = {tuple(sorted(d["factor"] for d in holdout_split(labels, groups, f, seed=s)[2]["factors"]))
              for s in range(8)}
    assert len(chosen) >= 3  # 7 factors, pairs drawn per seed: eight seeds give several different pairs


def test_a_split_that_empties_a_class_is_refused():
    labels = np.array([0] * 55 + [1] * 5)
    groups = [f"g{i}" for i in range(60)]
    f = {"distance_m": np.r_[np.zeros(55), np.ones(5)]}  # class 1 lives only in the high tail
    with pytest.raises(InputError, match="no item of class"):
        for s in range(16):  # whichever end a seed draws, some seed holds out the high end
            holdout_split(labels, groups, f, seed=s, group_fraction=0.2, n_factors=1, tail=0.1)
