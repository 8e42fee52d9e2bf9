"""Classifier benchmark: train on the seed-size procedural dataset, test on real motion capture and unseen
directions/motions; reports accuracies and training time.

    .venv/bin/python benchmarks/bench_train.py --out out/bench_train [--seed-data out/seed]

Steps (datasets are generated with `rtchannel dataset` unless they exist already):
  1. seed     : the `seed` preset (26 procedural motions x 3 heights x 18 directions x 2 gain sets = 2808)
  2. mocap    : the 11 CMU walks of the data registry (mocap/cmu/walk) x 18 directions (walk class only)
  3. unseen   : the seed plan with another plan seed and height (new procedural motions), 6 directions
  4. train on `seed` (timed), evaluate on `mocap` and `unseen`
  5. crossval : odd seed directions -> even seed directions (and held-out validation)
Writes OUT/results.json and OUT/results.md. Timing on a shared 2-core machine is noisy: one run, not a median.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import yaml

from rtchannel.cli import main as cli

ROOT = Path(__file__).resolve().parents[1]
MOCAP_WALKS = "data:mocap/cmu/walk"  # the CMU walks through the data registry

MOCAP_PLAN = {
    "name": "mocap_walks", "seed": 5, "backend": "points",
    "motion": {"fps": 60, "sources": [{"files": MOCAP_WALKS, "activity": "walk"}], "heights": [1.74]},
    "physical": {"directions": "seed"},
    "signal": {"gain_sets": [{"name": "seed"}]},
    "storage": {"items_per_shard": 18},
}


def _unseen_plan() -> dict:
    plan = yaml.safe_load((ROOT / "rtchannel" / "dataset" / "presets" / "seed.yaml").read_text())
    plan.update(name="unseen_motions", seed=99)
    plan["motion"]["heights"] = [1.65]
    plan["physical"]["directions"] = [2, 5, 8, 11, 14, 17]
    plan["signal"]["gain_sets"] = [{"name": "seed"}]
    return plan


def _dataset(config: str | dict, out: Path, workers: int) -> Path:
    if (out / "index.jsonl").is_file():
        return out
    if isinstance(config, dict):
        path = out.with_suffix(".yaml")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(yaml.safe_dump(config))
        config = str(path)
    t0 = time.perf_counter()
    assert cli(["dataset", "--config", config, "--out", str(out), "--workers", str(workers), "--quiet"]) == 0
    print(f"{out.name}: generated in {time.perf_counter() - t0:.0f} s")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench_train")
    ap.add_argument("--seed-data", type=Path, help="existing seed-preset dataset (default OUT/seed)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--extra", nargs="*", default=[], help="extra train options, e.g. --size 64 64")
    ap.add_argument("--skip-crossval", action="store_true")
    a = ap.parse_args()
    out = a.out
    seed = _dataset("seed", a.seed_data or out / "seed", a.workers)
    mocap = _dataset(MOCAP_PLAN, out / "mocap", a.workers)
    unseen = _dataset(_unseen_plan(), out / "unseen", a.workers)

    model = out / "model.pt"
    t0 = time.perf_counter()
    assert cli(["train", "--data", str(seed), "--out", str(model), "--quiet", *a.extra]) == 0
    wall = time.perf_counter() - t0
    blob = __import__("torch").load(model, weights_only=True)
    meta, hist = blob["meta"], blob["history"]
    results = {"train_wall_s": wall, "train_s": meta["train_seconds"], "load_s": meta["load_seconds"],
               "epochs": len(hist["val_acc"]), "epoch_s_median": sorted(hist["seconds"])[len(hist["seconds"]) // 2],
               "best_epoch": meta["best_epoch"],
               "val_accuracy": meta["val_accuracy"], "n_train": meta["n_train"], "n_val": meta["n_val"]}
    for name, data in (("mocap_walks", mocap), ("unseen_motions", unseen)):
        ev = out / f"eval_{name}"
        assert cli(["evaluate", "--model", str(model), "--data", str(data), "--out", str(ev), "--quiet"]) == 0
        m = json.loads((ev / "metrics.json").read_text())
        results[name] = {"n": m["n"], "accuracy": m["accuracy"], "macro_f1": m["macro_f1"]}
    if not a.skip_crossval:
        odd = "|".join(str(k) for k in range(1, 19, 2))
        even = "|".join(str(k) for k in range(2, 19, 2))
        table = out / "crossval_directions.csv"
        assert cli(["crossval", "--train", f"{seed}:direction={odd}", "--test", f"{seed}:direction={even}",
                    "--test", f"{seed}:direction={odd}", "--out", str(table), "--quiet", *a.extra]) == 0
        results["crossval_table"] = table.with_suffix(".md").read_text()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
