"""Per-part RCS shares of the facets body against the points backend's area law, at a carrier.

    python scripts/rcs_shares.py [--carrier-ghz 5.8] [--lod 10k]

A 3 s procedural walk (free space, no walls, isotropic antennas) seen by a monostatic radar 3 m ahead of and
3 m behind the walker at 1.0 m: each facet belongs to the bone with the largest skinning weight of its
corners; per frame the coherent RCS of the facets of each part group (trunk, shins, feet and toes) is
taken (`rtchannel.backends.rcs.frame_rcs`), averaged over frames and both views, and divided by the whole
body's. The share against the area law is that fraction over the group's Lund-Browder area fraction
(`rtchannel.body.scatterers`), printed in dB and as the amplitude scale a plan's gain set takes. The skin's
scattering coefficient is the carrier's (`rtchannel.scene.skin.scattering_coefficient`).
"""
import argparse

import numpy as np

from processing.pathset import PathSet
from processing.radar.antenna import Isotropic
from rtchannel.backends.facets import facet_paths
from rtchannel.backends.rcs import frame_rcs
from rtchannel.body.avatar import load_avatar
from rtchannel.body.scatterers import _TABLE
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig

GROUPS = {  # part group: (bones of the facets, scatterers of the area law)
    "trunk": (("Hips", "LowerBack", "Spine", "Spine1"), ("chest", "abdomen", "pelvis")),
    "shins": (("LeftLeg", "RightLeg"), ("left_shin", "right_shin")),
    "feet": (("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase"),
             ("left_foot", "right_foot", "left_toe", "right_toe")),
}


def shares(carrier_hz: float, lod: str = "10k") -> dict[str, float]:
    """{group: share [dB] of the group's coherent RCS fraction over its area fraction}."""
    motion = generate("walk", duration=3.0, speed=1.0, start=(-1.5, 0.0), pad_before=0.0, pad_after=0.0, seed=0)
    radar = RadarConfig(links=[Link(name="front", tx=(3.0, 0.0, 1.0)), Link(name="back", tx=(-3.0, 0.0, 1.0))],
                        antenna=Isotropic(), receiver=None)
    radar = radar.model_copy(update={"waveform": radar.waveform.model_copy(update={"carrier_hz": carrier_hz})})
    paths = facet_paths(motion, radar, scene="free_space", lod=lod, walls=False, trace_fps=None,
                        min_relative_gain_db=None)
    av = load_avatar(lod)
    w = av.dense_weights()
    bone_of_vertex = w.argmax(axis=1)
    face_bone = np.array([np.bincount(bone_of_vertex[f], minlength=w.shape[1]).argmax() for f in av.faces])
    names = av.rig.names
    area = {row[0]: row[4] for row in _TABLE}
    total_area = sum(area.values())
    out = {}
    totals = {k: frame_rcs(ps, carrier_hz)[0].mean() for k, ps in paths.items()}
    for group, (bones, scatterers) in GROUPS.items():
        mine = np.isin(face_bone, [names.index(b) for b in bones])
        frac = []
        for k, ps in paths.items():
            sel = mine[ps.ids % av.n_faces]
            sub = PathSet(times=ps.times, delays=ps.delays[:, sel], gains=ps.gains[:, sel], ids=ps.ids[sel])
            frac.append(frame_rcs(sub, carrier_hz)[0].mean() / totals[k])
        out[group] = 10 * np.log10(np.mean(frac) / (sum(area[s] for s in scatterers) / total_area))
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--carrier-ghz", type=float, default=5.8)
    ap.add_argument("--lod", default="10k")
    a = ap.parse_args()
    for g, db in shares(a.carrier_ghz * 1e9, a.lod).items():
        print(f"{g:6s} {db:+6.1f} dB  amplitude scale {10 ** (db / 20):.3f}")
