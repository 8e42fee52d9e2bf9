"""The body-shape numbers quoted in docs/physics.md, measured again.

    python scripts/body_shape_checks.py

1. Skin area against Du Bois' BSA = 0.007184 W^0.425 H^0.725 over a 48-shape grid (sex, BMI 18/25/35, stature
   1.55/1.9 m, age 30/75, proportions 0/1): the ratio's range.
2. facets, free space, diffuse scattering only: the received power summed over the facet paths of a BMI-35 and
   a BMI-18 man of 1.75 m (8 walk frames, monostatic radars 3 m away at four azimuths), and their skin areas.
"""
import itertools
from dataclasses import replace

import numpy as np

from rtchannel.backends.facets import facet_paths
from rtchannel.body.avatar import load_avatar
from rtchannel.body.shape import BodyShape, reshape_motion
from rtchannel.body.shaped_avatar import shaped_vertices
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig

FACES = load_avatar("full").faces


def area(v: np.ndarray) -> float:
    t = v[FACES]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def main() -> None:
    ratios = []
    for sex, bmi, h, age, prop in itertools.product((0, 1), (18, 25, 35), (1.55, 1.9), (30, 75), (0.0, 1.0)):
        shape = BodyShape(sex=sex, bmi=bmi, age_years=age, proportions=prop)
        w = bmi * h * h
        ratios.append(area(shaped_vertices("full", shape.key(h), h)) / (0.007184 * w**0.425 * (100 * h) ** 0.725))
    print(f"skin area / Du Bois BSA over {len(ratios)} shapes: {min(ratios):.3f} .. {max(ratios):.3f}")

    m = generate("walk", duration=1.0, start=(-0.3, 0.0), height=1.75)
    m = replace(m, rotations=m.rotations[45:53], positions=m.positions[45:53])
    radar = RadarConfig(links=[Link(name=f"a{k}", tx=(3 * np.cos(a), 3 * np.sin(a), 1.1))
                               for k, a in enumerate(np.deg2rad([0, 90, 180, 270]))])
    power, areas = [], []
    for bmi in (35.0, 18.0):
        r = reshape_motion(m, BodyShape(sex="male", age_years=30, bmi=bmi))
        ps = facet_paths(r, radar, scene="free_space", lod="5k", walls=False, trace_fps=None, clutter=False,
                         po=False, min_relative_gain_db=None)
        power.append(np.mean([(np.abs(p.gains) ** 2).sum(axis=1).mean() for p in ps.values()]))
        areas.append(area(shaped_vertices("full", r.rig.shape, 1.75)))
    print(f"facets diffuse power, BMI 35 / BMI 18 man of 1.75 m: {power[0] / power[1]:.3f} "
          f"({10 * np.log10(power[0] / power[1]):+.2f} dB); skin areas {areas[0]:.3f} / {areas[1]:.3f} m^2 = "
          f"{areas[0] / areas[1]:.3f}")


if __name__ == "__main__":
    main()
