"""How many real recordings the simulation saves: the transfer study behind `rtchannel transfer`.

A learning curve on real labelled images with subject-grouped cross-validation:

- Folds: the people of the real images are split into `folds` groups (`subject_folds`); each fold's test
  images are those of its people, and nothing of them reaches any training, normalisation, early stopping or
  model selection: every training below sees only the other folds' images, and none validates on real images.
- Shots: k real images per class drawn from the training folds (`shot_indices`; nested, so k = 5 holds the
  images of k = 2), or ``all`` of them.
- Arms, for every shot count, fold and seed:
  ``real``: trained from scratch on the k real images per class;
  ``finetune``: the simulation-pretrained network, then trained on the real images at `finetune_lr`;
  ``mixed``: the simulation-pretrained network, then trained on batches that mix real images
  (`real_share` of each batch) with the simulated ones, so the simulation stays in the training
  (rehearsal: the features keep covering the deployments the simulation draws while the real images
  pull them to the real sensor). At 0 shots all three are the simulation-only network (``sim``).
- Pretraining: one network per seed on the simulated dataset with the README's protocol (validation on
  held-out simulated deployments, `TrainConfig.val_split`), the same for every fold: it never sees a real
  image. Given checkpoints (`pretrained`) replace it.
- Trainings on real images run a fixed number of optimiser steps (`*_steps`, batches drawn with
  replacement), with no validation: early stopping would need held-out real images of the training folds,
  which a site with k recordings per class does not have. The step counts are set beforehand, not on any fold:
  short fixed schedules for the two arms that start from the pretrained network, and for the real-only arm a
  budget proportional to its image count (`real_step_budget`: ~50 draws per image, 60-150 steps), so that
  one image per class does not cost as much as all of them. The floor and the draws per image were read off
  simulated items (`benchmarks/transfer_steps_on_sim.py`: k simulated items per class from scratch, tested on
  other motion sources: 30 steps left 5 per class at 27-61 %, 60 steps reached the 78-86 % of 100-150 steps;
  20 per class gained 2-5 points from 60 to 150 steps), not off real images (docs/results.md says what
  prompted the check).

Every run is one task (`Task`); tasks run in worker processes (one torch thread each: two trainings on a 2-core
machine run twice as fast as one training on two threads, and results stay those of one thread), each
appended to ``runs.jsonl`` when it finishes, so an interrupted study resumes where it stopped. The report
(`processing.classifier.transfer_report`) aggregates the runs.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from processing.classifier.augment import PRESETS, AugmentConfig
from processing.classifier.model import ModelConfig
from processing.classifier.preprocess import PreprocessConfig
from processing.classifier.training import TrainConfig
from processing.errors import InputError

Arm = Literal["real", "finetune", "mixed"]
ARMS: tuple[Arm, ...] = ("real", "finetune", "mixed")
Shot = int | Literal["all"]


def _readme_pretraining() -> TrainConfig:
    """The README's single-radar protocol: scale augmentation, validation on held-out simulated deployments; at
    most 20 epochs (early stopping ended the campaign-1 pretraining at 14 with its best at 8; the cap bounds the
    study's time should the validation loss keep creeping down)."""
    return TrainConfig(val_split="deployment", val_fraction=0.15, epochs=20,
                       augment=AugmentConfig(on=True, **PRESETS["scale"]))


class TransferConfig(BaseModel):
    """Settings of a transfer study (counts, steps, learning rates; units: images per class, optimiser steps)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    shots: tuple[Shot, ...] = Field((0, 1, 2, 5, 10, 20, "all"), min_length=1, description="real images per class "
                                    "in training ('all': every training-fold image)")
    folds: int = Field(4, ge=2, le=50, description="subject-grouped folds (4: five people per test fold in "
                       "campaign 1, and a fifth fewer trainings than 5 folds)")
    seeds: tuple[int, ...] = Field((0,), min_length=1, description="training seeds (pretraining, shots, batches)")
    arms: tuple[Arm, ...] = Field(ARMS, min_length=1)
    batch_size: int = Field(32, ge=1, le=4096)
    real_steps: int = Field(150, ge=1, le=100_000, description="optimiser steps of the real-only arm (from scratch); "
                            "with real_passes, the most it gets")
    real_passes: float | None = Field(50.0, gt=0, le=10_000, description="real-only arm: steps to draw each real "
                                      "image about this many times (`real_step_budget`), between real_min_steps and "
                                      "real_steps; None: always real_steps")
    real_min_steps: int = Field(60, ge=1, le=100_000, description="real-only arm: the fewest steps (a network from "
                                "scratch needs some steps whatever the image count)")
    finetune_steps: int = Field(50, ge=1, le=100_000, description="steps of the fine-tuning arm")
    mixed_steps: int = Field(50, ge=1, le=100_000, description="steps of the mixed arm")
    lr: float = Field(1e-3, gt=0, le=1, description="Adam learning rate from scratch (the pretraining's)")
    finetune_lr: float = Field(1e-4, gt=0, le=1, description="learning rate of the finetune and mixed arms "
                               "(a tenth of the pretraining's: the pretrained weights are a starting point to keep)")
    feature_lr_scale: float = Field(1.0, ge=0, le=1, description="finetune and mixed arms: the convolutions' rate "
                                    "relative to finetune_lr (0: frozen)")
    real_share: float = Field(0.5, gt=0, le=1, description="mixed arm: share of real images in the draws")
    augment: AugmentConfig = Field(AugmentConfig(on=True, **PRESETS["scale"]), description="augmentation of every "
                                   "training on real images (the pretraining's)")
    pretrain: TrainConfig = Field(default_factory=_readme_pretraining, description="simulation pretraining (its "
                                  "seed is replaced by each study seed)")
    preprocess: PreprocessConfig = Field(PreprocessConfig(v_range_mps=6.0, time_mode="window", intensity="power"),
                                         description="inputs (the README's single-radar models)")
    link: str = Field("radar1", description="the simulated link the real images stand for")
    model: ModelConfig | None = Field(None, description="the network (None: the seed's DCNN, one branch, at the "
                                      "preprocessing's size)")

    @field_validator("shots")
    @classmethod
    def _shots(cls, v):
        if any(isinstance(s, int) and s < 0 for s in v) or len(set(v)) != len(v):
            raise InputError(f"shots must be distinct counts >= 0 or 'all', got {list(v)}")
        return tuple(sorted(v, key=lambda s: (s == "all", s if s != "all" else 0)))

    def digest(self) -> str:
        """A short hash of every setting (a resumed study must have the same)."""
        return hashlib.sha256(json.dumps(self.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()[:16]


def real_step_budget(n_images: int, cfg: TransferConfig) -> int:
    """Optimiser steps of a real-only training on `n_images` images: enough batches of ``cfg.batch_size`` to draw
    each image ``cfg.real_passes`` times on average (rounded up), within [real_min_steps, real_steps]; always
    ``real_steps`` when ``real_passes`` is None (real_steps wins over a larger real_min_steps). Set from the image
    count alone, never from a fold's results."""
    if cfg.real_passes is None:
        return cfg.real_steps
    steps = math.ceil(cfg.real_passes * n_images / cfg.batch_size)
    return int(min(cfg.real_steps, max(cfg.real_min_steps, steps)))


@dataclass
class Arrays:
    """Preprocessed inputs x [N, 1, V, T] float32, labels y [N], groups [N] (people for real images) and item
    names [N]."""

    x: np.ndarray
    y: np.ndarray
    groups: list[str]
    names: list[str]


def subject_folds(groups, n_folds: int) -> list[np.ndarray]:
    """Test indices of each fold: the people (`groups`) dealt round-robin over `n_folds` folds in a fixed shuffled
    order (seed 0, the same for every study seed), so a person is in exactly one test fold."""
    groups = np.asarray(groups)
    people = np.unique(groups)
    if people.size < n_folds:
        raise InputError(f"{n_folds} folds need at least {n_folds} people in the real images, found {people.size}")
    order = people[np.random.default_rng(0).permutation(people.size)]
    fold_of = {p: k % n_folds for k, p in enumerate(order)}
    return [np.flatnonzero([fold_of[g] == f for g in groups]) for f in range(n_folds)]


def shot_indices(y, train_idx, shots: Shot, n_classes: int, seed: int, fold: int) -> np.ndarray:
    """`shots` images per class from `train_idx` (all of them for 'all'), drawn per (seed, fold) in a fixed
    order so that a smaller count is a subset of a larger one; sorted."""
    if shots == "all":
        return np.sort(np.asarray(train_idx))
    rng = np.random.default_rng([seed, fold, 0x5407])
    y = np.asarray(y)
    picked = []
    for c in range(n_classes):
        of_c = np.asarray(train_idx)[y[train_idx] == c]
        picked.append(of_c[rng.permutation(of_c.size)][:shots])
    return np.sort(np.concatenate(picked)).astype(np.int64)


@dataclass(frozen=True)
class Task:
    """One training and its test: `arm` 'pretrain' (fold -1, shots 0) or one of `ARMS`."""

    arm: str
    shots: Shot
    fold: int
    seed: int

    @property
    def key(self) -> str:
        return f"{self.arm}|{self.shots}|{self.fold}|{self.seed}"


def plan_tasks(cfg: TransferConfig) -> list[Task]:
    """Every (arm, shots > 0, fold, seed) training of a study (pretrainings and 0 shots apart)."""
    return [Task(arm, s, f, seed) for seed in cfg.seeds for s in cfg.shots if s != 0 for arm in cfg.arms
            for f in range(cfg.folds)]


# ---- one task (runs in a worker process) ------------------------------------------------------------------
_DATA: dict = {}


def _init_worker(data: dict) -> None:
    """Worker initialiser: the study's arrays, sent once per process."""
    _DATA.clear()
    _DATA.update(data)


def _train_config(cfg: TransferConfig, task: Task, n_steps: int, lr: float, scale: float) -> TrainConfig:
    return TrainConfig(epochs=1, patience=1, batch_size=cfg.batch_size, lr=lr, seed=task.seed, threads=1,
                       augment=cfg.augment, epoch_samples=n_steps * cfg.batch_size, feature_lr_scale=scale)


def run_task(task: Task, init_state: dict | None = None, data: dict | None = None) -> dict:
    """Train and test one task on the study's arrays (`data`, default the worker's): the run's row (accuracy,
    macro F1 and confusion on the fold's test images, counts, seconds); a pretraining returns its state dict
    under "state" instead of a test."""
    from processing.classifier.metrics import classification_report
    from processing.classifier.training import train

    d = _DATA if data is None else data
    cfg: TransferConfig = d["config"]
    sim, real, mcfg, pre = d["sim"], d["real"], d["model"], d["preprocess"]
    t0 = time.perf_counter()
    if task.arm == "pretrain":
        tcfg = cfg.pretrain.model_copy(update={"seed": task.seed, "threads": 1})
        res = train(sim.x, sim.y, mcfg, tcfg, groups=sim.groups, progress=False, log=None, preprocess=pre,
                    deployments=d.get("deployments"))
        val_acc = res.history["val_acc"][res.best_epoch - 1] if res.val_idx.size else float("nan")
        return {"key": task.key, "arm": "pretrain", "seed": task.seed, "state": res.model.state_dict(),
                "val_accuracy": float(val_acc), "epochs": len(res.history["seconds"]), "best_epoch": res.best_epoch,
                "n_train": int(res.train_idx.size), "seconds": time.perf_counter() - t0}
    folds = d["folds"]
    test = folds[task.fold]
    train_pool = np.setdiff1d(np.arange(real.y.size), test)
    shots = shot_indices(real.y, train_pool, task.shots, mcfg.n_classes, task.seed, task.fold)
    assert not np.intersect1d(shots, test).size  # no test image reaches training
    if task.arm == "real":
        x, y, sources, weights, state = real.x[shots], real.y[shots], None, [1.0], None
        tcfg = _train_config(cfg, task, real_step_budget(shots.size, cfg), cfg.lr, 1.0)
    elif task.arm == "finetune":
        x, y, sources, weights, state = real.x[shots], real.y[shots], None, [1.0], init_state
        tcfg = _train_config(cfg, task, cfg.finetune_steps, cfg.finetune_lr, cfg.feature_lr_scale)
    elif task.arm == "mixed":
        x, y = np.concatenate([sim.x, real.x[shots]]), np.concatenate([sim.y, real.y[shots]])
        sources = np.r_[np.zeros(sim.y.size, np.int64), np.ones(shots.size, np.int64)]
        weights, state = [1.0 - cfg.real_share, cfg.real_share], init_state
        tcfg = _train_config(cfg, task, cfg.mixed_steps, cfg.finetune_lr, cfg.feature_lr_scale)
    else:
        raise InputError(f"unknown arm {task.arm!r}")
    if task.arm != "real" and state is None:
        raise InputError(f"{task.key}: needs the pretrained weights of seed {task.seed}")
    sources = np.zeros(y.size, np.int64) if sources is None else sources
    res = train(x, y, mcfg, tcfg, split=(np.arange(y.size), np.zeros(0, np.int64)), progress=False, log=None,
                preprocess=pre, init_state=state, sources=sources, source_weights=weights)
    row = _test_row(res.model, real, test, classification_report)
    # how far the fixed number of steps fitted the training images (no test image involved)
    row.update(key=task.key, arm=task.arm, shots=task.shots, fold=task.fold, seed=task.seed, n_real=int(shots.size),
               shots_per_class=shots.size / mcfg.n_classes, train_loss=float(res.history["train_loss"][-1]),
               train_acc=float(res.history["train_acc"][-1]), steps=(tcfg.epoch_samples or 0) // cfg.batch_size,
               seconds=time.perf_counter() - t0)
    return row


def _test_row(net, real: Arrays, test: np.ndarray, report_fn) -> dict:
    """Accuracy, macro F1 and confusion of a network on the test images."""
    import torch

    from processing.labels import ACTIVITIES

    net.eval()
    with torch.inference_mode():
        pred = net(torch.as_tensor(real.x[test])).argmax(1).numpy()
    rep = report_fn(real.y[test], pred, list(ACTIVITIES))
    return {"accuracy": float(rep.accuracy), "macro_f1": float(rep.macro_f1), "n_test": int(test.size),
            "confusion": rep.confusion.tolist()}


def sim_only_rows(states: dict[int, dict], data: dict) -> list[dict]:
    """The 0-shot rows: each seed's pretrained network on every fold's test images (arm 'sim')."""
    from processing.classifier.metrics import classification_report
    from processing.classifier.model import build_model

    rows = []
    for seed, state in states.items():
        net = build_model(data["model"])
        net.load_state_dict(state)
        for f, test in enumerate(data["folds"]):
            row = _test_row(net, data["real"], test, classification_report)
            row.update(key=f"sim|0|{f}|{seed}", arm="sim", shots=0, fold=f, seed=seed, n_real=0, shots_per_class=0.0,
                       seconds=0.0)
            rows.append(row)
    return rows


__all__ = ["ARMS", "Arrays", "Task", "TransferConfig", "plan_tasks", "real_step_budget", "run_task", "shot_indices",
           "sim_only_rows", "subject_folds"]
