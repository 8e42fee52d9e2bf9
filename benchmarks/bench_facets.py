"""Benchmark (issue 3): `facets` backend only (no synthesis), 5 s walk, two monostatic seed radars, room with
walls, 10k-triangle body. Reports median wall time per stage and the path counts, for a few settings of the
speed knobs (trace_fps, walls, LOD, gain threshold). Goal: <= 1 s wall at the default setting (first row).

The walk is `rtchannel.analysis.chain_bench.exact_duration_walk(5.0)`: hips from x = -3 m to 1.3 m along y = 0 (the
same motion as the chain benchmark), 1.7 m short of Radar 1.
Run: .venv/bin/python benchmarks/bench_facets.py [--repeats 3] [--quick] [--cpu]
The machine is shared: timings are noisy; medians over repeats are reported. With --cpu every stage is timed
in process CPU time (all threads) instead of wall time, which other load disturbs far less; prefix
NUMBA_NUM_THREADS=1 for the dataset workers' serial kernels. Issue 26 (shared static clutter work, fused ray
set-up, twins and skinning compiled) took the default row's backend CPU time with serial kernels from 1.09-1.15 s to
0.69 s on a loaded 2-core machine (rays 0.32 -> 0.19, gains 0.35 -> 0.29, clutter 0.13-0.21 -> 0.05, skinning
0.10 -> 0.03 s).
"""
import argparse
import json
import statistics
import time

from rtchannel.backends.facets import facet_paths
from rtchannel.analysis.chain_bench import exact_duration_walk
from rtchannel.radar import RadarConfig
from rtchannel.scene.rt_scene import get_scene

FULL = {"trace_fps": None, "image_lod": None, "min_relative_gain_db": None}  # full accuracy
SETTINGS = [
    {"lod": "10k", "walls": True},  # the defaults: trace_fps 10, image_lod 2k, -50 dB
    {"lod": "10k", "walls": True, **FULL},
    {"lod": "10k", "walls": True, **FULL, "trace_fps": 10.0},
    {"lod": "10k", "walls": True, "trace_fps": 10.0, "image_lod": None},
    {"lod": "10k", "walls": True, "trace_fps": None},
    {"lod": "10k", "walls": True, "trace_fps": 20.0},
    {"lod": "10k", "walls": True, "trace_fps": 5.0},
    {"lod": "10k", "walls": False},
    {"lod": "5k", "walls": True},
    {"lod": "2k", "walls": True},
]


def run(setting: dict, repeats: int) -> dict:
    motion = exact_duration_walk(5.0)
    radar = RadarConfig()
    get_scene("room", setting["lod"], motion.rig.height, radar.waveform.carrier_hz)  # load once, not timed
    facet_paths(motion, radar, scene="room", **setting)  # warm-up: numba/Dr.Jit kernels
    runs = []
    for _ in range(repeats):
        timing = {}
        t0, c0 = time.perf_counter(), time.process_time()
        paths = facet_paths(motion, radar, scene="room", timing=timing, **setting)
        runs.append({"total": time.perf_counter() - t0, "cpu_total": time.process_time() - c0, **timing})
    med = {k: round(statistics.median(r[k] for r in runs), 4) for k in runs[0]}
    counts = {name: ps.n_paths for name, ps in paths.items()}
    present = {name: round(float((ps.gains != 0).sum(axis=1).mean()), 1) for name, ps in paths.items()}
    return {"setting": setting, "median_s": med, "paths": counts, "mean_present_per_frame": present,
            "frames": motion.n_frames, "simulated_s": motion.duration}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="only the default setting")
    ap.add_argument("--skip-full-rate", action="store_true", help="skip the slow full-accuracy setting")
    ap.add_argument("--cpu", action="store_true", help="time stages in process CPU time, not wall time")
    args = ap.parse_args()
    if args.cpu:  # the backend's stage clocks read time.perf_counter
        time.perf_counter = time.process_time
    reduced = [s for s in SETTINGS if s.get("image_lod", 1) is not None or s.get("trace_fps", 1) is not None]
    settings = SETTINGS[:1] if args.quick else reduced if args.skip_full_rate else SETTINGS
    for setting in settings:
        print(json.dumps(run(setting, args.repeats)), flush=True)


if __name__ == "__main__":
    main()
