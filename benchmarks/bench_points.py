"""Benchmark (issues 2, 26): points backend, 5 s walk, two monostatic radars, 128 samples per chirp, all
signatures. Goals: < 0.25 s (issue 2), <= 0.1 s on 2 cores (issue 26: the exact synthesis runs its chunks on
one thread per core; set OMP_NUM_THREADS=1 to time one core). Run: python benchmarks/bench_points.py"""
import json

from rtchannel.analysis.chain_bench import bench_points

if __name__ == "__main__":
    print(json.dumps(bench_points(), indent=2))
