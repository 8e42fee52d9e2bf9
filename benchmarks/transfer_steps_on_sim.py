"""How many steps the transfer study's real-only arm needs, chosen on SIMULATED items only (no real image is read):
k simulated items per class from scratch (the arm's training: batch 32, the study's augmentation and learning rate,
fixed steps, no validation), tested on the items of a quarter of the motion sources held out.

    .venv/bin/python benchmarks/transfer_steps_on_sim.py --sim /work/data/gp4 5:30 5:60 5:100 5:150 1:30 1:100 \
        20:60 20:150

Each argument is K:STEPS; two seeds each. Prints one line per training (training and held-out accuracy, seconds).
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    from processing.classifier.experiment import load_dataset
    from processing.classifier.metrics import classification_report
    from processing.classifier.model import ModelConfig
    from processing.classifier.training import train
    from processing.classifier.transfer import Task, TransferConfig, _test_row, _train_config, shot_indices

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", required=True, help="simulated dataset")
    ap.add_argument("runs", nargs="+", metavar="K:STEPS")
    args = ap.parse_args()
    cfg = TransferConfig()
    pre = cfg.preprocess
    mcfg = cfg.model or ModelConfig(n_branches=1, input_size=(pre.n_velocity, pre.n_time))
    sim = load_dataset(args.sim, [cfg.link], pre)
    groups = np.asarray(sim.groups)
    sources = np.unique(groups)
    held = sources[np.random.default_rng(0).permutation(sources.size)][: sources.size // 4]
    test, pool = np.flatnonzero(np.isin(groups, held)), np.flatnonzero(~np.isin(groups, held))
    print(f"{sim.y.size} items of {sources.size} motion sources; {test.size} held out", flush=True)
    for k, steps in [(int(a), int(b)) for a, b in (r.split(":") for r in args.runs)]:
        for seed in (0, 1):
            idx = shot_indices(sim.y, pool, k, mcfg.n_classes, seed, 0)
            tcfg = _train_config(cfg, Task("real", k, 0, seed), steps, cfg.lr, 1.0)
            t0 = time.perf_counter()
            res = train(sim.x[idx], sim.y[idx], mcfg, tcfg, split=(np.arange(idx.size), np.zeros(0, np.int64)),
                        progress=False, log=None, preprocess=pre, sources=np.zeros(idx.size, np.int64),
                        source_weights=[1.0])
            row = _test_row(res.model, sim, test, classification_report)
            print(f"k={k} steps={steps} seed={seed} train_acc={res.history['train_acc'][-1]:.2f} "
                  f"held_out={100 * row['accuracy']:.1f} % ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
