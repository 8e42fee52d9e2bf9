"""Seconds per frame per radar of the `sionna` backend (medians), against the naive per-frame call.

Variants, all on the same skinned walk frames in the room with the seed's two monostatic radars:
- naive: Sionna's own ``PathSolver()(scene)`` once per radar per frame, with its Paths object read back
  (path count compacted every frame, so kernels recompile when it changes);
- per-radar: this backend's stage-wise solve (no compaction, padded candidates), one call per radar;
- joint: both radars in one call (the default);
- joint, diffuse only: ``specular=False`` (monostatically Sionna finds no body specular path).

    .venv/bin/python benchmarks/bench_sionna.py [--rays 1000000] [--frames 8] [--lod 10k] [--threads N]

Timings on a shared 2-core machine are noisy; medians over frames after a warm-up frame are reported.
Dr.Jit's on-disk kernel cache is redirected to a fresh temporary folder for the run.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--lod", default="10k")
    ap.add_argument("--threads", type=int, default=None, help="Dr.Jit worker threads (default: all cores)")
    args = ap.parse_args(argv)

    # Dr.Jit keeps compiled kernels in ~/.drjit across runs; a fresh cache per run keeps the naive
    # variant honest (a frame's path count is otherwise often compiled by an earlier run already).
    os.environ["HOME"] = tempfile.mkdtemp(prefix="bench_sionna_")
    from rtchannel.scene.llvm import import_mitsuba

    import_mitsuba()  # Dr.Jit's variant and libLLVM are set before drjit and sionna load
    import drjit as dr
    import sionna.rt as rt

    from rtchannel.body.avatar import load_avatar
    from rtchannel.backends.sionna_rt import place_antennas, trace_frames
    from rtchannel.motion.procedural import generate
    from rtchannel.radar import RadarConfig
    from rtchannel.scene.rt_scene import get_scene
    from rtchannel.body.skinning import skin_velocities, skin_vertices

    if args.threads:
        dr.set_thread_count(args.threads)
    m = generate("walk", start=(-1.5, 0.0), distance=3.0)
    idx = np.linspace(40, m.n_frames - 40, args.frames + 1).astype(int)  # +1 warm-up frame
    av = load_avatar(args.lod, m.rig.height)
    verts, vels = skin_vertices(av, m, idx), skin_velocities(av, m, idx)
    radar = RadarConfig()
    sc = get_scene("room", args.lod, m.rig.height, radar.waveform.carrier_hz)
    n_radars = len(radar.links)
    results = {}

    def naive(k):
        sc.set_body(verts[k])
        solver = rt.PathSolver()
        for link in radar.links:
            place_antennas(sc, [link], radar)
            p = solver(sc.sionna_scene, max_depth=1, samples_per_src=args.rays, max_num_paths_per_src=args.rays,
                       los=False, specular_reflection=True, diffuse_reflection=True, refraction=False)
            for arr in (p.a[0], p.a[1], p.tau, p.objects, p.primitives, p.vertices, p.interactions):
                np.asarray(arr)

    def ours(k, **kw):
        trace_frames(sc, radar, m.times[idx[k]:idx[k] + 1], verts[k:k + 1], vels[k:k + 1],
                     samples_per_src=args.rays, **kw)

    variants = {"naive (Sionna PathSolver per radar)": naive,
                "per-radar stage-wise, padded": lambda k: ours(k, joint_links=False),
                "joint (both radars, one call)": lambda k: ours(k),
                "joint, diffuse only": lambda k: ours(k, specular=False)}
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    for name, fn in variants.items():
        times, compiled = [], []
        for k in range(len(idx)):
            dr.kernel_history()
            t0 = time.perf_counter()
            fn(k)
            times.append(time.perf_counter() - t0)
            compiled.append(sum(1 for h in dr.kernel_history()
                                if h["type"] == dr.KernelType.JIT and not h.get("cache_hit", 1)))
        per = np.median(times[1:]) / n_radars
        results[name] = per
        print(f"{name:40s} {per:6.3f} s/frame/radar (median of {len(times) - 1}; "
              f"kernels compiled after warm-up: {sum(compiled[1:])})", flush=True)
    base = results["naive (Sionna PathSolver per radar)"]
    print(f"speed-up of the default (joint) over naive: {base / results['joint (both radars, one call)']:.2f}x "
          f"(threads: {dr.thread_count()}, rays/radar/frame: {args.rays:.0e}, LOD {args.lod})")


if __name__ == "__main__":
    main()
