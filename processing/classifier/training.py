"""Training, early stopping, checkpoints and prediction for the multiperspective DCNN (CPU only).

Determinism: `seed` drives numpy, torch's initialisation, the split and the batch order (a private
`torch.Generator`), and `torch.use_deterministic_algorithms(True)` is set (free on CPU), so the same data,
settings and seed give the same weights. Threads: `torch.set_num_threads(threads)`, pinned to
`DEFAULT_THREADS` = 1 unless `threads` is given: torch's CPU kernels split their sums by thread, so
1 and 2 threads give weights that differ after the first step (measured: different loss at epoch 1), and
a thread count chosen from the machine's load (`auto_threads`, the old default) made the result
depend on what else was running. An explicit `threads` is recorded in the checkpoint's train_config.

Augmentation (`TrainConfig.augment`, off by default): each *training* batch is transformed by
`processing.classifier.augment.augment_batch` (random time shift, stretch, velocity scale, dB jitter) with
the same private generator as the batch order, so runs stay deterministic; validation batches never are.
The augmentation settings are part of `TrainConfig` and so of the checkpoint's train_config.

Training stops with `TrainingError` (nothing is returned or saved) when the inputs hold non-finite
values or the loss becomes non-finite (a learning rate far too high, or broken data).

Checkpoints: `processing.classifier.checkpoint` (re-exported here).
"""
from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import torch
import torch.utils.deterministic
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from processing.classifier.augment import AugmentConfig, augment_batch
from processing.classifier.checkpoint import CHECKPOINT_VERSION, load_checkpoint, save_checkpoint
from processing.classifier.model import ModelConfig, MultiPerspectiveDCNN, build_model
from processing.classifier.preprocess import PreprocessConfig, preprocess_links
from processing.classifier.splits import holdout_split as _holdout_split
from processing.classifier.splits import split_indices  # noqa: F401 - re-exported (its old home)
from processing.errors import TrainingError, one_line

DEFAULT_THREADS = 1  # pinned: results must not depend on the machine's load (see the module docstring)


class TrainConfig(BaseModel):
    """Optimisation settings (Adam, cross-entropy, early stopping on validation loss)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    epochs: int = Field(40, ge=1, le=100_000, description="maximum epochs")
    batch_size: int = Field(32, ge=1, le=65536)
    lr: float = Field(1e-3, gt=0, le=1.0, description="Adam learning rate (Adam steps are ~lr per weight: "
                      "above 1 it only diverges)")
    weight_decay: float = Field(0.0, ge=0, le=1.0)
    patience: int = Field(6, ge=1, le=100_000, description="epochs without validation-loss improvement before stopping")
    min_delta: float = Field(1e-4, ge=0, le=10.0, description="improvement that resets the patience counter")
    val_fraction: float = Field(0.2, gt=0, lt=1, description="validation share (seed: 80:20)")
    group_split: bool = Field(True, description="keep all copies of one motion source on one side")
    val_split: Literal["groups", "deployment"] = Field(
        "groups", description="groups: validate on held-out motion sources (val_fraction of them); deployment: "
        "also on held-out tails of deployment factors, none of which reach training (`splits`)")
    holdout_factors: int = Field(2, ge=0, le=10, description="val_split deployment: factors with a held-out tail")
    holdout_tail: float = Field(0.125, gt=0, lt=0.5, description="val_split deployment: share of items in each "
                                "held-out tail")
    average: Literal["none", "window"] = Field(
        "none", description="window: the returned weights are the mean of the epochs around the best one whose "
        "validation loss stays within average_tolerance of the best (weight averaging in the flat region of the "
        "loss, as SWAD, Cha et al., NeurIPS 2021), with BatchNorm statistics re-estimated on the training data")
    average_tolerance: float = Field(0.2, gt=0, le=10.0, description="average window: relative excess of the "
                                     "validation loss over its minimum that an averaged epoch may have")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="random seed (scikit-learn's split takes 32 bits)")
    threads: int | None = Field(None, ge=1, le=256, description="torch CPU threads; None: DEFAULT_THREADS (1)")
    # channels-last runs the convolutions, pooling and BatchNorm of this network 1.5-2x faster on CPU (measured,
    # benchmarks/bench_train_speed.py); the weights then differ from 'contiguous' by float rounding only (the
    # dropout masks are drawn in the same order, `model.Dropout`), which Adam's first steps amplify
    memory_format: Literal["channels_last", "contiguous"] = Field(
        "channels_last", description="memory layout of the activations while training ('contiguous': the layout "
        "of trainings before it existed, which reproduces their weights)")
    epoch_samples: int | None = Field(None, ge=1, le=10_000_000, description="items drawn per epoch when the "
                                      "datasets are weighted (`train`'s source_weights); None: the training set's size")
    feature_lr_scale: float = Field(1.0, ge=0, le=1, description="learning rate of the feature-extraction networks "
                                    "(the convolutions and their BatchNorm) relative to lr: 1 one rate for all, < 1 "
                                    "a lower one (discriminative fine-tuning), 0 frozen (only the MLP head learns)")
    # absent from checkpoints written before it existed: those trained without augmentation, the default
    augment: AugmentConfig = Field(AugmentConfig(), description="random transforms of training batches (default off)")


def auto_threads() -> int:
    """2 threads on an idle machine, 1 when other work already loads the cores.

    Measured on the 2-core reference machine under a load average of ~8: one thread ran an epoch 10x
    faster than two (OpenMP threads spin-waiting for a core they never get); idle, two are ~1.6x faster.
    """
    import os

    cores = os.cpu_count() or 1
    return 1 if cores < 2 or os.getloadavg()[0] > 0.5 * cores else 2


def setup_torch(seed: int, threads: int | None = None) -> None:
    """Seed numpy/torch, set CPU threads (None: `DEFAULT_THREADS`) and ask for deterministic kernels."""
    torch.set_num_threads(threads or DEFAULT_THREADS)
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    torch.use_deterministic_algorithms(True)
    # deterministic mode also fills every new tensor's memory with NaN (a debugging aid against reading
    # uninitialised memory); no kernel here reads it, so the weights are the same bit for bit without it, and
    # the fills took a third of an epoch's CPU time (measured, torch.profiler: aten::fill_)
    torch.utils.deterministic.fill_uninitialized_memory = False  # type: ignore[attr-defined]  # not in torch's stubs


def dataset_arrays(reader, indices, links, pre: PreprocessConfig, progress: bool = False):
    """(X [N, n_links, V, T] float32, labels [N], groups [N]) from a `DatasetReader`'s entries."""
    from tqdm import tqdm

    indices = list(indices)
    x = np.zeros((len(indices), len(links), pre.n_velocity, pre.n_time), np.float32)
    y = np.zeros(len(indices), np.int64)
    groups = []
    for k, i in enumerate(tqdm(indices, desc="loading", unit="sample", disable=not progress, leave=False)):
        e = reader.entries[i]
        x[k] = preprocess_links(reader.load(i, links=list(links)), links, pre)
        y[k] = int(e["label"])
        groups.append(str(e.get("group", e.get("item_id", i))))
    return x, y, groups


@dataclass
class TrainResult:
    """A trained network plus what produced it."""

    model: nn.Module
    history: dict
    train_idx: np.ndarray
    val_idx: np.ndarray
    best_epoch: int
    seconds: float
    extra: dict = field(default_factory=dict)


def _evaluate(model, x, y, batch_size, loss_fn):
    model.eval()
    total, correct, n = 0.0, 0, 0
    with torch.inference_mode():
        for s in range(0, x.shape[0], batch_size):
            xb, yb = x[s:s + batch_size], y[s:s + batch_size]
            out = model(xb)
            total += float(loss_fn(out, yb).detach()) * xb.shape[0]
            correct += int((out.argmax(1) == yb).sum())
            n += xb.shape[0]
    return total / max(n, 1), correct / max(n, 1)


def train(x: np.ndarray, y: np.ndarray, model_cfg: ModelConfig, cfg: TrainConfig = TrainConfig(), groups=None,
          split: tuple[np.ndarray, np.ndarray] | None = None, progress: bool = True, log=print,
          preprocess: PreprocessConfig | None = None, deployments: dict | None = None,
          init_state: dict | None = None, sources=None, source_weights=None) -> TrainResult:
    """Train on X [N, n_branches, V, T] / labels y [N] with an 80:20 stratified (grouped) split.

    `split` overrides the split with explicit (train, validation) indices. With ``cfg.val_split ==
    "deployment"`` the split holds out motion sources and deployment regions (`splits.holdout_split`) and
    `deployments` must give the factors [N] per name (`splits.deployment_factors`); the description of what
    was held out is returned in ``TrainResult.extra["holdout"]``. `preprocess` is the configuration
    that made X; augmentation (`cfg.augment`) needs it to convert its time shift to columns and for the dB
    floor (None: the default `PreprocessConfig` at X's size). `init_state`: a state dict of the same network to
    start from instead of the seeded random initialisation (fine-tuning). The returned model carries
    the weights of the epoch with the lowest validation loss (early stopping after `patience` epochs
    without improvement). History: per-epoch train/val loss and accuracy, and seconds per epoch.

    Weighted datasets: with `source_weights` (one weight >= 0 per source) and `sources` (the source index of each
    item [N]), every epoch draws ``cfg.epoch_samples`` (default: the training set's size) training items with
    replacement, source k with probability weight_k / sum(weights) and uniformly within it, so a batch mixes the
    sources in those shares whatever their sizes (mixed batches: e.g. a few real recordings beside thousands of
    simulated ones). Without weights every epoch is one pass over the training items in a seeded order.
    """
    from tqdm import tqdm

    x = np.asarray(x)
    y = np.asarray(y)
    want = (model_cfg.n_branches, *model_cfg.input_size)
    if x.ndim != 4 or x.shape[1:] != want or y.shape != (x.shape[0],):
        raise TrainingError(f"training inputs must be X [N, {', '.join(map(str, want))}] with labels [N]; got X "
                            f"{list(x.shape)}, labels {list(y.shape)}")
    if x.shape[0] < 2:
        raise TrainingError(f"training needs at least 2 samples, got {x.shape[0]}")
    if not np.isfinite(x).all():
        raise TrainingError("training inputs hold non-finite values")
    if y.size and (y.min() < 0 or y.max() >= model_cfg.n_classes):
        raise TrainingError(f"labels must lie in 0..{model_cfg.n_classes - 1}, got {y.min()}..{y.max()}")
    if preprocess is None:
        preprocess = PreprocessConfig(n_velocity=model_cfg.input_size[0], n_time=model_cfg.input_size[1])
    if cfg.augment.enabled and cfg.augment.db_floor >= preprocess.floor_db:
        raise TrainingError(f"augment db_floor ({cfg.augment.db_floor:g} dB) must be less than the preprocessing's "
                            f"floor_db ({preprocess.floor_db:g} dB)")
    setup_torch(cfg.seed, cfg.threads)
    t_start = time.perf_counter()
    extra = {}
    try:
        if split is not None:
            tr, va = split
        elif cfg.val_split == "deployment":
            if deployments is None or groups is None:
                raise TrainingError("val_split 'deployment' needs the items' groups and deployment factors")
            tr, va, extra["holdout"] = _holdout_split(y, groups, deployments, cfg.seed, cfg.val_fraction,
                                                     cfg.holdout_factors, cfg.holdout_tail)
        else:
            tr, va = split_indices(y, groups if cfg.group_split else None, cfg.val_fraction, cfg.seed)
    except ValueError as e:  # too few samples or groups for the requested split
        raise TrainingError(f"cannot split the data: {one_line(e)}") from None
    fmt = torch.channels_last if cfg.memory_format == "channels_last" else torch.contiguous_format
    xt, yt = torch.from_numpy(np.ascontiguousarray(x[tr])), torch.from_numpy(np.asarray(y)[tr])
    xv = torch.from_numpy(np.ascontiguousarray(x[va])).contiguous(memory_format=fmt)
    yv = torch.from_numpy(np.asarray(y)[va])
    model = build_model(model_cfg)
    if init_state is not None:
        model.load_state_dict(init_state)
    model.to(memory_format=fmt)  # type: ignore[call-overload]  # torch's stubs lack the keyword
    opt = _optimizer(model, cfg)
    draw = _source_probabilities(sources, source_weights, tr) if source_weights is not None else None
    loss_fn = nn.CrossEntropyLoss()
    gen = torch.Generator().manual_seed(cfg.seed)
    hist: dict[str, list[float]] = {k: [] for k in ("train_loss", "train_acc", "val_loss", "val_acc", "seconds")}
    best, best_state, best_epoch, waited = np.inf, copy.deepcopy(model.state_dict()), 0, 0
    states = []  # every epoch's weights, for cfg.average (the network is small: ~1 MB each)
    bar = tqdm(range(1, cfg.epochs + 1), desc="training", unit="epoch", disable=not progress)
    for epoch in bar:
        t0 = time.perf_counter()
        model.train()
        if draw is None:
            order = torch.randperm(xt.shape[0], generator=gen)
        else:
            order = torch.multinomial(draw, cfg.epoch_samples or xt.shape[0], replacement=True, generator=gen)
        run_loss, run_ok = 0.0, 0
        for s in range(0, order.numel(), cfg.batch_size):
            b = order[s:s + cfg.batch_size]
            opt.zero_grad()
            xb = augment_batch(xt[b], cfg.augment, gen, preprocess) if cfg.augment.enabled else xt[b]
            out = model(xb.contiguous(memory_format=fmt))
            loss = loss_fn(out, yt[b])
            if not torch.isfinite(loss.detach()):
                raise TrainingError(f"training diverged: the loss became {float(loss.detach())} at epoch {epoch} "
                                    f"(learning rate {cfg.lr:g}); lower --lr. Nothing was saved")
            loss.backward()
            opt.step()
            run_loss += float(loss.detach()) * b.numel()
            run_ok += int((out.argmax(1) == yt[b]).sum())
        vl, vacc = _evaluate(model, xv, yv, 256, loss_fn) if xv.shape[0] else (float("nan"), float("nan"))
        if xv.shape[0] and not np.isfinite(vl):
            raise TrainingError(f"training diverged: the validation loss became {vl} at epoch {epoch} "
                                f"(learning rate {cfg.lr:g}); lower --lr. Nothing was saved")
        hist["train_loss"].append(run_loss / order.numel())
        hist["train_acc"].append(run_ok / order.numel())
        hist["val_loss"].append(vl)
        hist["val_acc"].append(vacc)
        hist["seconds"].append(time.perf_counter() - t0)
        bar.set_postfix(loss=f"{hist['train_loss'][-1]:.3f}", val_loss=f"{vl:.3f}", val_acc=f"{vacc:.3f}")
        if cfg.average != "none":
            states.append(copy.deepcopy(model.state_dict()))
        if not xv.shape[0] or vl < best - cfg.min_delta:
            best, best_state, best_epoch, waited = vl, copy.deepcopy(model.state_dict()), epoch, 0
        else:
            waited += 1
            if waited >= cfg.patience:
                if log:
                    log(f"early stop after epoch {epoch}; best epoch {best_epoch} (val loss {best:.4f})")
                break
    model.load_state_dict(best_state)
    if cfg.average == "window" and xv.shape[0]:
        lo, hi = averaging_window(hist["val_loss"], best_epoch, cfg.average_tolerance)
        model.load_state_dict(average_states(states[lo - 1:hi]))
        recompute_batch_norm(model, xt.contiguous(memory_format=fmt), cfg.batch_size)
        vl, vacc = _evaluate(model, xv, yv, 256, loss_fn)
        extra["averaged"] = {"epochs": [lo, hi], "val_loss": vl, "val_acc": vacc,
                             "best_val_loss": float(best), "best_val_acc": float(hist["val_acc"][best_epoch - 1])}
        if log:
            log(f"weights averaged over epochs {lo}-{hi}: val loss {vl:.4f} (best single epoch {best:.4f}), "
                f"val acc {vacc:.3f}")
    # checkpoints and callers get the usual layout (torch's stubs lack the keyword)
    model.to(memory_format=torch.contiguous_format).eval()  # type: ignore[call-overload]
    return TrainResult(model=model, history=hist, train_idx=tr, val_idx=va, best_epoch=best_epoch,
                       seconds=time.perf_counter() - t_start, extra=extra)


def _optimizer(model: MultiPerspectiveDCNN, cfg: TrainConfig) -> torch.optim.Optimizer:
    """Adam over the network, the feature networks at ``cfg.feature_lr_scale`` times the rate (frozen at 0)."""
    if cfg.feature_lr_scale == 1.0:
        return torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    features = list(model.fens.parameters())
    if cfg.feature_lr_scale == 0.0:  # frozen: no gradients through the convolutions at all (cheaper too)
        for q in features:
            q.requires_grad_(False)
        return torch.optim.Adam(model.mlp.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    groups: list[dict[str, Any]] = [{"params": features, "lr": cfg.lr * cfg.feature_lr_scale},
                                    {"params": list(model.mlp.parameters())}]
    return torch.optim.Adam(groups, lr=cfg.lr, weight_decay=cfg.weight_decay)


def _source_probabilities(sources, weights, train_idx) -> torch.Tensor:
    """Drawing probability [N_train] of each training item: its source's weight shared equally by the source's
    training items (sources without training items drop out, the others' shares are renormalised)."""
    src = np.asarray(sources, dtype=np.int64)[train_idx] if sources is not None else None
    w = np.asarray(weights, dtype=np.float64)
    if src is None or w.ndim != 1 or src.size == 0 or src.min() < 0 or src.max() >= w.size:
        raise TrainingError(f"weighted training needs a source index in 0..{w.size - 1} for every item")
    if not (np.isfinite(w).all() and (w >= 0).all()):
        raise TrainingError(f"dataset weights must be finite and >= 0, got {w.tolist()}")
    counts = np.bincount(src, minlength=w.size)
    per_item = np.where(counts[src] > 0, w[src] / np.maximum(counts[src], 1), 0.0)
    if per_item.sum() <= 0:
        raise TrainingError("every training item has weight 0")
    return torch.from_numpy(per_item / per_item.sum())


def averaging_window(val_loss: list[float], best_epoch: int, tolerance: float) -> tuple[int, int]:
    """First and last epoch (1-based, inclusive) of the contiguous run around `best_epoch` whose validation
    loss is at most (1 + `tolerance`) times the loss at `best_epoch`."""
    v = np.asarray(val_loss, float)
    b = best_epoch - 1
    limit = v[b] * (1.0 + tolerance) if v[b] >= 0 else v[b] * (1.0 - tolerance)
    lo = hi = b
    while lo > 0 and v[lo - 1] <= limit:
        lo -= 1
    while hi + 1 < v.size and v[hi + 1] <= limit:
        hi += 1
    return lo + 1, hi + 1


def average_states(states: list[dict]) -> dict:
    """Element-wise mean of state dicts (floating tensors; integer buffers such as BatchNorm's batch count are
    taken from the last state)."""
    out = {}
    for key, last in states[-1].items():
        if last.is_floating_point():
            out[key] = torch.stack([s[key] for s in states]).mean(dim=0)
        else:
            out[key] = last.clone()
    return out


def recompute_batch_norm(model: nn.Module, x: torch.Tensor, batch_size: int) -> None:
    """Re-estimate every BatchNorm layer's running mean and variance on inputs `x` [N, ...] (cumulative average
    over un-augmented batches, as torch.optim.swa_utils.update_bn): averaged weights need their own statistics."""
    bns = [m for m in model.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm)]
    if not bns:
        return
    momenta = [m.momentum for m in bns]
    for m in bns:
        m.reset_running_stats()
        m.momentum = None
    model.train()
    with torch.no_grad():
        for s in range(0, x.shape[0], batch_size):
            model(x[s:s + batch_size])
    for m, mom in zip(bns, momenta):
        m.momentum = mom
    model.eval()


__all__ = ["AugmentConfig", "CHECKPOINT_VERSION", "DEFAULT_THREADS", "TrainConfig", "TrainResult",
           "auto_threads", "average_states", "averaging_window", "dataset_arrays", "recompute_batch_norm",
           "load_checkpoint", "save_checkpoint", "setup_torch",
           "split_indices", "train"]
