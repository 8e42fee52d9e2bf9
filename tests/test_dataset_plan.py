"""Augmentation plans: validation (one clear error naming the field), deterministic expansion, presets."""
import re
from pathlib import Path

import pytest
import yaml
from pydantic import ValidationError

from rtchannel.cli import main
from rtchannel.dataset.plan import Plan, derive_seed, expand, load_plan
from rtchannel.radar import direction_angles
from thirdparty import needs, registered

REPO = Path(__file__).resolve().parents[1]
BASE = {"name": "t", "seed": 3, "motion": {"sources": [{"procedural": "walk", "variants": 2,
                                                        "params": {"speed": [1.0, 1.5]}},
                                                       {"procedural": "fall", "variants": 1}],
                                           "heights": [1.6, [1.7, 1.9]], "time_scales": [1.0, 1.2]},
        "physical": {"directions": [1, 11]},
        "signal": {"gain_sets": [{"name": "seed"}, {"name": "j", "perturb_db": 2}], "snr_db": [None, 10]}}


def _write(tmp_path, data, name="plan.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


def test_expansion_counts_ids_and_determinism(tmp_path):
    items = expand(load_plan(_write(tmp_path, BASE)))
    # 3 generator variants x 2 heights x 2 time scales x 2 directions x 2 gain sets x 2 SNRs
    assert len(items) == 3 * 2 * 2 * 2 * 2 * 2
    ids = [it.item_id for it in items]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)
    again = expand(load_plan(_write(tmp_path, BASE, "again.yaml")))
    assert [it.to_dict() for it in again] == [it.to_dict() for it in items]
    assert {it.direction for it in items} == {1, 11}
    assert {it.angle_deg for it in items} == {0.0, direction_angles(11)[0]}  # -160 deg
    # motion-layer draws are shared by all directions/gain sets of a motion; item seeds are not
    by_motion = {}
    for it in items:
        by_motion.setdefault(it.motion["key"], set()).add(repr(sorted(it.motion.items())))
    assert all(len(v) == 1 for v in by_motion.values())
    assert len({it.seed for it in items}) == len(items)
    walk_speeds = {it.motion["params"]["speed"] for it in items if it.activity == "walk"}
    assert len(walk_speeds) == 2 and all(1.0 <= s <= 1.5 for s in walk_speeds)
    drawn_h = {it.motion["height"] for it in items if it.motion["height"] != 1.6}
    assert all(1.7 <= h <= 1.9 for h in drawn_h) and len(drawn_h) == 6  # per motion: 3 variants x 2 scales
    assert len({it.group for it in items}) == 3


def test_other_plan_seed_changes_draws(tmp_path):
    a = expand(load_plan(_write(tmp_path, BASE)))
    b = expand(load_plan(_write(tmp_path, {**BASE, "seed": 4}, "b.yaml")))
    assert [x.item_id for x in a] == [x.item_id for x in b]
    assert all(x.seed != y.seed for x, y in zip(a, b))
    assert {x.motion["params"]["seed"] for x in a} != {y.motion["params"]["seed"] for y in b}
    # generator seeds stay = variant (mod 3), so falls keep cycling forward / left / right
    assert all(x.motion["params"]["seed"] % 3 == int(x.item_id.split("-")[2]) % 3 for x in a + b)
    assert derive_seed(1, "k") == derive_seed(1, "k") != derive_seed(1, "l")


@pytest.mark.parametrize("patch, field", [
    ({"motion": {**BASE["motion"], "heigths": [1.7]}}, "motion.heigths"),
    ({"motion": {**BASE["motion"], "heights": [2.9]}}, "motion.heights"),
    ({"motion": {"sources": [{"procedural": "dance"}]}}, "motion.sources.0.procedural"),
    ({"motion": {"sources": [{"procedural": "walk", "params": {"height": 1.7}}]}}, "motion.sources.0"),
    ({"physical": {"directions": [19]}}, "physical"),
    ({"physical": {"waveforms": [{"pri_s": -1}]}}, "physical.waveforms.0.pri_s"),
    ({"signal": {"gain_sets": [{"name": "g", "scale": {"nose": 2}}]}}, "signal.gain_sets.0.scale"),
    ({"storage": {"items_per_shard": 0}}, "storage.items_per_shard"),
    ({"motion": {**BASE["motion"], "clip_start_s": [-40.0, 1.0]}}, "motion.clip_start_s"),
    ({"motion": {**BASE["motion"], "clip_start_s": {"dance": 0.2}}}, "motion.clip_start_s"),
    ({"backend_option": {}}, "backend_option"),
])
def test_invalid_field_is_one_clear_error(tmp_path, capsys, patch, field):
    p = _write(tmp_path, {**BASE, **patch})
    with pytest.raises(ValidationError):
        load_plan(p)
    assert main(["dataset", "--config", str(p), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: plan {p}: {field}"), err
    assert not (tmp_path / "o").exists()


def test_missing_motion_folder_and_bad_yaml_are_one_line(tmp_path, capsys):
    p = _write(tmp_path, {**BASE, "motion": {"sources": [{"files": "nowhere", "activity": "walk"}]}})
    assert main(["dataset", "--config", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "motion source not found" in capsys.readouterr().err
    (tmp_path / "bad.yaml").write_text("motion: [unclosed\n")
    assert main(["dataset", "--config", str(tmp_path / "bad.yaml"), "--out", str(tmp_path / "o")]) == 2
    assert "not valid YAML" in capsys.readouterr().err
    p = _write(tmp_path, {**BASE, "motion": {"sources": [{"procedural": "walk", "params": {"speed": [2.6, 3.0]}}]}})
    assert main(["dataset", "--config", str(p), "--dry-run"]) == 2  # a drawn value out of range
    assert f"error: plan {p}: motion.sources.0.params.speed: Input should be less" in capsys.readouterr().err
    assert main(["dataset", "--config", "seed", "--backend", "nosuch", "--dry-run"]) == 2
    assert "unknown backend 'nosuch'" in capsys.readouterr().err
    p = _write(tmp_path, {**BASE, "backend_options": {"lod": "2k"}})
    assert main(["dataset", "--config", str(p), "--dry-run"]) == 2
    assert "backend_options: backend 'points' has no option 'lod' (its options:" in capsys.readouterr().err
    assert main(["dataset", "--config", "no_such_preset", "--out", str(tmp_path / "o")]) == 2
    assert re.search(r"presets: [a-z, ]*\bseed\b", capsys.readouterr().err)


SEED_TAKES = (registered("mocap/cmu/walk_daz/*.bvh") + registered("mocap/hdm05/pick/*")
              + registered("mocap/hdm05/asf/*")
              + ["mocap/cmu/sit/75_17.bvh", "mocap/opencap/sit_stand/opencap_STS_sample_mocap.json"])


def test_seed_preset_counts_without_its_motion_capture(capsys, monkeypatch, tmp_path):
    """Counting a plan (--dry-run) never fetches: it works in a clone without the third-party takes."""
    monkeypatch.setenv("RTCHANNEL_DATA_MIRROR", str(tmp_path / "no_mirror"))
    monkeypatch.setenv("RTCHANNEL_DATA_CACHE", str(tmp_path / "empty_cache"))
    assert main(["dataset", "--config", "seed", "--dry-run"]) == 0
    assert "2808 items" in capsys.readouterr().out


@needs(*SEED_TAKES)
def test_seed_preset_reproduces_the_seed_structure(capsys):
    plan = load_plan("seed")
    items = expand(plan)
    # the seed: 2826 pairs; the preset's arithmetic (26 motion sources x 3 heights x 18 x 2) gives 2808
    assert len(items) == 26 * 3 * 18 * 2 == 2808
    # real takes beside the generators for every activity but falls (issue 23)
    real = {it.activity for it in items if it.motion["kind"] == "file"}
    assert real == {"walk", "sit", "stand", "pick"}
    assert abs(len(items) - 2826) / 2826 < 0.01
    assert {it.activity for it in items} == {"fall", "walk", "stand", "sit", "pick"}
    assert sorted({it.direction for it in items}) == list(range(1, 19))
    assert {it.gain_set["name"] for it in items} == {"seed", "jitter"}
    assert all([link["name"] for link in it.radar["links"]] == ["radar1", "radar2"] for it in items)
    assert load_plan("seed", backend="facets").backend == "facets"
    assert main(["dataset", "--config", "seed", "--dry-run"]) == 0
    assert "2808 items" in capsys.readouterr().out
    example = expand(load_plan(REPO / "examples" / "dataset_small.yaml"))
    assert len(example) == 48
    assert isinstance(Plan.model_json_schema(), dict)


@needs(*SEED_TAKES)
def test_sionna_subset_preset_holds_the_seed_motions():
    """The cross-test's Sionna subset must differ from the seed preset only in the physical and signal
    layers (6 of 18 directions, one gain set) and the backend: same motions, same radars per direction."""
    def key(it):  # item ids are motion-pPP-sSS; PP counts the plan's own directions, so key by direction
        return it.item_id.split("-p")[0], it.direction, it.gain_set["name"]

    seed = {key(it): it for it in expand(load_plan("seed"))}
    sub = expand(load_plan("seed_sionna_subset"))
    assert len(sub) == 26 * 3 * 6 == 468
    assert sorted({it.direction for it in sub}) == [1, 4, 7, 10, 13, 16]
    for it in sub:
        assert it.backend == "sionna" and it.backend_options == {"samples_per_src": 100000, "trace_fps": 20.0}
        twin = seed[key(it)]
        assert (it.motion, it.radar, it.angle_deg, it.activity) == (twin.motion, twin.radar, twin.angle_deg,
                                                                    twin.activity)


def test_clip_start_per_activity_places_the_motion_in_its_recording(tmp_path):
    """clip_start_s: where in its recording a motion begins, drawn per motion and per activity; a negative
    time starts the recording inside the motion."""
    import numpy as np

    from rtchannel.dataset.items import build_motion

    plan = {**BASE, "motion": {**BASE["motion"], "sources": [
        {"procedural": "fall", "variants": 2, "params": {"pad_before": 0.0, "duration": 1.0}},
        {"procedural": "sit", "variants": 2, "params": {"pad_before": 0.0, "duration": 1.0}}],
        "time_scales": [1.0], "clip_s": {"*": 5.0}, "clip_start_s": {"fall": 0.3, "sit": [-0.5, 0.5]}}}
    items = expand(load_plan(_write(tmp_path, plan)))
    starts = {it.motion["key"]: (it.activity, it.motion["clip_start_s"]) for it in items}
    assert {x for a, x in starts.values() if a == "fall"} == {0.3}
    sit = [x for a, x in starts.values() if a == "sit"]
    assert all(-0.5 <= x <= 0.5 for x in sit) and len(set(sit)) == len(sit) == 4  # one draw per motion
    for it in [next(i for i in items if i.activity == "fall")] + [i for i in items if i.activity == "sit"]:
        m = build_motion(it.motion)
        assert m.n_frames == 5 * 60 + 1
        whole = build_motion({k: v for k, v in it.motion.items() if not k.startswith("clip")} | {"key": "w"})
        # recording frame k shows motion frame k - 60 start (held at the ends): the first pose before the
        # motion begins, the motion cut by -start seconds when it began before the recording
        first = round(it.motion["clip_start_s"] * 60)
        idx = np.clip(np.arange(m.n_frames) - first, 0, whole.n_frames - 1)
        np.testing.assert_array_equal(m.positions, whole.positions[idx])
    assert min(sit) < 0 < max(sit)  # both cases were checked
