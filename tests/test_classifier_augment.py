"""Classifier input augmentation (processing.classifier.augment), its use in training, the CLI flags and the
time-pooled FEN (issue 27). Synthetic images and a tiny synthetic dataset only: fast."""
import numpy as np
import pytest
import torch

from processing.classifier import (Classifier, ModelConfig, PreprocessConfig, TrainConfig, build_model,
                                   load_checkpoint, save_checkpoint, train)
from processing.classifier.augment import AugmentConfig, augment_batch, noise_floor_columns, resample
from processing.io.dataset_store import ACTIVITIES
from rtchannel.cli import main

NO_GEO = dict(shift_s=0.0, stretch=(1.0, 1.0), vscale=(1.0, 1.0))
NO_DB = dict(db_floor=0.0, db_offset=0.0, noise_db=None)


def _image(b=2, c=2, v=32, t=40, seed=0):
    """Noise in [0.1, 0.3], one quietest column (col 7, 0.05), a ridge at row 20 over columns 10..29."""
    g = torch.Generator().manual_seed(seed)
    x = 0.1 + 0.2 * torch.rand(b, c, v, t, generator=g)
    x[..., 7] = 0.05
    x[:, :, 20, 10:30] = 1.0
    return x


@pytest.mark.parametrize("k", [3, -5])
def test_shift_moves_content_by_k_columns_and_fills_with_the_noise_floor(k):
    x = _image()
    out = resample(x, float(k), 1.0, 1.0)
    floor = noise_floor_columns(x)
    assert torch.equal(floor, x[..., 7:8])
    if k > 0:
        torch.testing.assert_close(out[..., k:], x[..., :-k], atol=1e-5, rtol=0)
        entering = out[..., :k]
    else:
        torch.testing.assert_close(out[..., :k], x[..., -k:], atol=1e-5, rtol=0)
        entering = out[..., k:]
    torch.testing.assert_close(entering, floor.expand_as(entering), atol=1e-5, rtol=0)


def test_shift_seconds_to_columns_follows_the_time_mode():
    aug = AugmentConfig(on=True, shift_s=1.5, nominal_width_s=6.0)
    # window: a column is window_s / n_time = 6 / 64 s
    assert aug.max_shift_columns(PreprocessConfig(time_mode="window", window_s=6.0)) == pytest.approx(16.0)
    assert aug.max_shift_columns(PreprocessConfig(time_mode="window", window_s=3.0)) == pytest.approx(32.0)
    # active / resample: a fraction shift_s / nominal_width_s of the width
    assert aug.max_shift_columns(PreprocessConfig(time_mode="active", n_time=32)) == pytest.approx(8.0)


@pytest.mark.parametrize("s", [0.8, 1.25])
def test_velocity_scale_moves_a_ridge_from_offset_r_to_s_r(s):
    v, t = 64, 8
    x = torch.zeros(1, 2, v, t)
    row = 44
    x[:, :, row, :] = 1.0
    r = row - (v - 1) / 2  # 12.5 rows above the centre (0 m/s lies between rows 31 and 32)
    out = resample(x, 0.0, 1.0, s)
    rows = torch.arange(v, dtype=torch.float32)[:, None]
    col = out[0, 1]
    centroid = float((col * rows).sum(0).mean() / col.sum(0).mean()) - (v - 1) / 2
    assert centroid == pytest.approx(s * r, abs=0.25)
    assert torch.equal(out[0, 0], out[0, 1])  # every link of a sample: the same transform


def test_stretch_about_the_centre_and_fill_beyond_the_velocity_band():
    x = _image(b=1, c=1, v=32, t=40)
    out = resample(x, 0.0, 0.5, 1.0)  # twice as fast: the ridge (cols 10..29) shrinks to ~15..24
    ridge = out[0, 0, 20] > 0.9
    assert ridge[15:25].all() and not ridge[:14].any() and not ridge[26:].any()
    # the outer quarters come from outside the clip: the noise floor column
    torch.testing.assert_close(out[..., :9], x[..., 7:8].expand(-1, -1, -1, 9), atol=1e-5, rtol=0)
    # velocities compressed: the rows beyond the band get the floor column's edge rows
    out = resample(x, 0.0, 1.0, 0.5)
    torch.testing.assert_close(out[0, 0, :7, 7], x[0, 0, 0, 7].expand(7), atol=1e-5, rtol=0)


def test_identity_when_disabled_and_config_checks():
    x = _image()
    g = torch.Generator().manual_seed(0)
    pre = PreprocessConfig(n_velocity=32, n_time=40)
    assert not AugmentConfig().enabled  # off by default
    assert augment_batch(x, AugmentConfig(), g, pre) is x
    assert not AugmentConfig(on=True, **NO_GEO, **NO_DB).enabled and not AugmentConfig(on=True, p=0).enabled
    assert AugmentConfig(on=True).enabled
    state = g.get_state()
    assert augment_batch(x, AugmentConfig(on=True, p=0.0), g, pre) is x
    assert torch.equal(g.get_state(), state)  # nothing drawn when off
    # p = 1 with identity transforms except a zero-range one: unchanged values
    same = augment_batch(x, AugmentConfig(on=True, p=1.0, shift_s=0.0, stretch=(1, 1), vscale=(1, 1),
                                          db_floor=0.0, db_offset=1e-9, noise_db=None), g, pre)
    torch.testing.assert_close(same, x, atol=1e-6, rtol=0)
    for bad in (dict(stretch=(1.2, 0.9)), dict(vscale=(0.1, 1.0)), dict(p=1.5), dict(shift_s=-1), dict(foo=1)):
        with pytest.raises(ValueError):
            AugmentConfig(**bad)
    with pytest.raises(ValueError, match="db_floor"):
        augment_batch(x, AugmentConfig(on=True, db_floor=50.0), g, pre)


@pytest.mark.parametrize("scale", ["db", "linear"])
def test_deterministic_for_a_seed_and_values_stay_in_range(scale):
    x = torch.rand(16, 2, 32, 32, generator=torch.Generator().manual_seed(3))
    pre = PreprocessConfig(n_velocity=32, n_time=32, scale=scale)
    cfg = AugmentConfig(on=True, p=1.0, shift_s=2.0, db_floor=10.0, db_offset=6.0)
    a = augment_batch(x, cfg, torch.Generator().manual_seed(7), pre)
    b = augment_batch(x, cfg, torch.Generator().manual_seed(7), pre)
    c = augment_batch(x, cfg, torch.Generator().manual_seed(8), pre)
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert a.shape == x.shape and a.dtype == x.dtype
    assert torch.isfinite(a).all() and a.min() >= 0 and a.max() <= 1
    assert not torch.equal(a, x)


def test_db_jitter_is_a_gain_and_offset_of_the_db_scale():
    x = torch.linspace(0, 1, 41).reshape(1, 1, 1, 41).repeat(4, 1, 8, 1)
    pre = PreprocessConfig(n_velocity=8, n_time=41, floor_db=40.0)
    out = augment_batch(x, AugmentConfig(on=True, p=1.0, **NO_GEO, db_floor=5.0, db_offset=0.0, noise_db=None),
                        torch.Generator().manual_seed(1), pre)
    gains = []
    for i in range(4):  # value' = 1 - (1 - value) g, g = 40 / (40 + d), d in +-5 dB; then clipped to [0, 1]
        top = (1 - out[i, 0, 0, -6:-1]) / (1 - x[i, 0, 0, -6:-1])  # the top 5 dB: never clipped
        assert float(top.max() - top.min()) < 1e-4  # one gain per sample
        g = float(top.mean())
        assert 40 / 45 - 1e-5 <= g <= 40 / 35 + 1e-5
        torch.testing.assert_close(out[i], (1 - (1 - x[i]) * g).clamp(0, 1), atol=1e-5, rtol=0)
        gains.append(g)
    assert len(set(round(g, 4) for g in gains)) == 4  # drawn per sample
    assert out[:, :, :, -1].eq(1).all()  # the peak stays the peak without an offset


def _synthetic_dataset(root, n_per_class=6, t=80):
    """A dataset folder of 5 x n_per_class single-link items: class k a ridge at +0.8 k m/s, random onset."""
    from processing.io.dataset_store import write_shard

    rng = np.random.default_rng(0)
    v = np.linspace(-6.2, 6.2, 64, endpoint=False)
    time = np.arange(t) * 0.016
    recs = []
    for k, act in enumerate(ACTIVITIES):
        for j in range(n_per_class):
            p = rng.random((64, t)) * 1e-3
            on = rng.integers(5, 35)
            p[np.argmin(np.abs(v - 0.8 * (k + 1))), on:on + 40] = 1.0
            p[32] += 0.05
            link = {"p_vt": p.astype(np.float32), "velocity": v.astype(np.float32),
                    "time": time.astype(np.float32), "valid": np.ones(t, bool),
                    "power": (1.0 + 9.0 * (np.arange(t) >= on)).astype(np.float32)}
            recs.append({"entry": {"item_id": f"{act}_{j:02d}", "activity": act, "label": k, "group": f"{act}_{j}"},
                         "links": {"radar1": link}})
    (root / "shards").mkdir(parents=True)
    write_shard(root / "shards" / "s0.h5", recs)
    return root


def test_cli_train_with_augment_records_settings_and_loads(tmp_path):
    ds = _synthetic_dataset(tmp_path / "ds")
    model = tmp_path / "m.pt"
    args = ["--links", "radar1", "--size", "16", "16", "--padding", "same", "--epochs", "2", "--no-group-split",
            "--threads", "1", "--quiet", "--time-mode", "window", "--window-s", "2"]
    assert main(["train", "--data", str(ds), "--out", str(model), *args, "--augment", "--aug-shift-s", "0.4",
                 "--aug-stretch", "0.9", "1.1", "--aug-db", "3", "--time-pool", "max"]) == 0
    clf = load_checkpoint(model)
    tc = TrainConfig(**clf.meta["train_config"])  # the stored train_config validates back
    assert tc.augment == AugmentConfig(on=True, shift_s=0.4, stretch=(0.9, 1.1), db_floor=3.0)
    assert clf.model.cfg.time_pool == "max"
    # checkpoints written before augmentation existed: train_config without it means off
    old = {k: v for k, v in clf.meta["train_config"].items() if k != "augment"}
    assert not TrainConfig(**old).augment.enabled
    # any --aug-* implies --augment; a bad value is a one-line user error
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "n.pt"), *args, "--aug-vscale", "1", "1"]) == 0
    assert TrainConfig(**load_checkpoint(tmp_path / "n.pt").meta["train_config"]).augment.on
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "b.pt"), *args, "--aug-stretch", "2", "1"]) == 2
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "b.pt"), *args, "--aug-db", "40"]) == 2
    assert not (tmp_path / "b.pt").exists()
    # without --augment: off, as before
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "o.pt"), *args]) == 0
    assert TrainConfig(**load_checkpoint(tmp_path / "o.pt").meta["train_config"]).augment == AugmentConfig()


def test_cli_train_intensity_power_and_augment_noise_off(tmp_path):
    ds = _synthetic_dataset(tmp_path / "ds")
    args = ["--links", "radar1", "--size", "16", "16", "--padding", "same", "--epochs", "1", "--no-group-split",
            "--threads", "1", "--quiet", "--time-mode", "window", "--window-s", "1"]
    model = tmp_path / "p.pt"
    assert main(["train", "--data", str(ds), "--out", str(model), *args, "--intensity", "power",
                 "--aug-noise-db", "off"]) == 0
    clf = load_checkpoint(model)
    assert clf.preprocess.intensity == "power"  # stored, so evaluation shows real images the same way
    tc = TrainConfig(**clf.meta["train_config"])
    assert tc.augment.on and tc.augment.noise_db is None
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "n.pt"), *args,
                 "--aug-noise-db", "-30", "-25"]) == 0
    assert TrainConfig(**load_checkpoint(tmp_path / "n.pt").meta["train_config"]).augment.noise_db == (-30, -25)
    for bad in (["-30"], ["loud", "x"], ["-10", "-30"]):  # one number, not numbers, lo > hi: one-line errors
        assert main(["train", "--data", str(ds), "--out", str(tmp_path / "b.pt"), *args, "--aug-noise-db", *bad]) == 2
    assert not (tmp_path / "b.pt").exists()


def test_cli_augment_scale_keeps_only_the_stretch_and_velocity_scale(tmp_path):
    ds = _synthetic_dataset(tmp_path / "ds")
    args = ["--links", "radar1", "--size", "16", "16", "--padding", "same", "--epochs", "1", "--no-group-split",
            "--threads", "1", "--quiet", "--time-mode", "window", "--window-s", "1", "--intensity", "power"]
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "s.pt"), *args, "--augment", "scale"]) == 0
    aug = TrainConfig(**load_checkpoint(tmp_path / "s.pt").meta["train_config"]).augment
    assert aug == AugmentConfig(on=True, shift_s=0.0, db_floor=0.0, db_offset=0.0, noise_db=None)
    assert aug.enabled and aug.stretch == AugmentConfig().stretch and aug.vscale == AugmentConfig().vscale
    # an --aug-* option overrides the set's value; a bare --augment is still every transform
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "t.pt"), *args, "--augment", "scale",
                 "--aug-vscale", "0.9", "1.1"]) == 0
    aug = TrainConfig(**load_checkpoint(tmp_path / "t.pt").meta["train_config"]).augment
    assert aug.vscale == (0.9, 1.1) and aug.shift_s == 0 and aug.noise_db is None
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "a.pt"), *args, "--augment"]) == 0
    assert TrainConfig(**load_checkpoint(tmp_path / "a.pt").meta["train_config"]).augment == AugmentConfig(on=True)
    assert main(["train", "--data", str(ds), "--out", str(tmp_path / "b.pt"), *args, "--augment", "geometry"]) == 2
    assert not (tmp_path / "b.pt").exists()


def test_training_augments_training_batches_only_and_is_deterministic(monkeypatch):
    import importlib

    tr = importlib.import_module("processing.classifier.training")
    rng = np.random.default_rng(0)
    x = rng.random((30, 1, 16, 16), dtype=np.float32)
    y = np.repeat(np.arange(5), 6)
    mcfg = ModelConfig(n_branches=1, input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8)
    aug = AugmentConfig(on=True, p=1.0)
    cfg = TrainConfig(epochs=2, patience=5, batch_size=8, group_split=False, seed=2, threads=1, augment=aug)
    seen = []
    real = tr.augment_batch
    monkeypatch.setattr(tr, "augment_batch", lambda xb, *a: seen.append(xb.shape[0]) or real(xb, *a))
    pre = PreprocessConfig(n_velocity=16, n_time=16)
    a = train(x, y, mcfg, cfg, progress=False, log=None, preprocess=pre)
    assert sum(seen) == 2 * a.train_idx.size  # every training sample, each epoch; never the validation ones
    b = train(x, y, mcfg, cfg, progress=False, log=None, preprocess=pre)
    assert a.history["train_loss"] == b.history["train_loss"]
    off = train(x, y, mcfg, TrainConfig(**{**cfg.model_dump(), "augment": AugmentConfig()}), progress=False, log=None)
    assert off.history["train_loss"] != a.history["train_loss"]
    assert sum(seen) == 4 * a.train_idx.size  # not called when off


@pytest.mark.parametrize("pool", ["max", "mean"])
def test_time_pool_forward_and_old_checkpoints_load(tmp_path, pool):
    cfg = ModelConfig(n_branches=2, input_size=(16, 24), padding="same", channels=(4, 6), mlp_hidden=8,
                      time_pool=pool)
    m = build_model(cfg)
    assert m.n_features == 2 * 6 * 4  # channels x velocity rows (16 / 2 / 2); time pooled away
    assert m(torch.rand(3, 2, 16, 24)).shape == (3, 5)
    assert cfg.n_parameters() == sum(p.numel() for p in m.parameters())
    # a checkpoint written before the field existed loads as 'none' with identical outputs
    torch.manual_seed(0)
    base = ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8)
    clf = Classifier(model=build_model(base), preprocess=PreprocessConfig(n_velocity=16, n_time=16),
                     classes=list(ACTIVITIES), links=["radar1", "radar2"])
    path = save_checkpoint(tmp_path / "m.pt", clf)
    blob = torch.load(path, weights_only=True)
    assert blob["model_config"].pop("time_pool") == "none"
    torch.save(blob, tmp_path / "old.pt")
    again = load_checkpoint(tmp_path / "old.pt")
    assert again.model.cfg.time_pool == "none" and again.model.cfg == base
    x = np.random.default_rng(1).random((4, 2, 16, 16), dtype=np.float32)
    np.testing.assert_array_equal(again.predict_proba(x), clf.predict_proba(x))


def test_receiver_noise_sits_at_the_drawn_level_with_exponential_speckle():
    """One peak pixel on an empty (floor) image, noise at -20 dB re the peak added in linear power: the
    background's mean power is 0.01 of the peak (+-5 %: 4096 exponential samples have a 1.6 % standard error)
    and its median ln(2) = 0.69 of that (an exponential's median); samples not drawn stay untouched."""
    from processing.classifier.augment import add_noise

    pre = PreprocessConfig()
    x = torch.zeros(2, 1, 64, 64)
    x[:, 0, 32, 32] = 1.0
    speckle = -torch.log1p(-torch.rand(x.shape, generator=torch.Generator().manual_seed(1)))
    out = add_noise(x, torch.tensor([True, False]), torch.tensor([-20.0, -20.0]), speckle, pre)
    power = 10 ** ((out[0, 0] - 1) * pre.floor_db / 10)
    background = power.flatten()[torch.arange(64 * 64) != 32 * 64 + 32]
    peak = 1 + 0.01 * float(speckle[0, 0, 32, 32])  # the renormalisation divides by the noisy peak
    assert float(background.mean()) * peak == pytest.approx(0.01, rel=0.05)
    assert float(background.median()) * peak == pytest.approx(0.01 * np.log(2), rel=0.1)
    assert torch.equal(out[1], x[1]) and torch.isfinite(out).all()
