"""Cost of checking every stored array against its sha256 when a dataset run resumes.

    python benchmarks/bench_resume_verify.py [--items 300] [--out /tmp/verify_bench]

Builds (once) a points-backend dataset of about --items items from the seed preset's motions, then times
`scan_shards` without and with verification (each three times: the first pass may read from disk, the
others from the page cache) and a complete no-op resume (`run_plan` with nothing left to do).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--items", type=int, default=300)
    ap.add_argument("--out", type=Path, default=Path("/tmp/verify_bench"))
    args = ap.parse_args()
    from processing.io.dataset_store import SHARDS, scan_shards
    from rtchannel.dataset.plan import load_plan
    from rtchannel.dataset.runner import run_plan

    plan = load_plan("seed")
    n = [0]

    def first(it) -> bool:
        n[0] += 1
        return n[0] <= args.items

    t0 = time.perf_counter()
    s = run_plan(plan, args.out, workers=1, progress=False, item_filter=first)
    print(f"dataset: {s.done_before + s.done_now} items ({time.perf_counter() - t0:.0f} s to build or find)")
    size = sum(p.stat().st_size for p in (args.out / SHARDS).glob("*.h5"))
    for verify in (False, True, True, True):
        t0 = time.perf_counter()
        entries, bad = scan_shards(args.out, verify=verify)
        dt = time.perf_counter() - t0
        print(f"scan_shards(verify={verify}): {len(entries)} items, {size / 2**20:.1f} MiB, {dt:.2f} s "
              f"({1e3 * dt / max(len(entries), 1):.2f} ms/item, {size / 2**20 / dt:.0f} MiB/s), bad={bad}")
    n[0] = 0
    t0 = time.perf_counter()
    s = run_plan(plan, args.out, workers=1, progress=False, item_filter=first)
    print(f"no-op resume: {time.perf_counter() - t0:.2f} s (of which verification {s.verify_seconds:.2f} s)")


if __name__ == "__main__":
    main()
