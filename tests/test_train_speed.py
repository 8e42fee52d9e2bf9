"""Training throughput changes keep the numbers: the pool before the ReLU is exact, channels-last training draws
the same dropout masks and differs from the contiguous layout by float rounding only, the NaN fill of deterministic
mode is not needed for the same weights, and the cached inputs are the preprocessed ones (speed itself is measured
by benchmarks/bench_train_speed.py, never here)."""
import numpy as np
import pytest
import torch
from torch import nn

from processing.classifier import ModelConfig, PreprocessConfig, TrainConfig, train
from processing.classifier.model import Dropout, build_model


def _seed_order_fen(fen):
    """The same layers as `fen` in the seed's order conv -> BN -> ReLU -> pool -> dropout (shared modules)."""
    mods = list(fen.net)
    for i in range(len(mods) - 1):
        if isinstance(mods[i], nn.MaxPool2d) and isinstance(mods[i + 1], nn.ReLU):
            mods[i], mods[i + 1] = mods[i + 1], mods[i]
    return nn.Sequential(*mods)


def test_pool_before_relu_gives_the_seed_orders_outputs_and_gradients_bit_for_bit():
    """max(relu(a), relu(b)) = relu(max(a, b)) for a monotone ReLU: same forward values and, since the maximum's
    position is the same, the same gradients, exactly (no tolerance)."""
    torch.manual_seed(0)
    net = build_model(ModelConfig(n_branches=1, input_size=(32, 32), padding="same"))
    fen = net.fens[0]
    ref = _seed_order_fen(fen)
    assert [type(m) for m in ref][:5] == [nn.Conv2d, nn.BatchNorm2d, nn.ReLU, nn.MaxPool2d, Dropout]
    x = torch.randn(8, 1, 32, 32)
    fen.train()
    outs, grads = [], []
    for f in (fen.net, ref):
        torch.manual_seed(5)  # the same dropout masks
        out = f(x)
        out.square().sum().backward()
        outs.append(out.detach().clone())
        grads.append([p.grad.clone() for p in fen.parameters()])
        fen.zero_grad()
    assert torch.equal(outs[0], outs[1])
    assert all(torch.equal(a, b) for a, b in zip(*grads))


def test_channels_last_dropout_drops_what_contiguous_dropout_drops():
    """torch draws a channels-last tensor's mask in memory order (other elements for the same seed); `Dropout`
    draws it in logical order, so the result equals nn.Dropout on the contiguous tensor exactly."""
    x = torch.rand(4, 6, 5, 5) + 0.5
    torch.manual_seed(3)
    want = nn.Dropout(0.3).train()(x)
    torch.manual_seed(3)
    got = Dropout(0.3).train()(x.contiguous(memory_format=torch.channels_last))
    assert torch.equal(got, want)
    torch.manual_seed(3)
    plain = nn.Dropout(0.3).train()(x.contiguous(memory_format=torch.channels_last))
    assert not torch.equal(plain, want)  # what the layer is for: torch's own mask differs


def test_channels_last_training_step_equals_contiguous_up_to_rounding():
    """One forward/backward in each layout from the same weights and masks: the loss agrees to float32 rounding of
    sums over ~10^4 terms in another order (|error| <~ sqrt(n) * 6e-8 ~ 1e-5 relative; 1e-4 allows for the
    convolution algorithms' blocking), and so does every gradient relative to its largest element, with an
    absolute floor of 1e-5 for the convolution biases in front of BatchNorm, whose exact gradient is 0 (BatchNorm
    removes the mean) and whose computed one is rounding noise of ~1e-7."""
    torch.manual_seed(1)
    net = build_model(ModelConfig(n_branches=1))
    x, y = torch.rand(16, 1, 64, 64), torch.randint(0, 5, (16,))
    results = []
    for fmt in (torch.contiguous_format, torch.channels_last):
        net.to(memory_format=fmt).train()
        net.zero_grad()
        torch.manual_seed(7)
        loss = nn.functional.cross_entropy(net(x.contiguous(memory_format=fmt)), y)
        loss.backward()
        results.append((float(loss.detach()), [p.grad.clone().contiguous() for p in net.parameters()]))
    (l0, g0), (l1, g1) = results
    assert abs(l1 - l0) <= 1e-4 * abs(l0)
    for a, b in zip(g0, g1):
        assert float((a - b).abs().max()) <= 1e-3 * float(a.abs().max()) + 1e-5


def _tiny_xy(n=48, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.random((n, 1, 32, 32)).astype(np.float32)
    y = np.arange(n) % 5
    x[np.arange(n)[:, None], 0, (y * 6)[:, None] + np.arange(4), :] += 1.0  # a class-dependent velocity band
    return np.clip(x / 2, 0, 1).astype(np.float32), y


def test_trained_weights_do_not_need_the_nan_fill_of_deterministic_mode(monkeypatch):
    """`setup_torch` turns off torch's filling of new tensors with NaN; if any kernel read such memory the weights
    would differ (or be NaN): a training with the fill on gives the same weights bit for bit."""
    from processing.classifier import training

    x, y = _tiny_xy()
    cfg = TrainConfig(epochs=2, batch_size=8, group_split=False, seed=4, threads=1)
    mcfg = ModelConfig(input_size=(32, 32), padding="same", n_branches=1)
    fast = train(x, y, mcfg, cfg, progress=False, log=None).model.state_dict()
    original = training.setup_torch

    def with_fill(seed, threads=None):
        original(seed, threads)
        torch.utils.deterministic.fill_uninitialized_memory = True

    monkeypatch.setattr(training, "setup_torch", with_fill)
    filled = train(x, y, mcfg, cfg, progress=False, log=None).model.state_dict()
    assert all(torch.equal(fast[k], filled[k]) for k in fast)
    assert torch.utils.deterministic.fill_uninitialized_memory  # the patched run did fill
    torch.utils.deterministic.fill_uninitialized_memory = False


def test_contiguous_layout_is_still_reachable_and_returns_a_contiguous_model():
    """memory_format='contiguous' is the layout of trainings before the option existed; either way the returned
    network is in the usual layout (checkpoints, callers) and the two differ only by rounding (same labels here)."""
    x, y = _tiny_xy()
    mcfg = ModelConfig(input_size=(32, 32), padding="same", n_branches=1)
    nets = {}
    for fmt in ("contiguous", "channels_last"):
        cfg = TrainConfig(epochs=3, batch_size=8, group_split=False, seed=2, threads=1, memory_format=fmt)
        nets[fmt] = train(x, y, mcfg, cfg, progress=False, log=None).model
        assert all(p.is_contiguous() for p in nets[fmt].parameters())
    with torch.inference_mode():
        preds = [nets[f](torch.as_tensor(x)).argmax(1) for f in nets]
    assert (preds[0] == preds[1]).float().mean() >= 0.9  # rounding may flip a borderline sample, not the model


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("RTCHANNEL_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "arrays"


def test_cached_inputs_are_the_preprocessed_ones_and_train_the_same_weights(tiny_dataset, cache_dir, monkeypatch):
    from processing.classifier.experiment import load_dataset, train_classifier
    from processing.io.dataset_reader import DatasetReader

    pre = PreprocessConfig(n_velocity=32, n_time=32)
    spec = f"{tiny_dataset}:direction=1|7"
    fresh = load_dataset(spec, ["radar1"], pre, cache=False)
    assert not cache_dir.exists()  # cache=False neither reads nor writes
    cold = load_dataset(spec, ["radar1"], pre)
    assert len(list(cache_dir.glob("*.npy"))) == 1

    def no_reads(*a, **k):
        raise AssertionError("a cached load must not read the shards")

    monkeypatch.setattr(DatasetReader, "load", no_reads)
    warm = load_dataset(spec, ["radar1"], pre)
    for ds in (cold, warm):
        assert ds.x.dtype == np.float32 and np.array_equal(ds.x, fresh.x)
        assert np.array_equal(ds.y, fresh.y) and ds.groups == fresh.groups and ds.names == fresh.names
    cfg = TrainConfig(epochs=1, batch_size=8, group_split=False, seed=1, threads=1)
    mcfg = ModelConfig(input_size=(32, 32), padding="same", n_branches=1)
    a, b = (train_classifier(ds, links=["radar1"], preprocess=pre, model=mcfg, train_config=cfg).classifier
            for ds in (fresh, warm))
    assert all(torch.equal(u, v) for u, v in zip(a.model.state_dict().values(), b.model.state_dict().values()))
    # another preprocessing is another entry; a damaged entry is recomputed, not used
    with pytest.raises(AssertionError, match="must not read"):
        load_dataset(spec, ["radar1"], pre.model_copy(update={"floor_db": 30.0}))
    monkeypatch.undo()
    (path,) = cache_dir.glob("*.npy")
    np.save(path, np.zeros((3, 1, 32, 32), np.float32))
    again = load_dataset(spec, ["radar1"], pre)
    assert np.array_equal(again.x, fresh.x)
