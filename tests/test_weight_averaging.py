"""Weight averaging around the best epoch (`TrainConfig.average`) and the BatchNorm re-estimate it needs."""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from processing.classifier import ModelConfig, TrainConfig, train
from processing.classifier.training import average_states, averaging_window, recompute_batch_norm


def test_window_is_the_contiguous_run_within_tolerance_of_the_best():
    loss = [2.0, 1.3, 1.1, 1.0, 1.15, 1.25, 1.05, 1.4]
    # best epoch 4 (1.0); 20 %: epochs 2..7 are <= 1.2 except epoch 6 (1.25) breaks the run after epoch 5
    assert averaging_window(loss, 4, 0.2) == (3, 5)
    assert averaging_window(loss, 4, 0.3) == (2, 7)
    assert averaging_window(loss, 4, 0.01) == (4, 4)
    assert averaging_window([0.5, 0.4], 2, 10.0) == (1, 2)


def test_average_of_states_is_the_elementwise_mean_and_keeps_integer_buffers():
    a = {"w": torch.tensor([1.0, 3.0]), "n": torch.tensor(5)}
    b = {"w": torch.tensor([3.0, 7.0]), "n": torch.tensor(9)}
    m = average_states([a, b])
    assert torch.equal(m["w"], torch.tensor([2.0, 5.0])) and int(m["n"]) == 9


def test_batch_norm_statistics_are_re_estimated_on_the_data():
    # a lone BatchNorm: after the re-estimate its running mean is the data's mean and its running variance the
    # unbiased variance of each batch averaged over equal batches (cumulative average, momentum None)
    torch.manual_seed(0)
    bn = nn.Sequential(nn.BatchNorm1d(3))
    bn[0].running_mean.fill_(100.0)
    x = torch.randn(64, 3) * torch.tensor([1.0, 2.0, 3.0]) + torch.tensor([0.5, -1.0, 4.0])
    recompute_batch_norm(bn, x, batch_size=16)
    np.testing.assert_allclose(bn[0].running_mean.numpy(), x.mean(0).numpy(), atol=1e-6)
    want = torch.stack([x[s:s + 16].var(0, unbiased=True) for s in range(0, 64, 16)]).mean(0)
    np.testing.assert_allclose(bn[0].running_var.numpy(), want.numpy(), rtol=1e-5)
    assert bn[0].momentum == 0.1 and not bn.training


def test_training_with_averaging_returns_the_mean_of_the_window():
    rng = np.random.default_rng(0)
    n = 80
    y = np.arange(n) % 5
    x = rng.random((n, 1, 16, 16)).astype(np.float32) * 0.2
    for i in range(n):  # a class-dependent bright row: learnable in a few epochs
        x[i, 0, 3 * y[i]] += 1.0
    mcfg = ModelConfig(n_classes=5, n_branches=1, input_size=(16, 16), padding="same")
    base = dict(epochs=8, patience=8, batch_size=16, group_split=False, seed=1, threads=1)
    plain = train(x, y, mcfg, TrainConfig(**base), progress=False, log=None)
    avg = train(x, y, mcfg, TrainConfig(**base, average="window", average_tolerance=0.5), progress=False, log=None)
    # same seed, same split and the same epochs: only the returned weights differ
    assert plain.history["val_loss"] == avg.history["val_loss"] and plain.best_epoch == avg.best_epoch
    lo, hi = avg.extra["averaged"]["epochs"]
    assert (lo, hi) == averaging_window(avg.history["val_loss"], avg.best_epoch, 0.5) and lo <= avg.best_epoch <= hi
    w_plain = plain.model.state_dict()
    w_avg = avg.model.state_dict()
    conv = next(k for k in w_avg if k.endswith("weight") and w_avg[k].ndim == 4)
    assert (hi > lo) == (not torch.equal(w_plain[conv], w_avg[conv]))
    assert np.isfinite(avg.extra["averaged"]["val_loss"])
