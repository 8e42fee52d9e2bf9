"""One motion from many directions: separate `simulate` calls against `simulate_radars` (backend once).

    .venv/bin/python benchmarks/bench_directions.py [--backend facets] [--directions 18] [--repeats 3]

Prints medians [s] of both and their ratio, per direction and in total (5 s walk, the seed's two radars
per direction, default facets settings, signature-only route as datasets run it).
"""
from __future__ import annotations

import argparse
import json
import statistics
import time

from rtchannel.analysis.chain_bench import exact_duration_walk
from rtchannel.pipeline import simulate, simulate_radars
from rtchannel.radar import RadarConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="facets")
    ap.add_argument("--directions", type=int, default=18)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--duration", type=float, default=5.0)
    args = ap.parse_args()
    motion = exact_duration_walk(args.duration)
    radars = [RadarConfig.seed(direction=d) for d in range(1, args.directions + 1)]
    simulate(motion, radars[0], args.backend)  # warm-up: scene, kernels
    sep, shared = [], []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        for r in radars:
            simulate(motion, r, args.backend)
        sep.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        simulate_radars(motion, radars, args.backend)
        shared.append(time.perf_counter() - t0)
    a, b = statistics.median(sep), statistics.median(shared)
    print(json.dumps({"backend": args.backend, "directions": args.directions, "simulated_s": args.duration,
                      "separate_s": round(a, 3), "shared_s": round(b, 3),
                      "separate_per_direction_s": round(a / len(radars), 3),
                      "shared_per_direction_s": round(b / len(radars), 3), "speed_up": round(a / b, 2)}, indent=1))


if __name__ == "__main__":
    main()
