"""Benchmark: linear-blend skinning time per frame for each avatar LOD (positions, velocities) and
import time of a ~10 s motion-capture take. Run: python benchmarks/bench_skinning.py [path/to/take]"""
import json
import sys
import time
from pathlib import Path

import numpy as np

from rtchannel.body.avatar import LODS, load_avatar
from rtchannel.motion.augment import time_warp
from rtchannel.motion.load import load_motion
from rtchannel.body.skin_markers import skin_scatterer_trajectories
from rtchannel.body.skinning import skin_velocities, skin_vertices



def median_time(fn, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> dict:
    from rtchannel.data_registry import fetch  # third-party takes: mirror, cache or download

    take = Path(sys.argv[1]) if len(sys.argv) > 1 else fetch("mocap/cmu/walk/05_01_iclone.bvh")
    c3d = fetch("mocap/cmu/walk/82_08.c3d")
    out = {}
    load_motion(take)  # warm caches (avatar, soles) so the import time is the file's own
    t_import = median_time(lambda: load_motion(take), 3)
    motion = load_motion(take)
    out["import_bvh"] = {"file": take.name, "frames": motion.n_frames, "seconds_of_motion": round(motion.duration, 2),
                         "import_s": round(t_import, 3),
                         "import_s_per_10s": round(t_import * 10 / motion.duration, 3)}
    if c3d.exists():
        t_c3d = median_time(lambda: load_motion(c3d), 3)
        m3 = load_motion(c3d)
        out["import_c3d"] = {"file": c3d.name, "frames": m3.n_frames, "seconds_of_motion": round(m3.duration, 2),
                             "import_s": round(t_c3d, 3), "import_s_per_10s": round(t_c3d * 10 / m3.duration, 3)}
    ten_s = time_warp(motion, 10.0 / motion.duration)  # a 10 s take at the file's frame rate
    for lod in LODS:
        av = load_avatar(lod)
        n = ten_s.n_frames
        t_pos = median_time(lambda: skin_vertices(av, ten_s))
        t_vel = median_time(lambda: skin_velocities(av, ten_s))
        out[f"skin_{lod}"] = {"vertices": av.n_vertices, "triangles": av.n_faces, "frames": n,
                              "positions_ms_per_frame": round(1e3 * t_pos / n, 3),
                              "velocities_ms_per_frame": round(1e3 * t_vel / n, 3)}
    av = load_avatar("full")
    t_mk = median_time(lambda: skin_scatterer_trajectories(av, ten_s, velocities=True))
    out["skin_scatterers_21"] = {"ms_per_frame": round(1e3 * t_mk / ten_s.n_frames, 4)}
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
