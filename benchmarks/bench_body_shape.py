"""Benchmark (issue 37): the cost of a body shape per motion, as a dataset worker pays it.

First use in a process (the targets asset, the full avatar, the LOD's place on the full mesh), then per
motion: a drawn `BodyShape` put onto a 5 s procedural walk with `reshape_motion` (calibration, shaped rig,
forward kinematics, the floor lift on the 2k mesh) and the shaped rest vertices of one LOD, each a new shape
(nothing cached). Medians over the shapes.

Run: .venv/bin/python benchmarks/bench_body_shape.py [--shapes 20] [--lod 5k]
"""
import argparse
import statistics
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shapes", type=int, default=20)
    ap.add_argument("--lod", default="5k")
    args = ap.parse_args()
    t0 = time.perf_counter()
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.shape import BodyShape, draw_body_shape, reshape_motion
    from rtchannel.body.shaped_avatar import shaped_vertices
    from rtchannel.motion.procedural import generate

    walk = generate("walk", duration=5.0, height=1.75, seed=0)
    t1 = time.perf_counter()
    first = reshape_motion(walk, BodyShape(bmi=23.0))
    shaped_vertices(args.lod, first.rig.shape, first.rig.height)
    load_avatar(args.lod)
    t2 = time.perf_counter()
    rng = np.random.default_rng(0)
    fit, total = [], []
    for _ in range(args.shapes):
        shape = draw_body_shape(rng)
        a = time.perf_counter()
        key = shape.key(walk.rig.height)
        b = time.perf_counter()
        m = reshape_motion(walk, shape)
        shaped_vertices(args.lod, m.rig.shape, m.rig.height)
        c = time.perf_counter()
        fit.append(b - a)
        total.append(c - a)
        assert m.rig.shape == key
    print(f"imports + a 5 s walk: {t1 - t0:.2f} s; first shape in the process (asset, LOD map): {t2 - t1:.2f} s")
    print(f"per new shape, median of {args.shapes}: calibration {statistics.median(fit) * 1e3:.0f} ms, "
          f"calibration + reshape_motion + {args.lod} vertices {statistics.median(total) * 1e3:.0f} ms "
          f"(max {max(total) * 1e3:.0f} ms)")


if __name__ == "__main__":
    main()
