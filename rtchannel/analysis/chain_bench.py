"""Timing of the whole simulation chain of one backend on a standard walk (`rtchannel bench --chain`)."""
from __future__ import annotations

import statistics
import time
from dataclasses import replace


def exact_duration_walk(duration: float, fps: float = 60.0):
    """A procedural walk toward Radar 1 cut to exactly `duration` seconds (the generator adds start/stop
    ramps): at 1 m/s from (-3, 0) m, so a 5 s walk stays 1 m clear of the radar and the room's walls."""
    from rtchannel.motion.procedural import generate

    full = generate("walk", duration=duration, speed=1.0, start=(-3.0, 0.0), pad_before=0.0, pad_after=0.0,
                    fps=fps)
    n = int(round(duration * full.fps)) + 1
    return replace(full, positions=full.positions[:n], rotations=full.rotations[:n])


def bench_chain(backend: str = "points", repeats: int = 7, duration: float = 5.0, keep_iq: bool = False,
                **options) -> dict:
    """Median wall time [s] of one backend on a `duration`-s walk, two monostatic seed radars,
    128 samples per chirp, all signatures; with the split backend / synthesis / DSP. `keep_iq=False` times
    the default route (only what the DSP consumes is synthesised), `True` the full raw-IQ route."""
    from rtchannel.radar import RadarConfig
    from rtchannel.pipeline import simulate

    radar = RadarConfig()
    motion = exact_duration_walk(duration)
    simulate(motion, radar, backend=backend, **options)  # warm-up: imports, scene, kernels, FFT plans
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = simulate(motion, radar, backend=backend, keep_iq=keep_iq, **options)
        runs.append({"total": time.perf_counter() - t0, **res.timing})
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    return {"benchmark": backend, "options": options, "keep_iq": keep_iq, "simulated_s": motion.duration,
            "repeats": repeats,
            "median_s": med, "speed_x_real_time": motion.duration / med["total"], "links": len(radar.links),
            "samples_per_chirp": radar.waveform.samples_per_chirp}


def bench_points(repeats: int = 7, duration: float = 5.0) -> dict:
    """`bench_chain` of the points backend (kept for the benchmarks/ script)."""
    return bench_chain("points", repeats, duration)
