"""Cost of the antenna patterns in the `sionna` backend: the seed kit's horns against isotropic antennas.

Same process, same scene and frames, the two radars alternated over rounds (the machine is shared, so the
medians of rounds 2.. are compared; the first round compiles the kernels):

    .venv/bin/python benchmarks/bench_sionna_antennas.py [--rays 200000] [--rounds 6] [--duration 0.5]
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--duration", type=float, default=0.5, help="walk length [s], traced at 10 fps")
    args = ap.parse_args(argv)

    from processing.radar.antenna import Isotropic
    from rtchannel.analysis.chain_bench import exact_duration_walk
    from rtchannel.backends.sionna_rt import trace_frames
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_velocities, skin_vertices
    from rtchannel.radar import RadarConfig
    from rtchannel.scene.rt_scene import get_scene

    m = exact_duration_walk(args.duration).resampled(10)
    av = load_avatar("2k", m.rig.height)
    verts, vels = skin_vertices(av, m), skin_velocities(av, m)
    sc = get_scene("room", "2k", m.rig.height, 24.125e9)
    radars = {"isotropic": RadarConfig(antenna=Isotropic()), "seed horns": RadarConfig()}
    times: dict[str, list[float]] = {k: [] for k in radars}
    for _ in range(args.rounds):
        for name, radar in radars.items():
            t0 = time.perf_counter()
            trace_frames(sc, radar, m.times, verts, vels, samples_per_src=args.rays)
            times[name].append(time.perf_counter() - t0)
    for name, t in times.items():
        print(f"{name:12s} {np.median(t[1:]):.3f} s for {len(m.times)} frames x {len(radars[name].links)} radars "
              f"(median of rounds 2..{args.rounds}; all: {np.round(t, 3).tolist()})")


if __name__ == "__main__":
    main()
