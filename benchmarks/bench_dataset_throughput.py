"""Benchmark (issue 41, deliverable 2): dataset throughput, items per minute of a plan's subset, this checkout
against a baseline checkout measured in the same session (runs alternate, each in its own process).

Subset: the first K motions (distinct motion keys, in expansion order) of every motion source of the plan, with
all their items (placements, gain sets, ...): every source, procedural and file, is represented, and the same
rule picks the same items from the same plan on both checkouts. `--config` is a plan file or a preset name,
resolved by each checkout itself: `--config glasgow` runs each checkout's own preset (what a user of either
sees), a plan file runs the same plan on both (the code's own gain).

Per checkout and run: items, wall time [s] from `run_plan`'s start to its end (Dask cluster start-up and the
shards' HDF5 writes included), items per minute, and the mean CPU seconds per item from the index
(`cpu_seconds`: its share of a shared backend run). Reported: median, min and max over `--repeats` runs, the
ratio of the medians (this / baseline) and the load average. Where the index records the per-stage wall time
(`stage_seconds`: set-up, backend, synthesis, DSP, image chain), its mean per item is printed too. Before the
timed runs each checkout runs one motion untimed (numba fills its on-disk cache on a first run).

Run: python benchmarks/bench_dataset_throughput.py --config glasgow --backend facets [--motions-per-source 1]
     [--limit-motions N] [--workers 2] [--repeats 3] [--baseline DIR] [--baseline-config PLAN] [--json F]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def subset(items, per_source: int):
    """The items of the first `per_source` motion keys of each source (expansion order)."""
    keys: dict[str, list[str]] = {}
    for it in items:
        seen = keys.setdefault(it.source, [])
        if it.motion["key"] not in seen and len(seen) < per_source:
            seen.append(it.motion["key"])
    keep = {(s, k) for s, ks in keys.items() for k in ks}
    return [it for it in items if (it.source, it.motion["key"]) in keep]


def child(args) -> dict:
    """One run in this process (of the checkout on PYTHONPATH): the stats of `run_plan` on the subset."""
    from rtchannel.dataset.plan import expand, load_plan
    from rtchannel.dataset.runner import run_plan

    plan = load_plan(args.config, backend=args.backend)
    chosen = subset(expand(plan), args.motions_per_source)
    if args.limit_motions:
        keys = list(dict.fromkeys(it.motion["key"] for it in chosen))[:args.limit_motions]
        chosen = [it for it in chosen if it.motion["key"] in keys]
    ids = {it.item_id for it in chosen}
    with tempfile.TemporaryDirectory(prefix="bench_throughput_", dir=args.tmp) as d:
        t0 = time.perf_counter()
        s = run_plan(plan, Path(d) / "ds", workers=args.workers, progress=False,
                     item_filter=lambda it: it.item_id in ids)
        wall = time.perf_counter() - t0
        entries = [json.loads(line) for line in (Path(d) / "ds" / "index.jsonl").read_text().splitlines() if line]
    stages: dict[str, float] = {}
    for e in entries:
        for k, v in (e.get("stage_seconds") or {}).items():
            stages[k] = stages.get(k, 0.0) + v / len(entries)
    return {"items": s.done_now, "failed": len(s.failed), "wall_s": wall, "items_per_min": 60.0 * s.done_now / wall,
            "cpu_per_item_s": statistics.mean(e["cpu_seconds"] for e in entries) if entries else 0.0,
            "seconds_per_item": statistics.mean(e["seconds"] for e in entries) if entries else 0.0,
            "stage_seconds": stages, "plan": plan.name, "workers": s.workers}


def run_child(code: Path, config: str, args, limit_motions: int = 0) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(code), os.environ.get("PYTHONPATH")) if p)}
    argv = [sys.executable, str(Path(__file__).resolve()), "--child", "--config", config, "--workers",
            str(args.workers), "--motions-per-source", str(args.motions_per_source), "--tmp", args.tmp]
    if args.backend:
        argv += ["--backend", args.backend]
    if limit_motions:
        argv += ["--limit-motions", str(limit_motions)]
    r = subprocess.run(argv, cwd=code, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{code}: {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def summary(runs: list[dict]) -> dict:
    rates = [r["items_per_min"] for r in runs]
    return {"items": runs[0]["items"], "items_per_min_median": statistics.median(rates),
            "items_per_min_min": min(rates),
            "items_per_min_max": max(rates), "wall_s_median": statistics.median(r["wall_s"] for r in runs),
            "cpu_per_item_s_median": statistics.median(r["cpu_per_item_s"] for r in runs),
            "stage_seconds": {k: statistics.median(r["stage_seconds"].get(k, 0.0) for r in runs)
                              for k in runs[0]["stage_seconds"]}, "runs": runs}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="glasgow", help="plan file or preset name (default glasgow)")
    ap.add_argument("--backend", help="override the plan's backend (e.g. facets)")
    ap.add_argument("--motions-per-source", type=int, default=1, help="motions kept per source (default 1)")
    ap.add_argument("--workers", type=int, default=2, help="dataset workers (default 2; 1 runs in the process)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per checkout (default 3)")
    ap.add_argument("--code", type=Path, default=ROOT, help="checkout to time (default: this one)")
    ap.add_argument("--baseline", type=Path, help="second checkout, timed in the same session")
    ap.add_argument("--baseline-config", help="plan for the baseline (default: --config)")
    ap.add_argument("--tmp", default=tempfile.gettempdir(), help="folder for the temporary datasets")
    ap.add_argument("--json", type=Path, help="also write the results here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--limit-motions", type=int, default=0,
                    help="then keep only the first N motions of the subset (default: all)")
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args)), flush=True)
        return 0
    codes = {"this": (args.code.resolve(), args.config)}
    if args.baseline is not None:
        codes["baseline"] = (args.baseline.resolve(), args.baseline_config or args.config)
    out = {"cpus": os.cpu_count(), "load_before": os.getloadavg(), "config": {t: c for t, (_, c) in codes.items()},
           "code": {t: str(p) for t, (p, _) in codes.items()}, "backend": args.backend, "workers": args.workers,
           "motions_per_source": args.motions_per_source, "repeats": args.repeats}
    for tag, (code, config) in codes.items():  # untimed: numba's on-disk caches, file downloads
        run_child(code, config, args, limit_motions=1)
    runs = {t: [] for t in codes}
    for _ in range(args.repeats):
        for tag, (code, config) in codes.items():
            r = run_child(code, config, args, limit_motions=args.limit_motions)
            r["load_1min"] = os.getloadavg()[0]
            runs[tag].append(r)
            print(f"{tag:8s} {r['items']} items in {r['wall_s']:.1f} s: {r['items_per_min']:.1f} items/min, "
                  f"{r['cpu_per_item_s']:.3f} CPU s/item, load {r['load_1min']:.1f}", flush=True)
    out["results"] = {t: summary(rs) for t, rs in runs.items()}
    out["load_after"] = os.getloadavg()
    for tag, s in out["results"].items():
        print(f"{tag:8s} items/min median {s['items_per_min_median']:.1f} (min {s['items_per_min_min']:.1f}, max "
              f"{s['items_per_min_max']:.1f}); CPU per item {s['cpu_per_item_s_median']:.3f} s; plan "
              f"{s['runs'][0]['plan']} ({codes[tag][1]}), {s['items']} items")
        if s["stage_seconds"]:
            print("         per item [s]: " + ", ".join(f"{k} {v:.3f}" for k, v in s["stage_seconds"].items()))
    if "baseline" in out["results"]:
        a, b = out["results"]["this"], out["results"]["baseline"]
        out["ratio_items_per_min"] = a["items_per_min_median"] / b["items_per_min_median"]
        out["ratio_cpu_per_item"] = b["cpu_per_item_s_median"] / a["cpu_per_item_s_median"]
        # run k of this checkout against run k of the baseline, started next to it (the same machine load)
        paired = [x["items_per_min"] / y["items_per_min"] for x, y in zip(runs["this"], runs["baseline"])]
        out["paired_ratio_items_per_min"] = {"median": statistics.median(paired), "min": min(paired),
                                             "max": max(paired)}
        print(f"this / baseline: items per minute x{out['ratio_items_per_min']:.2f}, CPU per item "
              f"x{out['ratio_cpu_per_item']:.2f} less (paired items/min ratios: median "
              f"{out['paired_ratio_items_per_min']['median']:.2f}, "
              f"min {min(paired):.2f}, max {max(paired):.2f}); load average {out['load_before'][0]:.1f} before, "
              f"{out['load_after'][0]:.1f} after ({out['cpus']} CPUs)")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
