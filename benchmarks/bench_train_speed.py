"""Training throughput against a previous release, measured in one run: whole `rtchannel train` processes,
alternating between the two checkouts seed by seed.

    .venv/bin/python benchmarks/bench_train_speed.py --data /work/data/gp3 --baseline /work/base-a23t \\
        --seeds 0 1 2 3 4 5 6 7 8 --out out/bench_train_speed

Each seed trains once with the baseline checkout (PYTHONPATH) and once with this one, same options (default:
the README's single-radar protocol without the deployment split, which the older release lacks), in an
order that alternates (even seeds baseline first), one process at a time. Per training it records:

- epoch throughput: training samples x epochs / the epochs' wall seconds (the loop alone),
- end-to-end throughput: training samples x epochs / the whole process's wall seconds (imports, loading or
  the cache, training, writing),
- CPU throughput: the same per CPU second of the process (less sensitive to what else runs on the machine),
- the load average before and after, the loading seconds and the held-out validation accuracy.

This checkout's first run fills the preprocessed-input cache (`--cache-dir`, emptied at the start), later
runs read it. Writes OUT/results.json and OUT/results.md (median, minimum, maximum per figure and version,
and the ratios of the medians). Timing on a shared machine is noisy: read the load averages with the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ["--links", "radar1", "--v-range", "6", "--time-mode", "window", "--intensity", "power",
            "--augment", "scale"]


def _run(checkout: Path, data: str, out: Path, seed: int, extra: list[str], cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "RTCHANNEL_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "rtchannel.cli", "train", "--data", data, "--out", str(out), "--seed", str(seed),
           "--quiet", *PROTOCOL, *extra]
    load0 = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=out.parent, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{checkout}: train failed:\n{proc.stderr[-2000:]}")
    import torch

    blob = torch.load(out, weights_only=True)
    meta, hist = blob["meta"], blob["history"]
    n, epochs = int(meta["n_train"]), len(hist["seconds"])
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"seed": seed, "n_train": n, "epochs": epochs, "wall_s": wall, "cpu_s": cpu,
            "load_s": float(meta["load_seconds"]), "val_accuracy": float(meta["val_accuracy"]),
            "epoch_samples_per_s": n * epochs / float(sum(hist["seconds"])),
            "end_to_end_samples_per_s": n * epochs / wall, "cpu_samples_per_s": n * epochs / cpu,
            "loadavg_before": load0, "loadavg_after": os.getloadavg()[0]}


def _stats(rows: list[dict], key: str) -> dict:
    v = np.array([r[key] for r in rows], float)
    return {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max()), "mean": float(v.mean())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="dataset folder (e.g. the glasgow preset)")
    ap.add_argument("--baseline", required=True, type=Path, help="checkout of the previous release")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(9)))
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench_train_speed")
    ap.add_argument("--cache-dir", type=Path, help="preprocessed-input cache of this checkout (default OUT/cache)")
    ap.add_argument("--extra", nargs=argparse.REMAINDER, default=[], help="more train options, for both")
    a = ap.parse_args()
    out = a.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    cache = (a.cache_dir or out / "cache").resolve()
    shutil.rmtree(cache, ignore_errors=True)
    versions = {"baseline": a.baseline.resolve(), "current": ROOT}
    rows: dict[str, list[dict]] = {k: [] for k in versions}
    for seed in a.seeds:
        order = list(versions) if seed % 2 == 0 else list(versions)[::-1]
        for name in order:
            r = _run(versions[name], a.data, out / f"{name}_s{seed}.pt", seed, a.extra, cache)
            rows[name].append(r)
            print(f"{name:8s} seed {seed}: {r['epochs']} epochs x {r['n_train']}, "
                  f"epoch {r['epoch_samples_per_s']:.0f}, "
                  f"end-to-end {r['end_to_end_samples_per_s']:.0f}, cpu {r['cpu_samples_per_s']:.0f} samples/s; load "
                  f"{r['load_s']:.1f} s; val acc {100 * r['val_accuracy']:.1f} %; loadavg {r['loadavg_before']:.1f}",
                  flush=True)
    keys = ["epoch_samples_per_s", "end_to_end_samples_per_s", "cpu_samples_per_s", "load_s", "val_accuracy",
            "epochs", "loadavg_before"]
    summary = {name: {k: _stats(rs, k) for k in keys} for name, rs in rows.items()}
    ratios = {k: summary["current"][k]["median"] / summary["baseline"][k]["median"] for k in keys[:3]}
    (out / "results.json").write_text(json.dumps({"data": a.data, "baseline": str(a.baseline), "rows": rows,
                                                  "summary": summary, "ratios_of_medians": ratios}, indent=1))
    md = ["| figure | baseline median (min-max) | current median (min-max) | ratio |", "|---|---|---|---|"]
    for k in keys:
        b, c = summary["baseline"][k], summary["current"][k]
        md.append(f"| {k} | {b['median']:.3g} ({b['min']:.3g}-{b['max']:.3g}) | {c['median']:.3g} "
                  f"({c['min']:.3g}-{c['max']:.3g}) | {ratios.get(k, c['median'] / b['median']):.2f} |")
    (out / "results.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
