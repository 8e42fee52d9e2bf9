"""Real recordings as training data, only through the explicit path: `train --init` keeps the checkpoint's
preprocessing, `--data images:DIR` trains on labelled real images, several `--data` mix by weight, and every real
image a model saw is recorded and left out when the model is evaluated on real images."""
import json
import shutil

import numpy as np
import pytest
import torch

from processing.classifier import ModelConfig, PreprocessConfig, TrainConfig
from processing.errors import InputError
from rtchannel.cli import main

SMALL = ["--size", "32", "32", "--padding", "same", "--quiet", "--epochs", "1", "--threads", "1"]


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RTCHANNEL_CACHE_DIR", str(tmp_path / "cache"))


def test_init_keeps_the_checkpoints_preprocessing_and_refuses_another(tiny_dataset, tmp_path, capsys):
    from processing.classifier import load_checkpoint
    from rtchannel import train_classifier

    base = tmp_path / "base.pt"
    assert main(["train", "--data", str(tiny_dataset), "--out", str(base), "--links", "radar1", "--time-mode",
                 "window", "--no-group-split", *SMALL]) == 0
    start = load_checkpoint(base)
    # options left out take the checkpoint's values (here: links, time mode, size, padding)
    tuned = tmp_path / "tuned.pt"
    assert main(["train", "--data", str(tiny_dataset), "--out", str(tuned), "--init", str(base), "--quiet",
                 "--epochs", "1", "--no-group-split", "--lr", "1e-4", "--time-mode", "window"]) == 0
    clf = load_checkpoint(tuned)
    assert clf.preprocess == start.preprocess and clf.model.cfg == start.model.cfg and clf.links == ["radar1"]
    assert clf.meta["init"] == str(base)
    capsys.readouterr()
    # a given option that differs is refused, in one line, before any training
    assert main(["train", "--data", str(tiny_dataset), "--out", str(tmp_path / "x.pt"), "--init", str(base),
                 "--time-mode", "active", "--quiet"]) == 2
    assert main(["train", "--data", str(tiny_dataset), "--out", str(tmp_path / "x.pt"), "--init", str(base),
                 "--links", "radar1,radar2", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--time-mode active differs from the --init checkpoint's window" in err[0]
    assert "--links radar1,radar2 differs" in err[1] and not (tmp_path / "x.pt").exists()
    with pytest.raises(InputError, match="init: the preprocessing differs.*time_mode 'active'"):
        train_classifier(str(tiny_dataset), init=start, preprocess=start.preprocess.model_copy(
            update={"time_mode": "active"}), train_config=TrainConfig(epochs=1))


def test_source_weights_are_shares_of_the_draws():
    """Weights (1, 3) over 30 and 3 items: each item of the second source is drawn with probability 0.75 / 3 and
    of the first 0.25 / 30 (on paper); 20000 draws hold the second source's 75 % within 4 standard deviations
    (sqrt(0.75 * 0.25 / 20000) = 0.3 %). A source without training items drops out."""
    from processing.classifier.training import _source_probabilities

    sources = np.r_[np.zeros(30, int), np.ones(3, int)]
    p = _source_probabilities(sources, [1.0, 3.0], np.arange(33)).numpy()
    np.testing.assert_allclose(p[:30], 0.25 / 30, rtol=1e-12)
    np.testing.assert_allclose(p[30:], 0.75 / 3, rtol=1e-12)
    draws = torch.multinomial(torch.as_tensor(p), 20000, replacement=True, generator=torch.Generator().manual_seed(0))
    share = float((draws >= 30).float().mean())
    assert abs(share - 0.75) < 4 * np.sqrt(0.75 * 0.25 / 20000)
    only_first = _source_probabilities(sources, [1.0, 3.0], np.arange(30)).numpy()
    np.testing.assert_allclose(only_first, 1 / 30, rtol=1e-12)


def test_several_datasets_mix_by_weight_and_a_count_mismatch_is_one_line(tiny_dataset, tmp_path, capsys):
    from processing.classifier import load_checkpoint

    halves = [f"{tiny_dataset}:direction=1|4|7", f"{tiny_dataset}:direction=10|13|16"]
    out = tmp_path / "w.pt"
    assert main(["train", "--data", halves[0], "--data", halves[1], "--data-weights", "1", "3", "--out", str(out),
                 "--epoch-samples", "64", "--no-group-split", *SMALL]) == 0
    meta = load_checkpoint(out).meta
    assert meta["weights"] == [1.0, 3.0] and " + " in meta["train_spec"] and meta["real_images"] == []
    capsys.readouterr()
    assert main(["train", "--data", halves[0], "--data", halves[1], "--data-weights", "1", "--out", str(out),
                 *SMALL]) == 2
    assert "give one weight per --data (2), got 1" in capsys.readouterr().err


def test_real_images_train_are_recorded_and_left_out_of_evaluation(glasgow_dir, tmp_path, capsys):
    """Train on P36's images (`images:DIR:people=P36`): the checkpoint lists those five files with their
    sha256; `evaluate --images` on P36 and P46 warns, leaves the five out and scores P46's five."""
    from processing.classifier import load_checkpoint
    from processing.classifier.real_data import file_sha256

    model = tmp_path / "real.pt"
    assert main(["train", "--data", f"images:{glasgow_dir}:people=P36", "--links", "radar1", "--out", str(model),
                 "--no-group-split", "--val-fraction", "0.2", *SMALL]) == 0
    seen = load_checkpoint(model).meta["real_images"]
    assert sorted(r["file"] for r in seen) == sorted(f"{k}P36A0{k}R01.png" for k in (1, 2, 3, 4, 6))  # no drink (5)
    assert {r["role"] for r in seen} <= {"train", "validation"} and "train" in {r["role"] for r in seen}
    assert all(r["sha256"] == file_sha256(glasgow_dir / r["file"]) for r in seen)
    capsys.readouterr()
    ev = tmp_path / "ev"
    assert main(["evaluate", "--model", str(model), "--images", str(glasgow_dir), "--out", str(ev), "--quiet"]) == 0
    printed = capsys.readouterr()
    assert "warning: 5 of the images were training data of this model" in printed.out
    metrics = json.loads((ev / "metrics.json").read_text())
    assert metrics["n"] == 5 and metrics["left_out_seen_in_training"] == 5
    assert sorted(metrics["seen_in_training"]) == sorted(r["file"] for r in seen)
    # a folder of nothing but training images has nothing to test: one line, exit 2
    assert main(["evaluate", "--model", str(model), "--images", str(glasgow_dir), "--people", "P36",
                 "--out", str(tmp_path / "ev2"), "--quiet"]) == 2
    assert "was training data of this model" in capsys.readouterr().err


def test_image_specs_with_a_labels_csv_and_their_errors(glasgow_dir, tmp_path):
    from processing.classifier.experiment import load_dataset
    from processing.realdata.real_images import RealImageError

    renamed = tmp_path / "renamed"
    renamed.mkdir()
    shutil.copy(glasgow_dir / "1P36A01R01.png", renamed / "a.png")
    shutil.copy(glasgow_dir / "6P46A06R01.png", renamed / "b.png")
    (tmp_path / "labels.csv").write_text("file,activity,subject\na.png,walk,P36\nb.png,fall,P46\n")
    pre = PreprocessConfig(n_velocity=32, n_time=32, time_mode="window", intensity="power")
    ds = load_dataset(f"images:{renamed}", ["radar1"], pre, labels=tmp_path / "labels.csv")
    assert ds.names == ["a.png", "b.png"] and ds.groups == ["subject:P36", "subject:P46"]
    assert [ds.entries[i]["activity"] for i in range(2)] == ["walk", "fall"] and ds.x.shape == (2, 1, 32, 32)
    with pytest.raises(RealImageError, match="an image is one radar"):
        load_dataset(f"images:{renamed}", ["radar1", "radar2"], pre, labels=tmp_path / "labels.csv")
    with pytest.raises(RealImageError, match="pass --labels"):
        load_dataset(f"images:{renamed}", ["radar1"], pre)
    with pytest.raises(RealImageError, match="bad filter"):
        load_dataset(f"images:{renamed}:who=P36", ["radar1"], pre)


def test_an_ensemble_keeps_every_members_real_images():
    from processing.classifier import Classifier, build_model
    from processing.classifier.ensemble import ensemble
    from processing.labels import ACTIVITIES

    cfg = ModelConfig(n_branches=1, input_size=(32, 32), padding="same")
    members = []
    for k, files in enumerate((["a.png"], ["a.png", "b.png"])):
        torch.manual_seed(k)
        members.append(Classifier(build_model(cfg), PreprocessConfig(n_velocity=32, n_time=32), list(ACTIVITIES),
                                  ["radar1"], meta={"real_images": [{"file": f, "sha256": f * 2, "role": "train"}
                                                                    for f in files]}))
    vote = ensemble(members)
    assert sorted(r["file"] for r in vote.meta["real_images"]) == ["a.png", "b.png"]
