"""Accuracy budget (issue 26): choosing the cheapest calibrated setting within a budget, storing the choice,
and the calibration that makes the table."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from processing.errors import InputError
from rtchannel.accuracy import (FAST_FACTOR, CalibrationRow, CalibrationTable, choose, parse_budget, resolve,
                                shipped_tables, table_for)
from rtchannel.radar import RadarConfig


def _table(carrier=24.125e9, res=0.599584916) -> CalibrationTable:
    rows = [
        CalibrationRow(label="default", backend="facets", options={}, s_per_sim_s=0.30,
                       emd_m_s={"walk": 0.09, "sit": 0.20}, role="default"),
        CalibrationRow(label="exact", backend="facets", options={"lod": "full", "trace_fps": None}, s_per_sim_s=9.0,
                       emd_m_s={"walk": 0.07, "sit": 0.10}, role="exact"),
        CalibrationRow(label="cheap", backend="facets", options={"lod": "2k"}, s_per_sim_s=0.10,
                       emd_m_s={"walk": 0.12, "sit": 0.29}),
        CalibrationRow(label="better", backend="facets", options={"image_lod": "5k"}, s_per_sim_s=0.25,
                       emd_m_s={"walk": 0.088, "sit": 0.15}),
        CalibrationRow(label="walk only", backend="facets", options={"trace_fps": 5.0}, s_per_sim_s=0.2,
                       emd_m_s={"walk": 0.089, "sit": 0.33}),
        CalibrationRow(label="points", backend="points", options={}, s_per_sim_s=0.03,
                       emd_m_s={"walk": 0.18, "sit": 0.24}, role="points"),
    ]
    return CalibrationTable(radar="test", carrier_hz=carrier, range_resolution_m=res, reference="ref", rows=rows)


def test_budgets_choose_the_cheapest_row_within_the_target_on_every_activity():
    t = _table()
    # balanced: no worse than the default on every calibrated activity, cheapest first; "walk only" is as good
    # as the default on walk and cheaper, but fails sit: a per-activity pick would be a speckle-draw winner
    assert choose("balanced", "facets", t, "walk")[0].label == "better"
    assert choose("balanced", "facets", t, "sit")[0].label == "better"
    row, limit = choose("balanced", "facets", t, None)  # no activity: the target reported is the worst one's
    assert row.label == "better" and limit == pytest.approx(0.20)
    # balanced allows two standard errors of the difference to the default (seeds' speckle): with the default at
    # 0.09 +- 0.003 and a row at sem 0.004 the line is 0.09 + 2 x 0.005 = 0.10; 0.099 passes, 0.101 does not
    d = t.rows[0].model_copy(update={"emd_sem_m_s": {"walk": 0.003, "sit": 0.0}})
    for err, ok in ((0.099, True), (0.101, False)):
        r = CalibrationRow(label="noisy", backend="facets", options={"lod": "5k"}, s_per_sim_s=0.05,
                           emd_m_s={"walk": err, "sit": 0.20}, emd_sem_m_s={"walk": 0.004, "sit": 0.0})
        row, limit = choose("balanced", "facets", t.model_copy(update={"rows": [d, *t.rows[1:], r]}), "walk")
        assert (row.label == "noisy") is ok
        assert limit == pytest.approx(0.10 if ok else 0.09 + 2 * 0.003)  # the chosen row's own line
    # fast: FAST_FACTOR x the default's error; 2k is within it on walk (0.12 <= 0.135) and sit (0.29 <= 0.30)
    row, limit = choose("fast", "facets", t, "walk")
    assert row.label == "cheap" and limit == pytest.approx(FAST_FACTOR * 0.09)
    assert choose("exact", "facets", t, "walk")[0].label == "exact"
    assert choose(0.1, "facets", t, "walk")[0].label == "exact"  # only exact is within 0.1 on sit too
    assert choose(0.4, "facets", t, "walk")[0].label == "cheap"
    with pytest.raises(InputError, match=r"no calibrated facets setting reaches 0\.050 m/s on walk .*best on walk: "
                       r"exact, 0\.070"):
        choose(0.05, "facets", t, "walk")
    with pytest.raises(InputError, match="no sionna settings"):
        choose("balanced", "sionna", t, "walk")
    # a row that reproduced the default's errors exactly is the default's model: its timing is noise
    same = CalibrationRow(label="same model", backend="facets", options={"walls": "auto"}, s_per_sim_s=0.01,
                          emd_m_s=dict(t.row("default").emd_m_s))
    t2 = t.model_copy(update={"rows": [*t.rows, same]})
    assert choose("balanced", "facets", t2, "walk")[0].label == "better"  # not "same model" at 0.01 s
    # a saving within the timing noise (< MIN_SAVING) does not replace the default
    close = CalibrationRow(label="5 % cheaper", backend="facets", options={"clutter": False}, s_per_sim_s=0.285,
                           emd_m_s={"walk": 0.085, "sit": 0.15})
    assert choose("balanced", "facets", t.model_copy(update={"rows": [t.rows[0], t.rows[1], close]}), "walk")[0].label \
        == "default"
    assert choose("balanced", "facets", t.model_copy(update={"rows": [t.rows[0], t.rows[1], close.model_copy(
        update={"s_per_sim_s": 0.26})]}), "walk")[0].label == "5 % cheaper"
    # a row kept for the record ("measured") is never chosen, however good and cheap
    kept = t.rows[3].model_copy(update={"label": "record only", "role": "measured", "s_per_sim_s": 0.01})
    assert choose("balanced", "facets", t.model_copy(update={"rows": [*t.rows, kept]}), "walk")[0].label == "better"


def test_parse_budget():
    assert parse_budget("balanced") == "balanced"
    assert parse_budget("0.12") == pytest.approx(0.12)
    for bad in ("quick", "-1", "nan", "inf", "0"):
        with pytest.raises(InputError):
            parse_budget(bad)


def test_resolve_records_the_choice_and_overrides():
    t = _table()
    opts, rec = resolve("balanced", "facets", RadarConfig(), "sit", {"image_lod": "10k", "seed": 3}, t)
    assert opts == {"image_lod": "10k", "seed": 3}  # the user's explicit option wins over the chosen 5k
    assert rec["chosen"] == "better" and rec["overrides"] == {"image_lod": "10k"}
    assert rec["target_emd_m_s"] == pytest.approx(0.20) and rec["calibrated_emd_m_s"] == pytest.approx(0.15)
    assert rec["calibration_digest"] == t.digest()
    with pytest.raises(InputError, match="points backend has none"):
        resolve("balanced", "points", RadarConfig(), "sit", {}, t)


def test_tables_are_chosen_by_carrier_and_range_bin():
    with pytest.raises(InputError, match="no calibration table for a 77 GHz radar"):
        table_for(RadarConfig.model_validate({"waveform": {"carrier_hz": 77e9}}))
    t = _table()
    assert table_for(RadarConfig(), t)[0] is t


def test_shipped_tables_cover_the_presets_radars_and_balanced_is_no_worse_than_default():
    tables = shipped_tables()
    assert tables, "rtchannel/calibration/*.json missing"
    for radar in (RadarConfig(), RadarConfig.glasgow()):
        table, source = table_for(radar)
        assert source.startswith("shipped:")
        default = table.row("default")
        for act in table.motions:
            row, _ = choose("balanced", "facets", table, act)  # within 2 standard errors of the difference
            excess = row.error(act) - default.error(act)
            assert excess <= 2 * math.hypot(default.sem(act), row.sem(act)) and row.s_per_sim_s <= default.s_per_sim_s
            assert choose("fast", "facets", table, act)[0].s_per_sim_s <= row.s_per_sim_s


@pytest.fixture(scope="module")
def short_sit():
    from rtchannel.motion.procedural import generate

    return generate("sit", seed=0, pad_before=0.1, pad_after=0.1)


def test_simulate_stores_the_budget_with_the_signature(tmp_path, short_sit):
    from processing.io.signature_file import read_signature_file
    from rtchannel.pipeline import simulate

    res = simulate(short_sit, RadarConfig(), backend="facets", accuracy="fast", calibration=_table(), clutter=False)
    acc = res.config["accuracy"]
    assert acc["budget"] == "fast" and acc["activity"] == "sit"
    assert acc["chosen"] == "cheap"  # fast on sit: within 1.5 x 0.20 m/s, 2k is the cheapest
    assert res.config["backend_options"]["lod"] == "2k" and res.config["backend_stats"]["lod"] == "2k"
    path = res.save(tmp_path / "signature.h5")
    cfg = read_signature_file(path)[0]["config"]
    assert cfg["accuracy"]["chosen"] == acc["chosen"]
    assert cfg["backend_stats"]["lod"] == res.config["backend_stats"]["lod"]
    for sig in res.signatures.values():
        assert np.all(np.isfinite(sig.p_vt))


def test_cli_accuracy_errors_are_one_line(tmp_path):
    def run(*args):
        return subprocess.run([sys.executable, "-m", "rtchannel.cli", "simulate", "--activity", "sit", "--out",
                               str(tmp_path / "o"), "--quiet", "--no-plots", *args], capture_output=True, text=True)

    r = run("--backend", "facets", "--accuracy", "quick")
    assert r.returncode != 0 and "--accuracy" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run("--accuracy", "balanced")  # points
    assert r.returncode != 0 and "points backend has none" in r.stderr
    r = run("--backend", "facets", "--calibration", str(tmp_path / "none.json"))
    assert r.returncode != 0 and "--calibration needs --accuracy" in r.stderr


def test_plan_accuracy_is_checked_at_load():
    from pydantic import ValidationError

    from rtchannel.dataset.plan_schema import Plan

    base = {"motion": {"sources": [{"procedural": "walk"}]}}
    with pytest.raises((InputError, ValidationError), match="points backend has none"):
        Plan.model_validate({**base, "accuracy": "fast"})
    with pytest.raises((InputError, ValidationError)):
        Plan.model_validate({**base, "backend": "facets", "accuracy": "speedy"})
    plan = Plan.model_validate({**base, "backend": "facets", "accuracy": "0.2"})
    assert plan.accuracy == pytest.approx(0.2)


def test_calibration_measures_rows_against_a_converged_reference(tmp_path):
    from rtchannel.analysis.calibrate import calibrate, write_calibration
    from rtchannel.analysis.speed_error import Setting
    from rtchannel.motion.procedural import generate

    motion = generate("sit", seed=0, pad_before=0.1, pad_after=0.1)
    ref = Setting("ref", "facets", {"lod": "2k", "trace_fps": None, "clutter": False})
    cands = [(Setting("d", "facets", {"lod": "2k", "clutter": False}), "default"),
             (Setting("e", "facets", {"lod": "2k", "trace_fps": None, "clutter": False}), "exact"),
             (Setting("no walls", "facets", {"lod": "2k", "walls": False, "clutter": False}), "candidate")]
    table = calibrate(RadarConfig(), "test", ("sit",), cands, seeds=2, reference_seeds=2, motions={"sit": motion},
                      reference=ref)
    rows = {r.label: r for r in table.rows}
    # leaving out the walls' paths moves p(v,t) further from the reference than tracing at 10 fps does
    assert rows["no walls"].emd_m_s["sit"] > rows["d"].emd_m_s["sit"]
    assert all(r.s_per_sim_s > 0 and np.isfinite(r.emd_m_s["sit"]) for r in table.rows)
    files = write_calibration(table, tmp_path)
    loaded = CalibrationTable.model_validate(json.loads(files[0].read_text()))
    assert loaded.digest() == table.digest()


def test_several_motions_per_activity_must_all_meet_the_budget():
    """Each calibration motion is a key of its own: a row that is the default's equal on one fall and far worse
    on another does not qualify; merging a second run adds its motions' errors and keeps the first's costs."""
    from rtchannel.analysis.calibrate import calibration_motions, merge_tables

    ms = calibration_motions(("fall", "sit"), (0, 3))
    assert list(ms) == ["fall", "sit", "fall (motion seed 3)", "sit (motion seed 3)"]
    assert ms["fall"].params["seed"] == 0 and ms["fall (motion seed 3)"].params["seed"] == 3
    t = _table()
    more = t.model_copy(update={"rows": [r.model_copy(update={
        "s_per_sim_s": 99.0,
        "emd_m_s": {"walk (motion seed 3)": r.emd_m_s["walk"] * (2.0 if r.label == "better" else 1.0)}})
        for r in t.rows], "motions": {"walk (motion seed 3)": "walk, seed 3"}})
    merged = merge_tables(t, more)
    assert [r.s_per_sim_s for r in merged.rows] == [r.s_per_sim_s for r in t.rows]
    assert set(merged.row("default").emd_m_s) == {"walk", "sit", "walk (motion seed 3)"}
    assert choose("balanced", "facets", t, "walk")[0].label == "better"
    assert choose("balanced", "facets", merged, "walk")[0].label == "default"  # "better" fails the second walk
    with pytest.raises(ValueError, match="same rows"):
        merge_tables(t, t.model_copy(update={"rows": t.rows[:-1]}))


def test_dataset_items_carry_the_budget_and_store_the_choice(tmp_path):
    from rtchannel.dataset.items import run_item, shared_key
    from rtchannel.dataset.plan import expand
    from rtchannel.dataset.plan_schema import Plan

    cal = tmp_path / "cal.json"
    cal.write_text(_table().model_dump_json())
    plan = Plan.model_validate({"backend": "facets", "accuracy": "fast", "calibration": str(cal),
                                "backend_options": {"clutter": False},
                                "motion": {"sources": [{"procedural": "sit", "params": {"pad_before": 0.1,
                                                                                          "pad_after": 0.1}}]},
                                "physical": {"directions": [1]}})
    items = expand(plan)
    assert items and all(it.accuracy == "fast" for it in items)
    other = Plan.model_validate({**plan.model_dump(mode="json"), "accuracy": "exact"})
    assert shared_key(items[0]) != shared_key(expand(other)[0])  # another budget never shares a backend run
    rec = run_item(items[0])["entry"]["params"]
    assert rec["accuracy_choice"]["chosen"] == "cheap" and rec["backend_stats"]["lod"] == "2k"
    at77 = Plan.model_validate({**plan.model_dump(mode="json"), "calibration": None,
                                "physical": {"directions": [1], "waveforms": [{"carrier_hz": 77e9}]}})
    with pytest.raises(ValueError, match="accuracy: no calibration table for a 77 GHz radar"):
        expand(at77)


def test_validation_checks_named_budgets_against_the_default_on_the_same_motion(tmp_path):
    from rtchannel.analysis.accuracy_validation import _sem_of_difference, summary, validate, write_validation
    from rtchannel.analysis.speed_error import Setting
    from rtchannel.motion.procedural import generate

    assert _sem_of_difference(np.array([1.0, 3.0]), np.array([2.0, 2.0])) == pytest.approx(1.0)  # sqrt(2/2 + 0)
    assert _sem_of_difference(np.array([1.0]), np.array([2.0])) == 0.0
    motion = generate("sit", seed=1, pad_before=0.1, pad_after=0.1)
    ref = Setting("ref", "facets", {"lod": "2k", "trace_fps": None, "clutter": False})
    rows = validate(RadarConfig(), _table(), [("sit seed 1", motion)], budgets=("fast", 0.5), seeds=2,
                    reference_seeds=2, reference=ref)
    by = {r["budget"]: r for r in rows}
    assert set(by) == {"default", "fast", "0.5"} and by["default"]["speedup"] == pytest.approx(1.0)
    assert by["fast"]["chosen"] == "cheap" and by["fast"]["target_emd_m_s"] == pytest.approx(
        1.5 * by["default"]["achieved_emd_m_s"])
    assert by["0.5"]["target_emd_m_s"] == 0.5 and by["0.5"]["allowance_m_s"] == 0.0
    assert by["fast"]["within"] == (by["fast"]["achieved_emd_m_s"]
                                    <= by["fast"]["target_emd_m_s"] + by["fast"]["allowance_m_s"])
    assert summary(rows)["default"]["within_share"] is None
    files = write_validation(rows, tmp_path, {"radar": "seed", "seeds": 2, "reference_seeds": 2})
    assert all(f.exists() for f in files)


def test_merge_into_a_table_of_other_settings_fails_before_the_run(tmp_path, capsys):
    from rtchannel.cli import main

    table = json.loads((Path(__file__).resolve().parents[1] / "rtchannel/calibration/seed_24GHz.json").read_text())
    table["rows"] = table["rows"][:-1]
    bad = tmp_path / "old.json"
    bad.write_text(json.dumps(table))
    assert main(["bench", "--calibrate", "--radar", "seed", "--merge-into", str(bad), "--out", str(tmp_path)]) != 0
    assert "not this version's calibration settings" in capsys.readouterr().err
    assert not (tmp_path / "calibration.json").exists()
