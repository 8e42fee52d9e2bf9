"""Sim-to-real on real spectrogram images (twelve Glasgow images through the data registry): `evaluate --images` with
a tiny model trained here on synthetic inputs, the noise-aware valid mask, the active-span fix, and the real-data
Table I (`compare --real`)."""
import csv
import json
import shutil

import numpy as np
import pytest
import sklearn.metrics as skm
import torch

from processing.classifier import (Classifier, ModelConfig, PreprocessConfig, build_model, load_checkpoint,
                                   preprocess, save_checkpoint)
from processing.classifier.images import evaluate_images, image_inputs
from processing.io.dataset_store import ACTIVITIES
from processing.dsp.signatures import Signature
from processing.metrics.distances import normalised_dtw
from processing.realdata.real_images import (NOISE_COLUMN_DB, RealImageError, load_real_images, parse_people,
                                    read_real_image)
from processing.io.signature_file import write_signature_file
from processing.metrics.sim_real_table import (Curve, curves_from_images, dtw_activity_table, resample)
from rtchannel.cli import main
from thirdparty import GLASGOW_TEST_IMAGES, glasgow_folder_if_available, needs

GLASGOW = glasgow_folder_if_available()  # the twelve real test images, through the data registry
needs_glasgow = needs(*GLASGOW_TEST_IMAGES)
PRE = PreprocessConfig(n_velocity=32, n_time=32)
V = np.linspace(-6.2, 6.2, 64, endpoint=False)


def _line(v0: float, t: int, rng) -> np.ndarray:
    """Column-normalised p(v,t) [64, t] on V: a Gaussian line at v0 (conftest's `velocity_line`; the session
    fixture `model_path` was trained on such lines)."""
    from conftest import velocity_line

    return velocity_line(v0, t, rng)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@needs_glasgow
def test_evaluate_images_metrics_consistent_and_drink_apart(model_path, tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["evaluate", "--model", str(model_path), "--images", str(GLASGOW), "--out", str(out)]) == 0
    for name in ("confusion.png", "confusion.csv", "metrics.json", "predictions.csv", "unknown_predictions.csv",
                 "unknown_counts.csv"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    cm = np.array(m["confusion"])
    # 12 images, 2 of them drink (not a model class): 10 counted, 2 reported apart
    assert m["n"] == 10 == cm.sum() and m["n_unknown"] == 2
    assert m["unknown_classes"]["drink"]["n"] == 2 and sum(m["unknown_classes"]["drink"]["predicted"].values()) == 2
    assert m["accuracy"] == pytest.approx(np.trace(cm) / cm.sum(), abs=1e-12)
    rows = _rows(out / "predictions.csv")
    assert len(rows) == 10 and "drink" not in {r["true"] for r in rows}
    y_true, y_pred = [r["true"] for r in rows], [r["predicted"] for r in rows]
    assert m["macro_f1"] == pytest.approx(skm.f1_score(y_true, y_pred, average="macro", zero_division=0), abs=1e-12)
    assert m["accuracy"] == pytest.approx(skm.accuracy_score(y_true, y_pred), abs=1e-12)
    # probabilities: one column per class, rows sum to 1 (5 values rounded to 6 decimals: <= 2.5e-6 off)
    probs = np.array([[float(r[f"p_{c}"]) for c in ACTIVITIES] for r in rows])
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-5)
    assert [ACTIVITIES[i] for i in probs.argmax(axis=1)] == y_pred
    unk = _rows(out / "unknown_predictions.csv")
    assert sorted(r["file"] for r in unk) == ["5P36A05R01.png", "5P46A05R01.png"]
    counts = _rows(out / "unknown_counts.csv")
    assert len(counts) == 1 and counts[0]["true \\ predicted"] == "drink" and counts[0]["n"] == "2"
    # the confusion CSV (seed layout) holds the same counts
    grid = list(csv.reader(open(out / "confusion.csv")))
    assert grid[0][1:-1] == list(ACTIVITIES)
    np.testing.assert_array_equal(np.array([[int(v) for v in r[1:-1]] for r in grid[1:-1]]), cm)
    assert "not in accuracy" in capsys.readouterr().out


@needs_glasgow
def test_people_filter_splits_subjects(model_path, tmp_path):
    assert parse_people("P36-P45") == frozenset(range(36, 46))
    assert parse_people("36,P40-P41") == frozenset({36, 40, 41})
    with pytest.raises(RealImageError):
        parse_people("P45-P36")
    for people, subject in (("P36-P45", "P36"), ("P46-P56", "P46")):
        out = tmp_path / subject
        assert main(["evaluate", "--model", str(model_path), "--images", str(GLASGOW), "--people", people,
                     "--out", str(out)]) == 0
        rows = _rows(out / "predictions.csv")
        assert len(rows) == 5 and {r["subject"] for r in rows} == {subject}
        assert json.loads((out / "metrics.json").read_text())["n_unknown"] == 1


@needs_glasgow
def test_image_input_is_the_simulated_preprocessing(model_path):
    clf = load_checkpoint(model_path)
    images, bad = load_real_images(GLASGOW, people=frozenset({36}))
    assert not bad and len(images) == 6
    x = image_inputs(clf, images)
    for im, xi in zip(images, x):
        s = im.signature
        np.testing.assert_array_equal(xi[0], preprocess(s.p_vt, s.velocity, s.time, clf.preprocess, s.valid))
    ev = evaluate_images(clf, images)
    assert ev.report.n == 5 and [im.activity for im in ev.unknown] == ["drink"]


@needs_glasgow
def test_non_glasgow_names_need_labels(model_path, tmp_path, capsys):
    folder = tmp_path / "imgs"
    folder.mkdir()
    shutil.copy(GLASGOW / "1P36A01R01.png", folder / "my_walk.png")
    shutil.copy(GLASGOW / "6P36A06R01.png", folder / "my_fall.png")
    out = tmp_path / "ev"
    assert main(["evaluate", "--model", str(model_path), "--images", str(folder), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "my_fall.png" in err and "--labels" in err and len(err.splitlines()) == 1
    labels = tmp_path / "labels.csv"
    labels.write_text("file,activity,subject\nmy_walk.png,walk,P1\nmy_fall.png,fall,2\n")
    assert main(["evaluate", "--model", str(model_path), "--images", str(folder), "--labels", str(labels),
                 "--out", str(out)]) == 0
    rows = _rows(out / "predictions.csv")
    assert {(r["file"], r["true"], r["subject"]) for r in rows} == {("my_walk.png", "walk", "P1"),
                                                                    ("my_fall.png", "fall", "P2")}


@needs_glasgow
def test_two_branch_model_rejected(tmp_path, capsys):
    mcfg = ModelConfig(n_classes=5, n_branches=2, input_size=(32, 32), padding="same")
    torch.manual_seed(0)
    clf = Classifier(model=build_model(mcfg), preprocess=PRE, classes=list(ACTIVITIES), links=["radar1", "radar2"])
    path = save_checkpoint(tmp_path / "two.pt", clf)
    assert main(["evaluate", "--model", str(path), "--images", str(GLASGOW), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "2 branches" in err and len(err.splitlines()) == 1


@needs_glasgow
def test_noise_aware_valid_on_real_images():
    # walks never drop below -22 dB column power (all 360 measured); the fall 6P36 is a ~1 s event in
    # 5 s with the rest at -36 dB (its median column), so most of its columns are noise only
    walk = read_real_image(GLASGOW / "1P36A01R01.png")
    assert walk.valid.all()
    fall = read_real_image(GLASGOW / "6P36A06R01.png")
    assert 0.1 < fall.valid.mean() < 0.6
    assert (fall.mean_velocity[~fall.valid] == 0).all()
    rel_db = 10 * np.log10(np.maximum(fall.power, 1e-300) / fall.power.max())
    assert (rel_db[~fall.valid] < NOISE_COLUMN_DB).all() and (rel_db[fall.valid] >= NOISE_COLUMN_DB).all()


def test_active_span_ignores_noise_only_columns():
    t = np.arange(500) * 0.016
    p = np.full((64, 500), 1 / 64)                  # noise only: spread evenly over v (|v| bins ~ 16)
    p[:, 200:300] = 0.0
    p[40, 200:300] = 1.0                             # 1.6 s of motion at +1.6 m/s (8 bins from zero)
    valid = np.zeros(500, bool)
    valid[200:300] = True
    cfg = PreprocessConfig(active_margin_s=0.0, n_time=50)
    crop = preprocess(p[:, 200:300], V, t[200:300], PreprocessConfig(n_time=50, time_mode="resample"))
    np.testing.assert_allclose(preprocess(p, V, t, cfg, valid), crop)
    # without the mask, the noise columns' spread looks like more motion than the line: whole recording
    whole = preprocess(p, V, t, PreprocessConfig(n_time=50, time_mode="resample"))
    np.testing.assert_allclose(preprocess(p, V, t, cfg), whole)
    np.testing.assert_allclose(preprocess(p, V, t, cfg.model_copy(update={"active_valid_only": False}), valid), whole)


def test_old_checkpoints_keep_the_old_active_span(model_path, tmp_path):
    blob = torch.load(model_path, weights_only=True)
    del blob["preprocess"]["active_valid_only"]
    torch.save(blob, tmp_path / "old.pt")
    assert load_checkpoint(tmp_path / "old.pt").preprocess.active_valid_only is False
    assert load_checkpoint(model_path).preprocess.active_valid_only is True


# ---- Table I against real recordings ---------------------------------------------------------------
@needs_glasgow
def test_real_vs_real_table_has_zero_diagonal():
    images, _ = load_real_images(GLASGOW, people=frozenset({36}))
    curves = curves_from_images(images)
    tab = dtw_activity_table(curves, curves)
    assert tab.rows == tab.cols == ["fall", "walk", "stand", "sit", "pick", "drink"]
    np.testing.assert_array_equal(np.diag(tab.mean), 0.0)
    np.testing.assert_allclose(tab.mean, tab.mean.T, atol=1e-12)  # DTW is symmetric
    off = tab.mean[~np.eye(6, dtype=bool)]
    # different activities differ; RMS/peak normalisation bounds a pair by ~2 (opposite peaks)
    assert off.min() > 0.05 and off.max() < 2.0


def _signature(t: np.ndarray, mean_v: np.ndarray) -> Signature:
    p = np.zeros((64, t.size))
    p[np.clip(np.searchsorted(V, mean_v), 0, 63), np.arange(t.size)] = 1.0
    return Signature(time=t, velocity=V, p_vt=p, mean_velocity=mean_v, range=np.zeros(1),
                     range_distribution=np.ones((1, t.size)), valid=np.ones(t.size, bool), power=np.ones(t.size))


@needs_glasgow
def test_compare_real_cli_writes_table_with_real_columns(tmp_path):
    t = np.arange(250) * 0.016
    for act, v in (("walk", 1.3 * np.sin(np.pi * t / t[-1])), ("fall", -2.0 * np.exp(-((t - 2) / 0.3) ** 2))):
        write_signature_file(tmp_path / "sim" / act / "signature.h5", {"radar1": _signature(t, v)}, activity=act,
                             backend="points", seed=0, direction_deg=0.0, config={})
    out = tmp_path / "tab"
    assert main(["compare", "--real", str(GLASGOW), "--sim", str(tmp_path / "sim"), "--people", "P36",
                 "--out", str(out)]) == 0
    grid = list(csv.reader(open(out / "dtw_simulated_vs_real.csv")))
    assert grid[0] == ["simulated \\ real", "fall", "walk", "stand", "sit", "pick", "drink"]
    assert [r[0] for r in grid[1:]] == ["fall", "walk"]
    assert (out / "dtw_simulated_vs_real.png").is_file()
    # one real image per activity (P36): a cell is the normalised DTW of that one pair
    real = {im.activity: im for im in load_real_images(GLASGOW, people=frozenset({36}))[0]}
    sim_walk = Curve("w", "walk", t, 1.3 * np.sin(np.pi * t / t[-1]))
    im = real["fall"]
    want = normalised_dtw(resample(sim_walk, 0.016), resample(Curve("r", "fall", im.signature.time,
                                                                    im.signature.mean_velocity), 0.016))
    assert float(grid[2][1]) == pytest.approx(want, abs=5e-5)  # CSV keeps 4 decimals


@needs_glasgow
def test_compare_real_needs_a_simulated_side(tmp_path, capsys):
    assert main(["compare", "--real", str(GLASGOW), "--out", str(tmp_path / "o")]) == 2
    assert "--sim" in capsys.readouterr().err


def _glasgow_like(path, v0: float, seconds: float = 5.0):
    """A Glasgow-layout image the test makes itself: one Gaussian line at v0 m/s over the whole clip."""
    from processing.realdata.spectrogram_image import glasgow_layout
    from processing.realdata.spectrogram_image_writer import write_spectrogram_image

    v = np.linspace(-6, 6, 317)
    t = np.linspace(0, seconds, 120)
    power = np.exp(-0.5 * ((v[:, None] - v0) / 0.3) ** 2) + 1e-4
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_spectrogram_image(path, v, t * np.ones(1), glasgow_layout(seconds), power=power * np.ones((1, t.size)))


def test_images_in_sub_folders_are_traced_to_their_files_and_self_contradicting_names_skipped(model_path, tmp_path,
                                                                                            capsys):
    """Campaigns reuse subject numbers: predictions carry the path relative to --images and metrics come per
    sub-folder; a name whose activity digit contradicts its A-code is warned about and skipped, not fatal."""
    root = tmp_path / "images"
    _glasgow_like(root / "campA" / "1P01A01R01.png", 1.5, 10.0)  # walk, approaching
    _glasgow_like(root / "campB" / "1P01A01R01.png", 1.5, 10.0)  # same name, other campaign
    _glasgow_like(root / "campB" / "6P02A06R01.png", -1.5)       # fall, receding
    _glasgow_like(root / "campB" / "3P03A02R01.png", 0.5)        # digit 3 (stand) but code A02 (sit)
    out = tmp_path / "out"
    assert main(["evaluate", "--model", str(model_path), "--images", str(root), "--out", str(out)]) == 0
    assert "warning: campB/3P03A02R01.png: skipped, its name contradicts itself" in capsys.readouterr().err
    rows = _rows(out / "predictions.csv")
    assert sorted(r["file"] for r in rows) == ["campA/1P01A01R01.png", "campB/1P01A01R01.png",
                                               "campB/6P02A06R01.png"]
    by_folder = {r["folder"]: r for r in _rows(out / "metrics_by_folder.csv")}
    assert set(by_folder) == {"campA", "campB"} and by_folder["campA"]["n"] == "1" and by_folder["campB"]["n"] == "2"
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["by_folder"]["campB"]["n"] == 2
    assert [u["file"] for u in metrics["unreadable"]] == ["campB/3P03A02R01.png"]


def test_spectrogram_models_read_real_images_with_their_column_power(model_path, tmp_path):
    """A model with `intensity='power'` gets each image's column power from the reader: its input is the
    spectrogram's preprocessing, and a column whose power is 20 dB lower than another's shows 20 dB lower."""
    import dataclasses

    from processing.realdata.spectrogram_image import glasgow_layout
    from processing.realdata.spectrogram_image_writer import write_spectrogram_image

    clf = load_checkpoint(model_path)
    spec = dataclasses.replace(clf, preprocess=clf.preprocess.model_copy(update={"intensity": "power"}))
    v, t = np.linspace(-6, 6, 317), np.linspace(0, 5.0, 120)
    level = np.where(t < 2.5, 1.0, 0.01)  # the second half of the clip 20 dB weaker
    power = np.exp(-0.5 * ((v[:, None] - 1.0) / 0.3) ** 2) * level + 1e-6
    write_spectrogram_image(tmp_path / "1P01A01R01.png", v, t, glasgow_layout(5.0), power=power)
    images, bad = load_real_images(tmp_path)
    assert not bad and len(images) == 1
    s = images[0].signature
    x_p, x_s = image_inputs(clf, images)[0, 0], image_inputs(spec, images)[0, 0]
    np.testing.assert_array_equal(x_s, preprocess(s.p_vt, s.velocity, s.time, spec.preprocess, s.valid, s.power))
    half = x_s.shape[1] // 2
    # the line's brightest input cell in each half: equal in p(v,t); 20 dB (0.5 of the 40 dB display) apart in
    # the spectrogram, to within the image's colour steps (40 dB over 256 colours: 0.16 dB) and the edge columns
    assert x_p[:, 2:half - 2].max() == pytest.approx(x_p[:, half + 2:-2].max(), abs=0.02)
    assert x_s[:, 2:half - 2].max() - x_s[:, half + 2:-2].max() == pytest.approx(0.5, abs=0.02)
    assert evaluate_images(spec, images).report.n == 1
