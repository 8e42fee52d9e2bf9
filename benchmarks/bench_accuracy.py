"""Benchmark (issue 26): the facets chain at each accuracy budget against the default setting, same run.

The chain of `rtchannel bench --chain facets` (5 s walk toward Radar 1, two monostatic seed radars, room,
signatures only) is timed for the default options and for each budget (`simulate(..., accuracy=B)`, the
shipped calibration table of the seed radar), in rounds that alternate the settings so that a change of
machine load hits all of them; medians per setting and their ratio to the default's median are printed.

`--baseline DIR` also times the chain of a second checkout (e.g. the code before this issue:
`git worktree add /tmp/base 52e9098`) in subprocesses within the same rounds, so that "faster than
today's default" is a ratio measured in one session, not against a number from another day.

Run: .venv/bin/python benchmarks/bench_accuracy.py [--repeats 5] [--budgets fast,balanced] [--baseline DIR]
"""
import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

CHILD = """
import json, sys, time
sys.path.insert(0, {root!r})
from rtchannel.analysis.chain_bench import exact_duration_walk
from rtchannel.pipeline import simulate
from rtchannel.radar import RadarConfig
m, r = exact_duration_walk(5.0), RadarConfig()
simulate(m, r, backend="facets")
out = []
for _ in range({n}):
    t0 = time.perf_counter(); simulate(m, r, backend="facets"); out.append(time.perf_counter() - t0)
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="rounds (each times every setting once)")
    ap.add_argument("--budgets", default="fast,balanced", help="comma-separated budgets to time")
    ap.add_argument("--baseline", type=Path, help="a second checkout whose default chain is timed in each round")
    ap.add_argument("--json", type=Path, help="write the medians here")
    args = ap.parse_args()

    from rtchannel.analysis.chain_bench import exact_duration_walk
    from rtchannel.pipeline import simulate
    from rtchannel.radar import RadarConfig

    motion, radar = exact_duration_walk(5.0), RadarConfig()
    settings = {"default": {}}
    for b in args.budgets.split(","):
        settings[b] = {"accuracy": b}
    chosen = {}
    for name, kw in settings.items():  # warm-up: scenes, LODs, kernels
        res = simulate(motion, radar, backend="facets", **kw)
        chosen[name] = res.config.get("accuracy", {}).get("chosen", "defaults")
    times = {name: [] for name in settings}
    if args.baseline is not None:
        times["baseline (other checkout)"] = []
    for _ in range(args.repeats):
        for name, kw in settings.items():
            t0 = time.perf_counter()
            simulate(motion, radar, backend="facets", **kw)
            times[name].append(time.perf_counter() - t0)
        if args.baseline is not None:
            code = CHILD.format(root=str(args.baseline.resolve()), n=1)
            out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                 cwd=args.baseline)
            times["baseline (other checkout)"] += json.loads(out.stdout.strip().splitlines()[-1])
    med = {k: statistics.median(v) for k, v in times.items()}
    rows = {k: {"median_s": med[k], "ratio_to_default": med[k] / med["default"],
                "speedup_vs_default": med["default"] / med[k], "chosen": chosen.get(k, ""),
                "runs_s": [round(x, 4) for x in times[k]]} for k in times}
    if args.baseline is not None:
        for k in rows:
            rows[k]["speedup_vs_baseline"] = med["baseline (other checkout)"] / med[k]
    text = json.dumps({"repeats": args.repeats, "settings": rows}, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
