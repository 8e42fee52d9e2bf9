"""Benchmark (issue 12, deliverable 4): the whole `rtchannel simulate` process, start to exit.

Goals on an idle 2-core machine: `--backend points` <= 1.5 s and `--backend facets` <= 3 s (default 5 s
walk, the seed's two radars, 10k body, room), figures included (they are on by default).

Each case runs as its own process (`python -m rtchannel.cli simulate ...`, this checkout first on the path,
so an editable install of another checkout is not what gets timed), after one untimed warm-up run (numba
and Dr.Jit fill their on-disk caches on a first run). Reported per case: median, min and max wall time [s]
of `--repeats` runs, median CPU time (user + sys of the child) [s], and the ratio of the median wall time
to a `python -c pass` baseline measured in the same session (which tracks how loaded the machine is).
`--importtime` adds, per case, one `python -X importtime` run: the cumulative import time [s] of the
top-level modules the command loads. `--code DIR` times another checkout instead (e.g. the main branch,
for a before/after table).

Run: python benchmarks/bench_startup.py [--repeats 3] [--backends points facets] [--importtime] [--json F]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _env(code: Path) -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(code), os.environ.get("PYTHONPATH")) if p)}


def run_once(argv: list[str], code: Path) -> tuple[float, float]:
    """(wall [s], CPU user+sys [s]) of one child process; raises if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(argv, cwd=code, env=_env(code), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed ({r.returncode}): {r.stderr[-1000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def import_breakdown(argv: list[str], code: Path, top: int = 12) -> list[tuple[str, float]]:
    """[(module, cumulative import time [s])] of the `top` slowest modules imported at the top level (not as
    a dependency of another module) during one run of `argv` under `python -X importtime`."""
    r = subprocess.run([argv[0], "-X", "importtime", *argv[1:]], cwd=code, env=_env(code), capture_output=True,
                       text=True)
    rows = []
    for line in r.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cum, name = line[len("import time:"):].split("|")
        if len(name) - len(name.lstrip(" ")) <= 1:  # depth 0: " name"
            rows.append((name.strip(), int(cum) / 1e6))
    return sorted(rows, key=lambda x: -x[1])[:top]


def cases(backends: list[str], out: Path) -> dict[str, list[str]]:
    """{label: argv} of every case: each backend with and without figures."""
    py = [sys.executable, "-m", "rtchannel.cli", "simulate"]
    out_cases = {}
    for b in backends:
        for plots in (True, False):
            label = f"{b}{'' if plots else ' --no-plots'}"
            # no --quiet: the command as a user types it (tqdm turns itself off on the captured stderr)
            out_cases[label] = [*py, "--backend", b, "--out", str(out / label.replace(" ", "_")),
                                *([] if plots else ["--no-plots"])]
    return out_cases


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per case (default 3)")
    ap.add_argument("--backends", nargs="+", default=["points", "facets"], help="default: points facets")
    ap.add_argument("--warmup", type=int, default=1, help="untimed runs per case first (default 1)")
    ap.add_argument("--importtime", action="store_true", help="also the import-time breakdown per case")
    ap.add_argument("--code", type=Path, default=ROOT, help="checkout to time (default: this one)")
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args()
    code = args.code.resolve()

    result = {"code": str(code), "python": platform.python_version(), "cpus": os.cpu_count(),
              "load_before": os.getloadavg(), "repeats": args.repeats, "cases": {}}
    base = [run_once([sys.executable, "-c", "pass"], code)[0] for _ in range(max(3, args.repeats))]
    result["python_pass_s"] = statistics.median(base)
    with tempfile.TemporaryDirectory() as tmp:
        for label, argv in cases(args.backends, Path(tmp)).items():
            for _ in range(args.warmup):
                run_once(argv, code)
            runs = [run_once(argv, code) for _ in range(args.repeats)]
            walls = [w for w, _ in runs]
            entry = {"wall_median_s": statistics.median(walls), "wall_min_s": min(walls), "wall_max_s": max(walls),
                     "cpu_median_s": statistics.median(c for _, c in runs),
                     "ratio_to_python_pass": statistics.median(walls) / result["python_pass_s"],
                     "load_1min": os.getloadavg()[0]}
            if args.importtime:
                entry["imports_s"] = import_breakdown(argv, code)
            result["cases"][label] = entry
            print(f"{label:22s} wall median {entry['wall_median_s']:6.2f} s (min {entry['wall_min_s']:.2f}, max "
                  f"{entry['wall_max_s']:.2f}), cpu {entry['cpu_median_s']:.2f} s, x{entry['ratio_to_python_pass']:.0f}"
                  f" python -c pass, load {entry['load_1min']:.1f}", flush=True)
            for name, s in entry.get("imports_s", []):
                print(f"    import {name:40s} {s:6.3f} s")
    result["load_after"] = os.getloadavg()
    print(f"python -c pass: {result['python_pass_s'] * 1e3:.0f} ms; load average before {result['load_before'][0]:.1f}, "
          f"after {result['load_after'][0]:.1f} ({os.cpu_count()} CPUs)")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
