"""Benchmark (dataset issue): signatures per minute in points mode with 1 and 2 workers on a fixed subset of
the seed preset (the first generator seed of each activity x 3 heights = 15 of its 78 motions, 540 of 2808
items, 1080 signatures), the scaling efficiency, and the projected time of the full preset.

Run: python benchmarks/bench_dataset.py [--workers 1 2] [--seeds-per-activity 1] [--backend points]
The 1-worker figure is the in-process path (`--workers 1`); 2 workers use a local Dask cluster, whose
start-up is included in its wall time and in the projection. The machine is shared: figures are noisy.
"""
import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from rtchannel.dataset.plan import expand, load_plan
from rtchannel.dataset.runner import run_plan


def subset_filter(plan, per_activity: int):
    groups = {}
    for it in expand(plan):
        groups.setdefault(it.activity, [])
        if it.group not in groups[it.activity]:
            groups[it.activity].append(it.group)
    keep = {g for gs in groups.values() for g in gs[:per_activity]}
    return lambda it: it.group in keep


def bench(workers: int, per_activity: int, backend: str | None) -> dict:
    plan = load_plan("seed", backend=backend)
    total = len(expand(plan))
    with tempfile.TemporaryDirectory(prefix="bench_dataset_") as d:
        t0 = time.perf_counter()
        s = run_plan(plan, Path(d) / "ds", workers=workers, progress=False,
                     item_filter=subset_filter(plan, per_activity))
        wall = time.perf_counter() - t0
        from processing.io.dataset_reader import DatasetReader

        entries = DatasetReader(Path(d) / "ds").entries
        secs = [e["seconds"] for e in entries]
        cpu = [e["cpu_seconds"] for e in entries]
    n_sig = 2 * s.done_now
    return {"workers": workers, "items": s.done_now, "failed": len(s.failed), "wall_s": round(wall, 2),
            "signatures_per_min": round(60 * n_sig / wall, 1), "items_per_min": round(60 * s.done_now / wall, 1),
            "median_item_wall_s": round(statistics.median(secs), 4),
            "mean_item_cpu_s": round(statistics.mean(cpu), 4),
            # CPU time per item hardly depends on other processes: the time this machine would need unloaded
            "projected_full_preset_unloaded_min": round(total * statistics.mean(cpu) / workers / 60, 2),
            "projected_full_preset_min": round(total / (s.done_now / wall) / 60, 2), "full_preset_items": total}


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--seeds-per-activity", type=int, default=1)
    ap.add_argument("--backend", default=None)
    a = ap.parse_args()
    rows = [bench(w, a.seeds_per_activity, a.backend) for w in a.workers]
    if len(rows) > 1:
        base = rows[0]["signatures_per_min"] / rows[0]["workers"]
        for r in rows[1:]:
            r["scaling_efficiency"] = round(r["signatures_per_min"] / (r["workers"] * base), 3)
    print(json.dumps({"cpu_count": os.cpu_count(), "load_avg_1min": os.getloadavg()[0], "runs": rows}, indent=2))
