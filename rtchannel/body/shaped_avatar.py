"""The avatar in another body shape: its rest vertices at every level of detail and its rig.

A shaped rig carries its shape as ``Rig.shape``, a tuple of (name, value) pairs (`rtchannel.body.shape`
writes it); the ``mh_*`` entries are MakeHuman's macro values, which fix the mesh up to scale. The shaped
body is `body_targets.shaped_points` lifted so its soles are on the floor, its rig read off its helper cubes,
then both scaled uniformly to the rig's height, so a shaped rig scaled to another height (`Rig.scaled`) still
drives the same body, geometrically similar. Skinning weights stay: the topology is the base mesh's.

Levels of detail: each decimated vertex has its place on the full surface (closest point: triangle and
barycentric coordinates, computed once per process) and keeps its small offset from it (the decimation's
error, ~mm); a shaped LOD vertex is that barycentric blend of the shaped full mesh plus the offset, so every
LOD follows the same shape.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from processing.errors import InputError
from rtchannel.body.avatar import LODS, Avatar, load_avatar
from rtchannel.body.body_targets import N_SKIN, MacroValues, joints_from_points, shaped_points
from rtchannel.body.meshgeom import closest_points_on_mesh
from rtchannel.motion.pose import Rig, avatar_rig

MACRO_PREFIX = "mh_"  # names of the MakeHuman macro values in a rig's shape key


def macro_from_key(key: tuple) -> MacroValues:
    """MakeHuman's macro values recorded in a rig's shape key (InputError if it has none)."""
    values = {name[len(MACRO_PREFIX):]: v for name, v in key if name.startswith(MACRO_PREFIX)}
    if set(values) != set(MacroValues._fields):
        raise InputError(f"a body shape key must hold {', '.join(MACRO_PREFIX + f for f in MacroValues._fields)}")
    return MacroValues(**{f: float(values[f]) for f in MacroValues._fields})


def macro_key(m: MacroValues) -> tuple:
    """The ``mh_*`` pairs of a rig's shape key for macro values `m`."""
    return tuple((MACRO_PREFIX + f, float(v)) for f, v in m._asdict().items())


class _UnitBody:
    """A shaped body at its own size: skin [V, 3], bone heads and tails [J, 3] (m, soles on z = 0), stature."""

    def __init__(self, m: MacroValues):
        p = shaped_points(m)
        lift = np.array([0.0, 0.0, -p[:N_SKIN, 2].min()])
        self.skin = p[:N_SKIN] + lift
        heads, tails = joints_from_points(p)
        self.heads, self.tails = heads + lift, tails + lift
        self.stature = float(np.ptp(self.skin[:, 2]))


@lru_cache(maxsize=32)
def _unit_body(m: MacroValues) -> _UnitBody:
    return _UnitBody(m)


@lru_cache(maxsize=None)
def lod_on_full(lod: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each vertex of LOD `lod` sits on the full mesh: the full-mesh vertex indices of its closest
    triangle [n, 3], barycentric coordinates [n, 3] and its offset from that point [n, 3] (m, rest pose)."""
    full, av = load_avatar("full"), load_avatar(lod)
    face, bary, closest, _ = closest_points_on_mesh(av.vertices, full.vertices, full.faces)
    return full.faces[face], bary, av.vertices - closest


@lru_cache(maxsize=32)
def _unit_lod(lod: str, m: MacroValues) -> np.ndarray:
    skin = _unit_body(m).skin
    if lod == "full":
        return skin
    corners, bary, offset = lod_on_full(lod)
    return np.einsum("ni,nij->nj", bary, skin[corners]) + offset


def _check(lod: str) -> None:
    if lod not in LODS:
        raise InputError(f"unknown level of detail {lod!r}; choose one of {', '.join(LODS)}")


def shaped_rig(key: tuple, height: float) -> Rig:
    """The avatar rig in the body shape `key` (a rig shape key), scaled to `height` m; ``rig.shape = key``."""
    body = _unit_body(macro_from_key(key))
    base = avatar_rig(height)  # validates the height
    s = base.height / body.stature
    return replace(base, rest=body.heads * s, tails=body.tails * s, shape=tuple(key))


def shaped_vertices(lod: str, key: tuple, height: float) -> np.ndarray:
    """Rest vertices [V, 3] (m, project frame, soles on z = 0) of LOD `lod` in body shape `key` at `height` m."""
    _check(lod)
    m = macro_from_key(key)
    out = _unit_lod(lod, m) * (float(height) / _unit_body(m).stature)
    out.setflags(write=False)
    return out


def shaped_avatar(lod: str, rig: Rig) -> Avatar:
    """The avatar at LOD `lod` in `rig`'s body shape and height (the plain avatar if ``rig.shape`` is None)."""
    if rig.shape is None:
        return load_avatar(lod, rig.height)
    av = load_avatar(lod)
    return Avatar(shaped_vertices(lod, rig.shape, rig.height), av.faces, av.weights, rig, lod)


__all__ = ["MACRO_PREFIX", "macro_from_key", "macro_key", "lod_on_full", "shaped_rig", "shaped_vertices",
           "shaped_avatar"]
