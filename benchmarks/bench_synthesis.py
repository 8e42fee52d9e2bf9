"""Benchmark (issue 12, item 1): synthesis + DSP of fixed path sets, full-IQ route against consumed-only.

Paths: the `facets` backend on the chain benchmark's 5 s walk (`rtchannel.analysis.chain_bench.exact_duration_walk`),
two monostatic seed radars, 10k body, room, default settings, made once by `rtchannel.pipeline.backend_paths`
(cached with --paths FILE); the `points` backend likewise. Timed: only `rtchannel.pipeline.process_paths`
(synthesis, receiver noise, DSP) with the default radar (receiver noise on), per route:
  full      keep_iq=True: IQ [chirps, samples] synthesised, `receive`d, DSP from the IQ;
  consumed  keep_iq=False: the DSP's projection synthesised directly (`processing.synthesis.projection`).
With --compare TREE the same measurements run on another source tree (e.g. the code before this change,
`git archive <commit> | tar -x -C /tmp/before`), in a worker process per tree, interleaved repeat by repeat
so that every tree sees the same machine state. Reports medians [s] of wall time (and of process CPU time)
and wall ns per path-chirp (present paths per frame x chirps, summed over links).
With --chain it also times the whole chain, `rtchannel.pipeline.simulate` of the facets walk (backend included;
as `rtchannel bench --chain facets`, which keeps the IQ, and with simulate's default, which does not).
Run: .venv/bin/python benchmarks/bench_synthesis.py [--repeats 5] [--compare DIR] [--paths FILE] [--chain]
The machine is shared: timings are noisy; medians over repeats are reported.
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROUTES = ("full", "consumed")


def make_paths(out: Path) -> None:
    """Facets and points path sets of the benchmark walk, pickled to `out`."""
    from rtchannel.analysis.chain_bench import exact_duration_walk
    from rtchannel.pipeline import backend_paths
    from rtchannel.radar import RadarConfig

    motion, radar = exact_duration_walk(5.0), RadarConfig()
    sets = {b: backend_paths(motion, radar, b) for b in ("facets", "points")}
    out.write_bytes(pickle.dumps(sets))


def worker(paths_file: Path) -> None:
    """Answer "backend route" lines on stdin with one JSON timing line each (after a warm-up run)."""
    import numpy as np

    from rtchannel.pipeline import process_paths
    from rtchannel.radar import RadarConfig

    sets = pickle.loads(paths_file.read_bytes())
    radar = RadarConfig()
    motion = None
    for line in sys.stdin:
        backend, route = line.split()
        if route not in ROUTES:
            raise ValueError(route)
        if backend == "chain":
            from rtchannel.analysis.chain_bench import exact_duration_walk
            from rtchannel.pipeline import simulate

            motion = exact_duration_walk(5.0) if motion is None else motion
            t0, c0 = time.perf_counter(), time.process_time()
            res = simulate(motion, radar, backend="facets", keep_iq=route == "full")
            print(json.dumps({"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0, **res.timing,
                              "path_chirps": float("nan")}), flush=True)
            continue
        paths = sets[backend]
        timing: dict = {}
        t0, c0 = time.perf_counter(), time.process_time()
        process_paths(paths, radar, keep_iq=route == "full", timing=timing)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        chirps = int(np.floor((paths[next(iter(paths))].times[-1] - paths[next(iter(paths))].times[0])
                              / radar.waveform.pri_s + 1e-9)) + 1
        path_chirps = sum(float((ps.gains != 0).sum(axis=1).mean()) * chirps for ps in paths.values())
        print(json.dumps({"wall": wall, "cpu": cpu, **timing, "path_chirps": path_chirps}), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--compare", type=Path, action="append", default=[], help="another source tree to time")
    ap.add_argument("--paths", type=Path, default=Path("/tmp/bench_synthesis_paths.pkl"),
                    help="path-set cache (made if missing)")
    ap.add_argument("--chain", action="store_true", help="also time simulate() of the facets walk end to end")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.paths)
        return
    here = Path(__file__).resolve().parents[1]
    if not args.paths.exists():
        make_paths(args.paths)
    trees = [here, *[p.resolve() for p in args.compare]]
    procs = {}
    for tree in trees:
        env = {**os.environ, "PYTHONPATH": str(tree)}
        procs[tree] = subprocess.Popen([sys.executable, __file__, "--worker", "--paths", str(args.paths)], cwd="/",
                                       env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    cases = [(b, r) for b in ("facets", "points") + (("chain",) if args.chain else ()) for r in ROUTES]
    runs = {(tree, b, r): [] for tree in trees for b, r in cases}

    def ask(tree, backend, route):
        p = procs[tree]
        p.stdin.write(f"{backend} {route}\n")
        p.stdin.flush()
        return json.loads(p.stdout.readline())

    for tree in trees:  # warm-up: imports, numba caches, FFT plans
        for b, r in cases:
            ask(tree, b, r)
    for _ in range(args.repeats):
        for b, r in cases:
            for tree in trees:
                runs[(tree, b, r)].append(ask(tree, b, r))
    for p in procs.values():
        p.stdin.close()
        p.wait()
    rows = []
    for tree in trees:
        for b, r in cases:
            rs = runs[(tree, b, r)]
            keys = ("wall", "cpu", "synthesis", "dsp") + (("backend",) if b == "chain" else ())
            med = {k: statistics.median(x[k] for x in rs) for k in keys}
            rows.append({"tree": str(tree), "backend": b, "route": r, "repeats": len(rs),
                         "median_s": {k: round(v, 4) for k, v in med.items()},
                         "wall_ns_per_path_chirp": (None if b == "chain"
                                                    else round(med["wall"] / rs[0]["path_chirps"] * 1e9, 2)),
                         "path_chirps": None if b == "chain" else rs[0]["path_chirps"]})
    print(json.dumps({"load_average_after": os.getloadavg(), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
