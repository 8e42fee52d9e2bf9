"""Benchmark (issue 2): points backend, 5 s walk, two monostatic radars, 128 samples per chirp, raw IQ plus
all signatures. Goal: < 0.25 s (20x faster than real time). Run: python benchmarks/bench_points.py"""
import json

from rtchannel.analysis.chain_bench import bench_points

if __name__ == "__main__":
    print(json.dumps(bench_points(), indent=2))
