"""`rtchannel bench`: speed of the simulation chain (medians over repeats, split per stage)."""
from __future__ import annotations

import json
import statistics
import time
from pathlib import Path


def bench_points(repeats: int = 7, duration: float = 5.0) -> dict:
    """Median wall time [s] of the points backend on a `duration`-s walk, two monostatic seed radars,
    128 samples per chirp, raw IQ plus all signatures; with the split backend / synthesis / DSP."""
    from rtchannel.motion.procedural import generate
    from rtchannel.radar import RadarConfig
    from rtchannel.simulate import simulate

    from dataclasses import replace

    radar = RadarConfig()
    full = generate("walk", duration=duration, pad_before=0.0, pad_after=0.0)
    n = int(round(duration * full.fps)) + 1  # exactly `duration` seconds (the walk adds stop ramps)
    motion = replace(full, positions=full.positions[:n], rotations=full.rotations[:n])
    simulate(motion, radar)  # warm-up: imports, FFT plans, caches
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = simulate(motion, radar, keep_iq=True)
        runs.append({"total": time.perf_counter() - t0, **res.timing})
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    sim_s = motion.duration
    return {"benchmark": "points", "simulated_s": sim_s, "repeats": repeats, "median_s": med,
            "speed_x_real_time": sim_s / med["total"], "links": len(radar.links),
            "samples_per_chirp": radar.waveform.samples_per_chirp}


def cmd_bench(args) -> int:
    result = bench_points(repeats=args.repeats, duration=args.duration)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


def add_bench(sub) -> None:
    p = sub.add_parser("bench", help="time the simulation chain (medians, per-stage split)",
                       description="Time the points backend on a procedural walk with the seed's two "
                       "monostatic radars: raw IQ plus all signatures; prints medians as JSON.")
    p.add_argument("--repeats", type=int, default=7, help="timed repeats (default 7)")
    p.add_argument("--duration", type=float, default=5.0, help="simulated activity length [s] (default 5)")
    p.add_argument("--out", type=Path, help="also write the JSON here")
    p.set_defaults(func=cmd_bench)
