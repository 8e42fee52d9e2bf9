"""Benchmark (issue 12, deliverable 4): the whole `rtchannel simulate` process, start to exit.

Goals on an idle 2-core machine: `--backend points` <= 1.5 s and `--backend facets` <= 3 s (default 5 s
walk, the seed's two radars, 10k body, room), figures included (they are on by default).

Each case runs as its own process (`python -m rtchannel.cli simulate ...`, this checkout first on the path,
so an editable install of another checkout is not what gets timed), after one untimed warm-up run (numba
and Dr.Jit fill their on-disk caches on a first run). Reported per case: median, min and max wall time [s]
of `--repeats` runs, median CPU time (user + sys of the command and the processes it waited for, such as
its figure process) [s], and the ratio of the median wall time to a `python -c pass` baseline measured in
the same session (which tracks how loaded the machine is).
`--importtime` adds, per case, one `python -X importtime` run: the cumulative import time [s] of the
top-level modules the command loads. `--split` adds, per case, `--repeats` runs of
`benchmarks/startup_stages.py` (the same command inside one process, its stages timed apart: imports per
stage, scene load, backend, synthesis+DSP, signature.h5, figures; medians [s]) and the interpreter's own
start-up (whole process minus the in-process total). `--code DIR` times another checkout instead.

`--baseline DIR` times a second checkout (e.g. `git archive main | tar -x -C DIR`) in the same session,
runs interleaved with this one's so both see the same machine load, prints the ratio of the medians and the
median, min and max of the ratios pair by pair (run k of this checkout against the baseline's run k), and
checks that both wrote bit-identical signature.h5 contents (every dataset's bytes, dtype and shape, every
attribute): a start-up change must not change results.

Run: python benchmarks/bench_startup.py [--repeats 3] [--backends points facets] [--importtime] [--split]
     [--baseline DIR] [--plots-only] [--json F]
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


def split_once(argv: list[str], code: Path) -> tuple[float, dict]:
    """(whole-process wall [s], `startup_stages.py` result) of one run of the `rtchannel` command in `argv`
    (`[python, -m, rtchannel.cli, *args]`) with its stages timed inside the process."""
    probe = [argv[0], str(ROOT / "benchmarks" / "startup_stages.py"), *argv[3:]]
    t0 = time.time()
    r = subprocess.run(probe, cwd=code, env=_env(code), capture_output=True, text=True)
    t1 = time.time()
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(probe)} failed ({r.returncode}): {r.stderr[-1000:]}")
    res = json.loads(r.stdout.strip().splitlines()[-1])
    res["start_s"], res["exit_s"] = res["start_epoch"] - t0, t1 - res["end_epoch"]
    return t1 - t0, res


def median_split(runs: list[tuple[float, dict]]) -> dict[str, list[float]]:
    """{stage: [median work s, median import s]} over runs, plus "interpreter start" (spawn to the probe's
    first line), "interpreter exit" (the probe's last line to the parent seeing the exit) and "whole process"."""
    names = list(dict.fromkeys(n for _, r in runs for n in r["stages"]))
    out = {"interpreter start": [statistics.median(r["start_s"] for _, r in runs), 0.0]}
    for n in names:
        out[n] = [statistics.median(r["stages"].get(n, [0.0, 0.0])[k] for _, r in runs) for k in (0, 1)]
    out["interpreter exit"] = [statistics.median(r["exit_s"] for _, r in runs), 0.0]
    out["whole process"] = [statistics.median(w for w, _ in runs), 0.0]
    return out


def signature_contents(path: Path) -> dict[str, tuple]:
    """{name: (dtype, shape, bytes)} of every dataset and attribute in an HDF5 file (for bit-identity)."""
    import h5py
    import numpy as np

    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            for k, v in obj.attrs.items():
                a = np.asarray(v)
                out[f"{name}@{k}"] = (str(a.dtype), a.shape, a.tobytes() if a.dtype != object else repr(v).encode())
            if isinstance(obj, h5py.Dataset):
                a = obj[()]
                out[name] = (str(a.dtype), np.shape(a), np.asarray(a).tobytes())

        visit("/", f)
        f.visititems(visit)
    return out


def identical(a: Path, b: Path) -> list[str]:
    """Names of the datasets/attributes that differ between two signature files ([] if bit-identical), but
    for the root's `timing` attribute (the run's own stage times, different on every run)."""
    ca, cb = signature_contents(a), signature_contents(b)
    return sorted(k for k in ca.keys() | cb.keys() if ca.get(k) != cb.get(k) and k != "/@timing")


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


def _timed(label: str, argvs: dict[str, list[str]], codes: dict[str, Path], args, pass_s: dict) -> dict:
    """Warm-up, then `args.repeats` timed runs per checkout, interleaved; {tag: entry}."""
    for tag, code in codes.items():
        for _ in range(args.warmup):
            run_once(argvs[tag], code)
    runs = {tag: [] for tag in codes}
    for _ in range(args.repeats):
        for tag, code in codes.items():
            runs[tag].append(run_once(argvs[tag], code))
    out = {}
    for tag, rs in runs.items():
        walls = [w for w, _ in rs]
        out[tag] = {"wall_median_s": statistics.median(walls), "wall_min_s": min(walls), "wall_max_s": max(walls),
                    "cpu_median_s": statistics.median(c for _, c in rs),
                    "ratio_to_python_pass": statistics.median(walls) / pass_s[tag], "load_1min": os.getloadavg()[0]}
    if "baseline" in runs:  # pair by pair (run k of this against run k of the baseline, started next to it)
        ratios = [a[0] / b[0] for a, b in zip(runs["this"], runs["baseline"])]
        out["this"]["paired_ratio"] = {"median": statistics.median(ratios), "min": min(ratios), "max": max(ratios)}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per case (default 3)")
    ap.add_argument("--backends", nargs="+", default=["points", "facets"], help="default: points facets")
    ap.add_argument("--warmup", type=int, default=1, help="untimed runs per case first (default 1)")
    ap.add_argument("--importtime", action="store_true", help="also the import-time breakdown per case")
    ap.add_argument("--split", action="store_true", help="also the per-stage split per case (startup_stages.py)")
    ap.add_argument("--plots-only", action="store_true", help="skip the --no-plots cases")
    ap.add_argument("--code", type=Path, default=ROOT, help="checkout to time (default: this one)")
    ap.add_argument("--baseline", type=Path, help="second checkout timed in the same session (before/after)")
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args()
    codes = {"this": args.code.resolve()}
    if args.baseline is not None:
        codes["baseline"] = args.baseline.resolve()

    result = {"code": {t: str(c) for t, c in codes.items()}, "python": platform.python_version(),
              "cpus": os.cpu_count(), "load_before": os.getloadavg(), "repeats": args.repeats, "cases": {}}
    pass_s = {t: statistics.median(run_once([sys.executable, "-c", "pass"], c)[0] for _ in range(max(3, args.repeats)))
              for t, c in codes.items()}
    result["python_pass_s"] = pass_s["this"]
    with tempfile.TemporaryDirectory() as tmp:
        per_code = {t: cases(args.backends, Path(tmp) / t) for t in codes}
        for label in per_code["this"]:
            if args.plots_only and label.endswith("--no-plots"):
                continue
            argvs = {t: per_code[t][label] for t in codes}
            timed = _timed(label, argvs, codes, args, pass_s)
            entry = timed["this"]
            line = (f"{label:22s} wall median {entry['wall_median_s']:6.2f} s (min {entry['wall_min_s']:.2f}, max "
                    f"{entry['wall_max_s']:.2f}), cpu {entry['cpu_median_s']:.2f} s, "
                    f"x{entry['ratio_to_python_pass']:.0f}"
                    f" python -c pass, load {entry['load_1min']:.1f}")
            if "baseline" in timed:
                base = timed["baseline"]
                entry["baseline"] = base
                entry["ratio_to_baseline"] = entry["wall_median_s"] / base["wall_median_s"]
                out_dir = {t: Path(argvs[t][argvs[t].index("--out") + 1]) for t in codes}
                diff = identical(out_dir["this"] / "signature.h5", out_dir["baseline"] / "signature.h5")
                entry["differs_from_baseline"] = diff
                pr = entry["paired_ratio"]
                line += (f"\n{'':22s} baseline median {base['wall_median_s']:6.2f} s "
                         f"(min {base['wall_min_s']:.2f}, max {base['wall_max_s']:.2f}), "
                         f"cpu {base['cpu_median_s']:.2f} s: ratio {entry['ratio_to_baseline']:.2f}"
                         f" (paired: median {pr['median']:.2f}, min {pr['min']:.2f}, max {pr['max']:.2f});"
                         f" signature.h5 {'bit-identical' if not diff else 'DIFFERS: ' + ', '.join(diff[:8])}")
            print(line, flush=True)
            if args.importtime:
                entry["imports_s"] = import_breakdown(argvs["this"], code=codes["this"])
                for name, s in entry["imports_s"]:
                    print(f"    import {name:40s} {s:6.3f} s")
            if args.split:
                runs = {t: [] for t in codes}
                for _ in range(args.repeats):
                    for t, c in codes.items():
                        runs[t].append(split_once(argvs[t], c))
                splits = {t: median_split(r) for t, r in runs.items()}
                entry["split_s"] = splits["this"]
                if "baseline" in splits:
                    entry["baseline"]["split_s"] = splits["baseline"]
                print(f"    {'stage (median s)':22s} {'work':>7s} {'import':>7s}"
                      + (f" | {'baseline work':>13s} {'import':>7s}" if "baseline" in splits else ""))
                for stage in dict.fromkeys([*splits.get("baseline", {}), *splits["this"]]):
                    w, i = splits["this"].get(stage, [0.0, 0.0])
                    row = f"    {stage:22s} {w:7.3f} {i:7.3f}"
                    if "baseline" in splits:
                        bw, bi = splits["baseline"].get(stage, [0.0, 0.0])
                        row += f" | {bw:13.3f} {bi:7.3f}"
                    print(row, flush=True)
            result["cases"][label] = entry
    result["load_after"] = os.getloadavg()
    print(f"python -c pass: {result['python_pass_s'] * 1e3:.0f} ms; "
          f"load average before {result['load_before'][0]:.1f}, "
          f"after {result['load_after'][0]:.1f} ({os.cpu_count()} CPUs)")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
