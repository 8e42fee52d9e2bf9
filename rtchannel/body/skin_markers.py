"""The seed's 21 point scatterers as fixed points on the avatar's skin (triangle + barycentric).

`rtchannel.body.scatterers` places each scatterer on a bone, inside the body. Here each one is moved out to
the skin once, in the rest pose of the full mesh: a ray from the bone point along a per-part
direction (front for head, neck, trunk and legs; outward for shoulders and arms; up for feet) meets
the surface, and that surface point is kept as (triangle, barycentric coordinates), so it moves with
the skinned surface. Other levels of detail use the closest point of their own surface to it.
A skin point's skinning weights are the barycentric blend of its triangle's vertex weights; LBS is
linear in the weights, so skinning that point equals interpolating the skinned triangle.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import sparse

from rtchannel.body.avatar import Avatar, load_avatar
from rtchannel.body.meshgeom import closest_points_on_mesh, ray_first_hit
from rtchannel.body.scatterers import SCATTERER_NAMES, seed_scatterers
from rtchannel.motion.pose import Motion
from rtchannel.body.skinning import blend_points, matrix_derivatives, rest_for_motion

_FRONT, _UP = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
_MAX_RAY_M = 0.25
_DIRECTIONS = {"head": _FRONT, "neck": _FRONT, "chest": _FRONT, "abdomen": _FRONT, "pelvis": _FRONT}
for _side, _y in (("left", 1.0), ("right", -1.0)):
    _DIRECTIONS.update({
        f"{_side}_shoulder": (0.0, _y, 1.0), f"{_side}_upper_arm": (0.0, _y, 0.0),
        f"{_side}_forearm": (0.0, _y, 0.0), f"{_side}_hand": (0.0, _y, 0.0),
        f"{_side}_thigh": _FRONT, f"{_side}_shin": _FRONT, f"{_side}_foot": _UP, f"{_side}_toe": _UP})


@dataclass(frozen=True)
class SkinMarkers:
    """Scatterers attached to an avatar's surface.

    Attributes:
        names: scatterer names [M] (`rtchannel.body.scatterers.SCATTERER_NAMES` order).
        faces: triangle index per scatterer [M] (into the avatar's faces).
        bary: barycentric coordinates [M, 3].
        gains: default amplitude gains [M] (as in `seed_scatterers`).
        lod: the avatar LOD these refer to.
    """

    names: tuple[str, ...]
    faces: np.ndarray
    bary: np.ndarray
    gains: np.ndarray
    lod: str

    def rest_points(self, avatar: Avatar) -> np.ndarray:
        """Rest-pose positions [M, 3] (m) on `avatar` (same LOD, any height)."""
        return np.einsum("mi,mij->mj", self.bary, avatar.vertices[avatar.faces[self.faces]])

    def weights(self, avatar: Avatar) -> sparse.csr_matrix:
        """Skinning weights [M, J] of the marker points (blend of their triangles' vertex weights)."""
        corners = avatar.faces[self.faces]
        w = sparse.csr_matrix((len(self.faces), avatar.weights.shape[1]))
        for c in range(3):
            w = w + sparse.diags(self.bary[:, c]) @ avatar.weights[corners[:, c]]
        return w.tocsr()


@lru_cache(maxsize=1)
def _full_surface_points() -> np.ndarray:
    """Rest skin points [21, 3] (m) on the full mesh at its native height."""
    av = load_avatar("full")
    sc = seed_scatterers(av.rig)
    dirs = np.array([_DIRECTIONS[n] for n in sc.names], float)
    face, bary, t = ray_first_hit(sc.rest_points, dirs / np.linalg.norm(dirs, axis=1, keepdims=True),
                                  av.vertices, av.faces)
    near_f, _, near_p, _ = closest_points_on_mesh(sc.rest_points, av.vertices, av.faces, k=16)
    tri = av.vertices[av.faces[near_f]]
    outward = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inside = np.einsum("ij,ij->i", sc.rest_points - near_p, outward) < 0
    # Some bone points lie outside the skin (the foot bone runs above the instep), where the ray would
    # hit another part (the shin): those, and rays that travel implausibly far, take the nearest skin.
    hit = (face >= 0) & inside & (t < _MAX_RAY_M)
    out = near_p.copy()
    out[hit] = np.einsum("mi,mij->mj", bary[hit], av.vertices[av.faces[face[hit]]])
    return out


@lru_cache(maxsize=None)
def _markers_for_lod(lod: str) -> SkinMarkers:
    av = load_avatar(lod)
    face, bary, _, _ = closest_points_on_mesh(_full_surface_points(), av.vertices, av.faces, k=16)
    return SkinMarkers(SCATTERER_NAMES, face, bary, seed_scatterers(av.rig).gains, lod)


def skin_markers(avatar: Avatar) -> SkinMarkers:
    """The 21 scatterers as surface points of `avatar` (its LOD; valid at any height)."""
    return _markers_for_lod(avatar.lod)


def skin_scatterer_trajectories(avatar: Avatar, motion: Motion, velocities: bool = False, method: str = "spline"):
    """Positions [F, 21, 3] (m) of the skin scatterers over the motion, and velocities [F, 21, 3] (m/s)
    when `velocities` (derivative as in `rtchannel.body.skinning`).

    Returns positions, or (positions, velocities).
    """
    mk = skin_markers(avatar)
    if motion.rig.shape is None:
        rest = mk.rest_points(avatar) * (motion.rig.height / avatar.height)
    else:  # the same surface points on the shaped skin
        rest = np.einsum("mi,mij->mj", mk.bary, rest_for_motion(avatar, motion)[avatar.faces[mk.faces]])
    w = mk.weights(avatar)
    pos = blend_points(w, rest, motion.skinning_matrices())
    if not velocities:
        return pos
    return pos, blend_points(w, rest, matrix_derivatives(motion, method))


__all__ = ["SkinMarkers", "skin_markers", "skin_scatterer_trajectories"]
