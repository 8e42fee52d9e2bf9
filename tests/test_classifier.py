"""Activity classifier: preprocessing, metrics against scikit-learn, training on a small simulated dataset,
checkpoint round trip, CLI train/evaluate/crossval and evaluation of .dat recordings."""
import json

import numpy as np
import pytest
import sklearn.metrics as skm
import torch

from processing.classifier import (Classifier, ModelConfig, PreprocessConfig, TrainConfig, build_model,
                                   classification_report, confusion_matrix, load_checkpoint, preprocess,
                                   save_checkpoint, split_indices, train)
from processing.classifier.metrics import plot_confusion, write_confusion_csv
from processing.io.dataset_store import ACTIVITIES
from rtchannel.cli import main

SMALL = ["--size", "32", "32", "--padding", "same", "--quiet"]


def test_preprocess_fixed_size_and_scaling():
    rng = np.random.default_rng(0)
    v = np.linspace(-6.2, 6.2, 64, endpoint=False)
    for t in (37, 140, 400):
        p = rng.random((64, t))
        img = preprocess(p, v, np.arange(t) * 0.016, PreprocessConfig(n_velocity=32, n_time=48))
        assert img.shape == (32, 48) and img.dtype == np.float32
        assert img.max() == pytest.approx(1.0, abs=1e-6) and img.min() >= 0.0
    # a pure tone at +2 m/s stays at +2 m/s on the fixed velocity grid (within one input bin, 12.4/32 m/s)
    p = np.zeros((64, 50))
    p[np.argmin(np.abs(v - 2.0))] = 1.0
    cfg = PreprocessConfig(n_velocity=32, n_time=32)
    grid = (np.arange(32) + 0.5) / 32 * 12.4 - 6.2
    assert abs(grid[preprocess(p, v, None, cfg).mean(axis=1).argmax()] - 2.0) <= 12.4 / 32
    # window mode keeps absolute time: a 1 s recording fills ~1/6 of a 6 s window
    img = preprocess(np.ones((64, 62)), v, np.arange(62) * 0.016, PreprocessConfig(time_mode="window", window_s=6.0))
    assert 0.12 < (img.max(axis=0) > 0).mean() < 0.22
    assert not preprocess(np.zeros((64, 10)), v).any()


@pytest.mark.parametrize("kw", [{}, {"n_branches": 1}, {"fusion": "sum"}, {"fusion": "max", "shared_weights": True},
                                {"kernel_size": 4, "padding": "same"}])
def test_model_variants_shapes(kw):
    cfg = ModelConfig(**kw)
    m = build_model(cfg)
    out = m(torch.zeros(3, cfg.n_branches, 64, 64))
    assert out.shape == (3, 5)
    convs = [c.out_channels for c in m.fens[0].modules() if isinstance(c, torch.nn.Conv2d)]
    assert convs == [64, 72, 80, 96]  # the seed's kernel counts
    with pytest.raises(ValueError, match="too small"):
        build_model(ModelConfig(input_size=(16, 16)))


def test_metrics_equal_sklearn():
    rng = np.random.default_rng(5)
    y = rng.integers(0, 5, 300)
    pred = np.where(rng.random(300) < 0.7, y, rng.integers(0, 5, 300))
    pred[pred == 3] = 2  # class 3 never predicted: precision 0 by convention (zero_division=0)
    rep = classification_report(y, pred, ACTIVITIES)
    np.testing.assert_array_equal(rep.confusion, skm.confusion_matrix(y, pred, labels=range(5)))
    assert rep.confusion.sum() == y.size
    assert rep.accuracy == pytest.approx(skm.accuracy_score(y, pred), abs=1e-12)
    p, r, f, _ = skm.precision_recall_fscore_support(y, pred, labels=range(5), zero_division=0)
    np.testing.assert_allclose(rep.precision, p, atol=1e-12)
    np.testing.assert_allclose(rep.recall, r, atol=1e-12)
    np.testing.assert_allclose(rep.f1, f, atol=1e-12)
    assert rep.macro_f1 == pytest.approx(skm.f1_score(y, pred, average="macro", zero_division=0), abs=1e-12)
    # a class absent from both y and pred does not enter the macro average (sklearn's default labels)
    y2, p2 = np.array([0, 1, 1, 0]), np.array([0, 1, 0, 0])
    assert classification_report(y2, p2, ACTIVITIES).macro_f1 == pytest.approx(skm.f1_score(y2, p2, average="macro"))
    with pytest.raises(ValueError):
        confusion_matrix([0, 7], [0, 1], 5)


def test_confusion_csv_and_png(tmp_path):
    y = np.array([0, 0, 1, 2, 3, 4, 4, 4])
    pred = np.array([0, 1, 1, 2, 3, 4, 4, 0])
    rep = classification_report(y, pred, ACTIVITIES)
    rows = write_confusion_csv(rep, tmp_path / "c.csv").read_text().splitlines()
    assert rows[0].split(",") == ["true \\ predicted", *ACTIVITIES, "recall"]
    counts = np.array([[int(v) for v in r.split(",")[1:6]] for r in rows[1:6]])
    assert counts.sum() == y.size and counts[4, 0] == 1
    assert float(rows[6].split(",")[-1]) == pytest.approx(6 / 8)
    assert plot_confusion(rep, tmp_path / "c.png").stat().st_size > 5000


def test_split_stratified_and_grouped():
    y = np.repeat(np.arange(5), 40)
    tr, va = split_indices(y, val_fraction=0.2, seed=1)
    assert va.size == 40 and np.all(np.bincount(y[va]) == 8) and not set(tr) & set(va)
    groups = [f"g{i // 5}" for i in range(200)]  # 40 motions, 5 augmented copies each
    tr, va = split_indices(y, groups, 0.2, seed=1)
    assert not {groups[i] for i in tr} & {groups[i] for i in va}
    assert 0.1 < va.size / 200 < 0.3 and set(y[va]) == set(range(5))


def test_training_reaches_high_accuracy_and_reload_is_identical(trained, tmp_path):
    reader, pre, x, y, res = trained
    va = res.val_idx
    clf = Classifier(model=res.model, preprocess=pre, classes=list(ACTIVITIES), links=["radar1", "radar2"])
    acc = (clf.predict(x[va]) == y[va]).mean()
    # 24 validation items of 5 noiseless, well separated classes; measured 1.0. 0.85 allows ~3 errors
    # (seed or BLAS changes) yet fails for a broken pipeline (chance is 0.2).
    assert acc >= 0.85, (acc, res.history["val_acc"])
    assert va.size == 24 and np.bincount(y[va], minlength=5).min() >= 4  # stratified 80:20 of 24 per class
    path = save_checkpoint(tmp_path / "m.pt", clf, history=res.history)
    again = load_checkpoint(path)
    assert again.classes == list(ACTIVITIES) and again.preprocess == pre and again.links == ["radar1", "radar2"]
    np.testing.assert_array_equal(again.predict_proba(x), clf.predict_proba(x))  # same weights, same kernels


def test_training_is_deterministic(tiny_dataset):
    rng = np.random.default_rng(0)
    x = rng.random((40, 2, 32, 32), dtype=np.float32)
    y = np.repeat(np.arange(5), 8)
    cfg = TrainConfig(epochs=2, group_split=False, seed=4, threads=1)
    a = train(x, y, ModelConfig(input_size=(32, 32), padding="same"), cfg, progress=False, log=None)
    b = train(x, y, ModelConfig(input_size=(32, 32), padding="same"), cfg, progress=False, log=None)
    assert a.history["train_loss"] == b.history["train_loss"]


def test_cli_train_evaluate_crossval(tiny_dataset, tmp_path, capsys):
    model = tmp_path / "m.pt"
    args = ["--epochs", "3", "--no-group-split", "--threads", "1", *SMALL]
    assert main(["train", "--data", str(tiny_dataset), "--out", str(model), *args]) == 0
    for name in ("m.pt", "m_curves.png", "m_val_confusion.png", "m_val_confusion.csv"):
        assert (tmp_path / name).is_file()
    out = tmp_path / "ev"
    assert main(["evaluate", "--model", str(model), "--data", f"{tiny_dataset}:activity=walk|fall",
                 "--out", str(out), "--quiet"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["n"] == 48 and np.sum(metrics["confusion"]) == 48
    table = tmp_path / "cv.csv"
    assert main(["crossval", "--train", f"{tiny_dataset}:direction=1|7|13", "--test",
                 f"{tiny_dataset}:direction=4|10|16", "--test", f"{tiny_dataset}:direction=1|7|13",
                 "--out", str(table), *args]) == 0
    rows = table.read_text().splitlines()
    assert len(rows) == 3 and rows[1].split(",")[4] == "60"  # 60 items in the unseen directions
    assert "held-out validation split" in rows[2] and (tmp_path / "cv.md").is_file()
    # user errors: one line, exit 2
    capsys.readouterr()
    assert main(["evaluate", "--model", str(tmp_path / "none.pt"), "--data", str(tiny_dataset)]) == 2
    assert main(["train", "--data", f"{tiny_dataset}:activity=swim", "--out", str(model), *args]) == 2
    assert main(["train", "--data", f"{tiny_dataset}:activity", "--out", str(model), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(e.startswith("error: ") for e in err)


def test_evaluate_recordings_from_dat(trained, tmp_path):
    """Simulated IQ written as .dat recordings, evaluated with one command, match the dataset's result."""
    from processing.realdata.ancortek import write_dat
    from rtchannel.motion.procedural import generate
    from rtchannel.radar import RadarConfig, direction_angles
    from rtchannel.pipeline import simulate

    reader, pre, x, y, res = trained
    clf = Classifier(model=res.model, preprocess=pre, classes=list(ACTIVITIES), links=["radar1", "radar2"])
    model = save_checkpoint(tmp_path / "m.pt", clf)
    radar = RadarConfig().rotated(direction_angles(4)[0])
    rec_dir = tmp_path / "rec"
    samples = []
    for act in ("fall", "walk"):
        kw = {"distance": 2.0, "start": (-1.0, 0.0)} if act == "walk" else {"duration": 1.2}
        motion = generate(act, fps=30.0, height=1.7, seed=5, pad_before=0.2, pad_after=0.2, **kw)
        sim = simulate(motion, radar, keep_iq=True)
        for link in ("radar1", "radar2"):
            write_dat(rec_dir / "pairs" / f"{act}_01_{link}.dat", sim.links[link].iq, radar.waveform)
        write_dat(rec_dir / "two" / f"take_{act}.dat", [sim.links["radar1"].iq, sim.links["radar2"].iq],
                  radar.waveform)
        samples.append({n: vars(r.signature) for n, r in sim.links.items()})
    expected = clf.predict_proba(clf.inputs(samples))
    out = tmp_path / "ev"
    assert main(["evaluate", "--model", str(model), "--recordings", str(rec_dir / "pairs"), "--out", str(out),
                 "--quiet"]) == 0
    pairs = [r.split(",") for r in (out / "predictions.csv").read_text().splitlines()[1:]]
    assert [r[:2] for r in pairs] == [["fall_01", "fall"], ["walk_01", "walk"]]  # paired by name, labelled
    assert main(["evaluate", "--model", str(model), "--recordings", str(rec_dir / "two"), "--channels", "2",
                 "--out", str(out), "--quiet"]) == 0
    rows = [r.split(",") for r in (out / "predictions.csv").read_text().splitlines()[1:]]
    assert [r[1] for r in rows] == ["fall", "walk"]  # labels from the file names
    # confidence of the .dat path equals that of the simulated signatures (same IQ, same DSP)
    got = np.array([float(r[3]) for r in rows])
    # (atol 1e-4: predictions.csv rounds confidences to 4 decimals)
    np.testing.assert_allclose(got, expected.max(axis=1), atol=1e-4)
    np.testing.assert_allclose([float(r[3]) for r in pairs], expected.max(axis=1), atol=1e-4)
    # a spectrogram model (intensity 'power') gets the recordings' column power and valid mask as well
    spec = Classifier(model=res.model, preprocess=pre.model_copy(update={"intensity": "power"}),
                      classes=list(ACTIVITIES), links=["radar1", "radar2"])
    expected = spec.predict_proba(spec.inputs(samples))
    assert main(["evaluate", "--model", str(save_checkpoint(tmp_path / "s.pt", spec)), "--recordings",
                 str(rec_dir / "two"), "--channels", "2", "--out", str(out), "--quiet"]) == 0
    rows = [r.split(",") for r in (out / "predictions.csv").read_text().splitlines()[1:]]
    np.testing.assert_allclose([float(r[3]) for r in rows], expected.max(axis=1), atol=1e-4)


def test_active_time_mode_crops_idle_standing():
    from processing.classifier.preprocess import PreprocessConfig, preprocess

    v = np.linspace(-6.2, 6.2, 64, endpoint=False) + 0.097
    t = np.arange(500) * 0.016                       # 8 s at 16 ms bins
    p = np.zeros((64, 500))
    p[32] = 1.0                                      # standing still: all energy at v = 0
    p[40, 200:300] = 5.0                             # 1.6 s of motion at +1.6 m/s
    cfg = PreprocessConfig(time_mode="active", active_margin_s=0.0, n_time=50)
    whole = preprocess(p, v, t, PreprocessConfig(n_time=50, time_mode="resample"))
    act = preprocess(p, v, t, cfg)
    # the active span (bins 200..299) fills the whole image; the whole-recording image shows it in 1/5
    moving = act[40] > 0.5
    assert moving.all()
    assert (whole[40] > 0.5).sum() == 10
    np.testing.assert_allclose(act, preprocess(p[:, 200:300], v, t[200:300],
                                               PreprocessConfig(n_time=50, time_mode="resample")))


def _small_clf():
    cfg = ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8)
    torch.manual_seed(0)
    return Classifier(model=build_model(cfg), preprocess=PreprocessConfig(n_velocity=16, n_time=16),
                      classes=list(ACTIVITIES), links=["radar1", "radar2"])


def _tampered(tmp_path, edit):
    path = save_checkpoint(tmp_path / "ok.pt", _small_clf())
    blob = torch.load(path, weights_only=True)
    edit(blob)
    bad = tmp_path / "bad.pt"
    torch.save(blob, bad)
    return bad


@pytest.mark.parametrize("edit, message", [
    (lambda b: b.pop("state_dict"), r"missing field 'state_dict'"),
    (lambda b: b.update(classes="walk"), r"invalid field 'classes'"),
    (lambda b: b["state_dict"].pop("mlp.0.weight"), r"state_dict lacks 'mlp.0.weight'"),
    (lambda b: b["state_dict"].update({"extra.w": torch.zeros(1)}), r"state_dict has unexpected 'extra.w'"),
    (lambda b: b["state_dict"].update({"mlp.0.weight": torch.zeros(3, 3)}), r"'mlp.0.weight' has shape \[3, 3\]"),
    (lambda b: b["state_dict"]["mlp.0.bias"].fill_(float("nan")), r"'mlp.0.bias' holds non-finite values"),
    (lambda b: b["model_config"].update(mlp_hidden=200_000_000), r"model_config.mlp_hidden: Input should be less"),
    (lambda b: b["model_config"].update(mlp_hidden=60_000, channels=[64, 64]), r"model_config.\(root\): .*parameters"),
    (lambda b: b["model_config"].update(input_size=[4096, 4096]), r"model_config.*MiB of activations"),
    (lambda b: b["preprocess"].update(floor_db=float("inf")), r"preprocess.floor_db: Input should be a finite"),
    (lambda b: b["preprocess"].update(n_time=32), r"preprocess makes 16 x 32 images but the network takes 16 x 16"),
    (lambda b: b.update(links=["radar1"]), r"links has 1 names but the network has 2"),
])
def test_bad_checkpoints_are_one_line_errors_before_allocating(tmp_path, edit, message):
    from processing.errors import CheckpointError
    bad = _tampered(tmp_path, edit)
    with pytest.raises(CheckpointError, match=message) as exc:
        load_checkpoint(bad)
    assert "\n" not in str(exc.value) and "bad.pt" in str(exc.value)


def test_checkpoint_garbage_and_cli_exit_status(tmp_path, capsys):
    from processing.errors import CheckpointError
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"\x80\x02not a zip")
    with pytest.raises(CheckpointError, match="junk.pt is not a classifier checkpoint"):
        load_checkpoint(junk)
    bad = _tampered(tmp_path, lambda b: b["model_config"].update(mlp_hidden=2e8))
    assert main(["evaluate", "--model", str(bad), "--recordings", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "mlp_hidden" in err[0]


def test_diverging_training_raises_and_saves_nothing(tmp_path):
    from processing.errors import TrainingError
    rng = np.random.default_rng(1)
    x = rng.random((40, 2, 16, 16), dtype=np.float32)
    y = np.repeat(np.arange(5), 8)
    mcfg = ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8, batch_norm=False)
    with pytest.raises(TrainingError, match="training diverged: the .*loss became (nan|inf)"):
        # +-3.3e38 inputs: the first conv sums +inf and -inf (float32 overflow), the loss is nan
        train(np.where(x > 0.5, 3.3e38, -3.3e38).astype(np.float32), y, mcfg,
              TrainConfig(epochs=3, lr=1.0, group_split=False, threads=1), progress=False, log=None)
    x_nan = x.copy()
    x_nan[3, 0, 2, 2] = np.nan
    with pytest.raises(TrainingError, match="non-finite"):
        train(x_nan, y, mcfg, TrainConfig(epochs=1, group_split=False, threads=1), progress=False, log=None)
    clf = _small_clf()
    with torch.no_grad():
        clf.model.mlp[0].weight[0, 0] = float("inf")
    from processing.errors import CheckpointError
    with pytest.raises(CheckpointError, match="non-finite values; the model was not saved"):
        save_checkpoint(tmp_path / "m.pt", clf)
    assert list(tmp_path.iterdir()) == []


def test_training_defaults_to_one_pinned_thread(monkeypatch):
    """Weights depended on the thread count (1 vs 2 threads differ after one step) and the old default
    picked it from the machine's load; the default is now pinned."""
    import importlib
    tr = importlib.import_module("processing.classifier.training")  # the package's `train` is the function
    monkeypatch.setattr(tr, "auto_threads", lambda: 2)  # whatever the load says
    tr.setup_torch(0)
    assert torch.get_num_threads() == 1
    for bad in (dict(lr=float("inf")), dict(lr=10.0), dict(seed=2**40), dict(epochs=10**9)):
        with pytest.raises(Exception, match="lr|seed|epochs"):
            TrainConfig(**bad)


def test_checkpoint_unpacking_to_more_than_the_limit_is_refused_unread(tmp_path):
    """A zip member whose declared size exceeds the limit (a deflate bomb) is refused from the directory."""
    import zipfile
    from processing.errors import CheckpointError
    p = tmp_path / "bomb.pt"
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as z:
        with z.open("archive/data/0", "w", force_zip64=True) as f:
            block = bytes(1 << 20)
            for _ in range(1100):  # 1.1 GiB of zeros, ~1 MB compressed
                f.write(block)
    assert p.stat().st_size < 5 << 20
    with pytest.raises(CheckpointError, match=r"bomb\.pt: 1100 MiB is larger than any valid checkpoint"):
        load_checkpoint(p)


def test_window_centres_on_the_valid_motion_not_on_noise_columns():
    """A 5 s recording (16 ms bins) with a 1 s activity at 0.5-1.5 s and noise elsewhere: a noise column's
    p(v,t) is flat over v, which the motion measure reads as much motion (|v| averages a quarter of the
    axis), so 3.5 s of noise pulled the 2 s window's centre to ~2.5 s and cut the activity out. With the
    valid mask the window holds the whole activity."""
    from processing.classifier.preprocess import _time_window

    v = np.linspace(-6, 6, 64)
    t = np.arange(312) * 0.016
    act = (t >= 0.5) & (t < 1.5)
    p = np.full((64, t.size), 1 / 64)
    p[:, act] = 0.0
    p[np.argmin(np.abs(v - 1.0)), act] = 1.0  # a 1 m/s line
    cfg = PreprocessConfig(time_mode="window", window_s=2.0, n_time=64)
    inside = _time_window(p, t, cfg, valid=act)
    assert (inside.max(axis=0) == 1.0).sum() == act.sum() == 62  # every activity column inside the window
    legacy = _time_window(p, t, cfg.model_copy(update={"window_valid_only": False}), valid=act)
    assert (legacy.max(axis=0) == 1.0).sum() < 31  # noise-centred: most of the activity falls outside it
    # old checkpoints keep what they were trained with
    from processing.classifier.checkpoint import LEGACY_PREPROCESS

    assert LEGACY_PREPROCESS["window_valid_only"] is False


def test_window_weighs_motion_by_column_power_when_noise_passes_the_valid_mask():
    """The same recording seen with a noise floor only 25 dB under the activity (a weaker radar or a farther
    person): every column passes the valid threshold, and only the columns' power tells noise from motion."""
    from processing.classifier.preprocess import _time_window

    v = np.linspace(-6, 6, 64)
    t = np.arange(312) * 0.016
    act = (t >= 0.5) & (t < 1.5)
    p = np.full((64, t.size), 1 / 64)
    p[:, act] = 0.0
    p[np.argmin(np.abs(v - 1.0)), act] = 1.0
    power = np.where(act, 1.0, 10 ** -2.5)
    cfg = PreprocessConfig(time_mode="window", window_s=2.0, n_time=64)
    valid = np.ones(t.size, bool)
    kept = _time_window(p, t, cfg, valid=valid, power=power)
    assert (kept.max(axis=0) == 1.0).sum() == act.sum()
    unweighted = _time_window(p, t, cfg.model_copy(update={"window_power": False}), valid=valid, power=power)
    assert (unweighted.max(axis=0) == 1.0).sum() < 31
    # the full pipeline reads `power` from the sample, as it reads `valid`
    from processing.classifier.preprocess import preprocess_links

    sample = {"r": {"p_vt": p, "velocity": v, "time": t, "valid": valid, "power": power}}
    x = preprocess_links(sample, ["r"], cfg)
    assert x.shape == (1, 64, 64) and np.isfinite(x).all()
    with pytest.raises(ValueError, match="power has 3 time bins"):
        preprocess_links({"r": {**sample["r"], "power": np.ones(3)}}, ["r"], cfg)


def test_library_training_is_the_clis_and_can_start_from_a_checkpoint(tiny_dataset, tmp_path):
    """`train_classifier` is what `rtchannel train` runs (same weights for the same settings and seed), takes
    several datasets, starts from a checkpoint's weights (`init=`) and is called in a loop from Python."""
    from processing.classifier import load_checkpoint
    from processing.errors import InputError
    from rtchannel import evaluate_classifier, train_classifier

    pre = PreprocessConfig(n_velocity=32, n_time=32)
    mcfg = ModelConfig(input_size=(32, 32), padding="same")
    cfg = TrainConfig(epochs=1, group_split=False, threads=1, seed=2)
    lib = train_classifier(str(tiny_dataset), preprocess=pre, model=mcfg, train_config=cfg)
    assert main(["train", "--data", str(tiny_dataset), "--out", str(tmp_path / "cli.pt"), "--epochs", "1",
                 "--no-group-split", "--threads", "1", "--seed", "2", *SMALL]) == 0
    cli = load_checkpoint(tmp_path / "cli.pt")
    for (k, a), b in zip(lib.classifier.model.state_dict().items(), cli.model.state_dict().values()):
        assert torch.equal(a, b), k
    assert lib.meta["n_train"] + lib.meta["n_val"] == 120 and "validation accuracy" in repr(lib)
    # several datasets are one training set
    halves = [f"{tiny_dataset}:direction=1|4|7", f"{tiny_dataset}:direction=10|13|16"]
    both = train_classifier(halves, preprocess=pre, model=mcfg, train_config=cfg)
    assert both.meta["n_train"] + both.meta["n_val"] == 120 and " + " in both.meta["train_spec"]
    # init: training starts from the given weights (a learning rate of 1e-12 leaves them where they were)
    lib.save(tmp_path / "lib.pt")
    still = TrainConfig(epochs=1, group_split=False, threads=1, seed=5, lr=1e-12)
    from processing.classifier.experiment import load_dataset

    half = load_dataset(halves[0], preprocess=pre)  # loaded once, trained on in a loop
    for init in (lib.classifier, tmp_path / "lib.pt"):
        tuned = train_classifier(half, preprocess=pre, model=mcfg, train_config=still, init=init)
        w0, w1 = (c.model.mlp[0].weight for c in (lib.classifier, tuned.classifier))
        np.testing.assert_allclose(w1.detach().numpy(), w0.detach().numpy(), rtol=0, atol=1e-9)
    scratch = train_classifier(half, preprocess=pre, model=mcfg, train_config=still)
    assert not torch.allclose(scratch.classifier.model.mlp[0].weight, lib.classifier.model.mlp[0].weight)
    with pytest.raises(InputError, match="init: the checkpoint's network"):
        train_classifier(half, links=["radar1"], preprocess=pre, train_config=still, init=lib.classifier,
                         model=mcfg.model_copy(update={"n_branches": 1}))
    ev = evaluate_classifier(tmp_path / "lib.pt", f"{tiny_dataset}:activity=walk|fall")
    assert ev.report.n == 48 and ev.title.startswith("lib.pt on ")
    assert sorted(p.name for p in ev.save(tmp_path / "ev")) == ["confusion.csv", "confusion.png", "metrics.json",
                                                                 "predictions.csv"]
