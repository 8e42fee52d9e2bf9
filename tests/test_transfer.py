"""The transfer study (`rtchannel transfer`): subject-grouped folds, nested shots, no test image in any training,
resuming, worker processes giving the runs of one process, and the simulation's worth read off the curve."""
import json

import numpy as np
import pytest

from processing.classifier import ModelConfig, PreprocessConfig, TrainConfig
from processing.classifier.transfer import TransferConfig, real_step_budget, shot_indices, subject_folds
from processing.classifier.transfer_report import simulation_worth
from processing.errors import InputError
from rtchannel.cli import main


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RTCHANNEL_CACHE_DIR", str(tmp_path / "cache"))


def test_folds_hold_each_person_in_exactly_one_test_fold():
    groups = [f"subject:P{p}" for p in range(36, 56) for _ in range(15)]
    folds = subject_folds(groups, 5)
    assert sorted(np.concatenate(folds).tolist()) == list(range(300))  # a partition of the images
    people = [{groups[i] for i in f} for f in folds]
    assert all(len(p) == 4 for p in people) and len(set().union(*people)) == 20
    assert all(not (a & b) for i, a in enumerate(people) for b in people[i + 1:])
    with pytest.raises(InputError, match="at least 6 people"):
        subject_folds(groups[:15 * 5], 6)


def test_shots_are_nested_per_class_and_drawn_from_the_training_folds_only():
    y = np.tile(np.arange(5), 60)
    train_pool = np.arange(0, 240)
    picks = {k: shot_indices(y, train_pool, k, 5, seed=1, fold=2) for k in (1, 2, 5, 20)}
    for k, idx in picks.items():
        assert np.bincount(y[idx], minlength=5).tolist() == [k] * 5 and idx.max() < 240
    assert all(set(picks[a]) <= set(picks[b]) for a, b in ((1, 2), (2, 5), (5, 20)))
    assert np.array_equal(shot_indices(y, train_pool, "all", 5, 1, 2), train_pool)
    assert not np.array_equal(picks[5], shot_indices(y, train_pool, 5, 5, seed=2, fold=2))  # the seed draws


def test_simulation_worth_is_read_off_the_real_only_curve():
    """Sim only at 80 %, real only at 70 % with 2 and 90 % with 5 per class: the line through the two crosses
    80 % at 2 + (80 - 70) / (90 - 70) * 3 = 3.5 recordings per class."""
    def row(arm, spc, acc):
        return {"arm": arm, "shots_per_class": spc, "accuracy_pct_mean": acc}

    curve = [row("real", 1, 40.0), row("real", 2, 70.0), row("real", 5, 90.0)]
    w = simulation_worth([row("sim", 0, 80.0)] + curve)
    assert w["bound"] == "within" and w["per_class"] == pytest.approx(3.5, abs=1e-12)
    assert simulation_worth([row("sim", 0, 30.0)] + curve)["bound"] == "below"
    above = simulation_worth([row("sim", 0, 95.0)] + curve)
    assert above["bound"] == "above" and above["per_class"] is None and "5 per class" in above["text"]


def test_real_only_steps_grow_with_the_images_between_the_floor_and_the_cap():
    """Defaults (50 draws per image, batch 32, 60-150 steps): 5 images need ceil(250 / 32) = 8 steps, raised to the
    floor of 60; 40 images ceil(62.5) = 63 and 50 images ceil(78.125) = 79 (rounded up, not down); 100 images 157,
    capped at 150. Without real_passes every count gets real_steps; a cap below the floor wins."""
    cfg = TransferConfig()
    assert [real_step_budget(n, cfg) for n in (5, 25, 40, 50, 100, 240)] == [60, 60, 63, 79, 150, 150]
    assert real_step_budget(20, cfg.model_copy(update={"batch_size": 16})) == 63  # ceil(1000 / 16) = ceil(62.5)
    assert real_step_budget(5, TransferConfig(real_passes=None, real_steps=77)) == 77
    assert real_step_budget(240, TransferConfig(real_steps=20)) == 20  # the cap wins over the floor of 60
    assert real_step_budget(64, TransferConfig(real_passes=1.5, real_min_steps=1)) == 3


def _config(**kw) -> TransferConfig:
    small = dict(shots=(0, 1, "all"), folds=2, seeds=(0,), real_steps=2, finetune_steps=2, mixed_steps=2, batch_size=8,
                 preprocess=PreprocessConfig(n_velocity=32, n_time=32, time_mode="window", intensity="power",
                                             v_range_mps=6.0),
                 model=ModelConfig(n_branches=1, input_size=(32, 32), padding="same"),
                 pretrain=TrainConfig(epochs=1, group_split=False, batch_size=16))
    return TransferConfig(**{**small, **kw})


def test_no_test_image_reaches_a_training_and_a_study_resumes(tiny_dataset, glasgow_dir, tmp_path, monkeypatch):
    """Two people, two folds: every training's inputs are compared with the test fold's images (none may
    be among them); a second call with the same settings runs nothing and reports the same; other settings in
    the same folder are refused."""
    from processing.classifier import training, transfer_run

    original_run, original_train = transfer_run.run_task, training.train
    checked = []
    # distinct step counts per arm; the real-only budget, ceil(4.8 * 5 / 8) = 3, is below its cap of 9
    cfg = _config(real_passes=4.8, real_min_steps=1, real_steps=9, finetune_steps=2, mixed_steps=1)
    expected = {"real": 3, "finetune": 2, "mixed": 1}

    def run_and_check(task, state=None, data=None):
        inputs: list[np.ndarray] = []
        steps: list[int | None] = []

        def spy(x, y, *a, **k):
            inputs.append(np.asarray(x))
            steps.append(a[1].epoch_samples // a[1].batch_size if task.arm != "pretrain" else None)
            return original_train(x, y, *a, **k)

        monkeypatch.setattr(training, "train", spy)
        row = original_run(task, state, data)
        monkeypatch.setattr(training, "train", original_train)
        if task.arm != "pretrain":
            test = data["real"].x[data["folds"][task.fold]].reshape(len(data["folds"][task.fold]), -1)
            seen = inputs[0].reshape(len(inputs[0]), -1)
            assert not any((seen == t).all(axis=1).any() for t in test), task
            assert steps == [expected[task.arm]] and row["steps"] == expected[task.arm], (task, steps)
            assert real_step_budget(row["n_real"], cfg) == expected["real"]
            checked.append(task.key)
        return row

    monkeypatch.setattr(transfer_run, "run_task", run_and_check)
    out = tmp_path / "study"
    study = transfer_run.run_transfer(f"{tiny_dataset}", glasgow_dir, out, cfg, workers=1, progress=False, log=None)
    assert len(checked) == 2 * 3 * 2  # shots 1 and all x 3 arms x 2 folds
    assert {r["arm"] for r in study.rows} == {"sim", "real", "finetune", "mixed"} and len(study.rows) == 14
    assert all(r["n_test"] == 5 for r in study.rows)  # one person's five images (drink is not a class)
    for name in ("transfer.csv", "transfer.md", "transfer.png", "transfer.json", "pretrained_s0.pt", "runs.jsonl"):
        assert (out / name).is_file()
    assert len((out / "runs.jsonl").read_text().splitlines()) == 13  # 12 runs and the pretraining
    first = (out / "transfer.csv").read_text()

    def nothing_to_do(*a, **k):
        raise AssertionError("a finished study must not train again")

    monkeypatch.setattr(transfer_run, "run_task", nothing_to_do)
    again = transfer_run.run_transfer(f"{tiny_dataset}", glasgow_dir, out, cfg, workers=1, progress=False, log=None)
    assert (out / "transfer.csv").read_text() == first and len(again.rows) == 14
    with pytest.raises(InputError, match="holds a study with other settings"):
        transfer_run.run_transfer(f"{tiny_dataset}", glasgow_dir, out, cfg.model_copy(update={"real_share": 0.25}),
                                  workers=1, progress=False, log=None)


def test_two_worker_processes_give_the_runs_of_one(tiny_dataset, glasgow_dir, tmp_path):
    from processing.classifier.transfer_run import run_transfer

    cfg = _config(arms=("real", "finetune"), shots=(0, 1))
    one = run_transfer(f"{tiny_dataset}", glasgow_dir, tmp_path / "one", cfg, workers=1, progress=False, log=None)
    two = run_transfer(f"{tiny_dataset}", glasgow_dir, tmp_path / "two", cfg, workers=2, progress=False, log=None)
    key = {r["key"]: (r["accuracy"], r["train_loss"] if "train_loss" in r else None) for r in one.rows}
    assert key == {r["key"]: (r["accuracy"], r["train_loss"] if "train_loss" in r else None) for r in two.rows}


def test_cli_transfer_from_given_checkpoints(tiny_dataset, glasgow_dir, tmp_path, capsys):
    pre = tmp_path / "pre.pt"
    assert main(["train", "--data", str(tiny_dataset), "--out", str(pre), "--links", "radar1", "--size", "32", "32",
                 "--padding", "same", "--epochs", "1", "--no-group-split", "--quiet"]) == 0
    out = tmp_path / "cli"
    args = ["transfer", "--sim", str(tiny_dataset), "--images", str(glasgow_dir), "--out", str(out), "--folds", "2",
            "--shots", "0", "1", "--arms", "real", "mixed", "--real-steps", "2", "--mixed-steps", "2", "--workers", "1",
            "--real-passes", "0", "--quiet"]
    assert main([*args, "--pretrained", str(pre)]) == 0
    doc = json.loads((out / "transfer.json").read_text())
    assert {r["arm"] for r in doc["summary"]} == {"sim", "real", "mixed"} and "worth" in doc
    assert doc["config"]["real_passes"] is None  # --real-passes 0: always --real-steps
    assert "| arm | real per class |" in capsys.readouterr().out
    assert main([*args, "--pretrained", str(pre), str(pre)]) == 2
    assert main([*args[:-1], "--shots", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "one checkpoint per seed" in err[0]
