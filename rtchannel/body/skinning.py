"""Linear blend skinning of the avatar by a `Motion`: vertex positions, velocities and safe face normals.

A vertex with rest position x and weights w_j moves to sum_j w_j A_j(t) [x; 1], where A_j are
`Motion.skinning_matrices()`. Because this is linear in A, a vertex velocity is the same blend of
dA_j/dt, so velocities come from differentiating the per-joint matrices once instead of every vertex.
dA/dt is the derivative of a cubic spline through the frames (``method="spline"``, the default: the
exact derivative of the smooth C2 interpolant of the pose sequence) or a second-order central
difference (``method="central"``, one-sided second order at both ends, via numpy.gradient). On smooth
motion both agree with a fine finite difference to well under 1 %; on 60 fps mocap the two differ by
~5 % RMS (frame-to-frame jitter of the capture, which the spline follows and the central difference
averages), so pick "central" to compare against frame-differenced positions.

The avatar is rescaled to the motion's rig height when they differ, so a motion generated for a
1.52 m rig drives a 1.52 m body whatever LOD or height the avatar was loaded with; a motion on a shaped rig
(`rtchannel.body.shape.reshape_motion`) drives the avatar in that shape (`rest_for_motion`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.interpolate import CubicSpline

from rtchannel.body.avatar import Avatar
from rtchannel.body.meshgeom import vertex_face_incidence
from rtchannel.body.shaped_avatar import shaped_vertices
from rtchannel.motion import pose
from rtchannel.motion.pose import Motion
from processing.errors import InputError

DEGENERATE_AREA_M2 = 1e-12  # below this a triangle's normal is not trusted (1 um^2)


@dataclass(frozen=True)
class SkinnedSequence:
    """Skinned body over a set of frames.

    Attributes:
        times: frame times [F] (s).
        vertices: vertex positions [F, V, 3] (m).
        velocities: vertex velocities [F, V, 3] (m/s), or None when not requested.
        faces: triangles [T, 3].
    """

    times: np.ndarray
    vertices: np.ndarray
    velocities: np.ndarray | None
    faces: np.ndarray


def rest_for_motion(avatar: Avatar, motion: Motion) -> np.ndarray:
    """The avatar's rest vertices [V, 3] (m) for the motion's rig: scaled to its height, and in its body shape
    when it has one (``motion.rig.shape``: the same LOD's vertices shaped, `rtchannel.body.shaped_avatar`)."""
    if motion.rig.shape is not None:
        return shaped_vertices(avatar.lod, motion.rig.shape, motion.rig.height)
    if abs(avatar.rig.height - motion.rig.height) < 1e-9:
        return avatar.vertices
    return avatar.vertices * (motion.rig.height / avatar.rig.height)


def _frames(motion: Motion, frames) -> np.ndarray:
    idx = np.arange(motion.n_frames) if frames is None else np.atleast_1d(np.asarray(frames))
    if idx.dtype.kind not in "iu" or (idx.size and (idx.min() < -motion.n_frames or idx.max() >= motion.n_frames)):
        raise IndexError(f"frames must be integer indices within 0..{motion.n_frames - 1}")
    return idx % motion.n_frames


def matrix_derivatives(motion: Motion, method: str = "spline") -> np.ndarray:
    """Time derivative of the skinning matrices, [F, J, 3, 4] (1/s, and m/s in the last column)."""
    a = motion.skinning_matrices()
    if method == "spline":
        return CubicSpline(motion.times, a, axis=0)(motion.times, 1)
    if method == "central":
        return np.gradient(a, 1.0 / motion.fps, axis=0, edge_order=2)
    raise InputError(f"unknown velocity method {method!r} (use 'spline' or 'central')")


def skin_vertices(avatar: Avatar, motion: Motion, frames=None) -> np.ndarray:
    """Skinned vertex positions [F, V, 3] (m) at the given frame indices (default: all frames)."""
    idx = _frames(motion, frames)
    mats = motion.skinning_matrices()[idx]
    return blend_points(avatar.weights, rest_for_motion(avatar, motion), mats)


def skin_velocities(avatar: Avatar, motion: Motion, frames=None, method: str = "spline") -> np.ndarray:
    """Vertex velocities [F, V, 3] (m/s) at the given frame indices (see the module doc for `method`)."""
    idx = _frames(motion, frames)
    dmats = matrix_derivatives(motion, method)[idx]
    return blend_points(avatar.weights, rest_for_motion(avatar, motion), dmats)


def skin(avatar: Avatar, motion: Motion, frames=None, velocities: bool = True,
         method: str = "spline") -> SkinnedSequence:
    """Skinned positions (and velocities) of every vertex at the given frames."""
    idx = _frames(motion, frames)
    vel = skin_velocities(avatar, motion, idx, method) if velocities else None
    return SkinnedSequence(motion.times[idx], skin_vertices(avatar, motion, idx), vel, avatar.faces)


def face_normals_and_areas(vertices: np.ndarray, faces: np.ndarray,
                           min_area: float = DEGENERATE_AREA_M2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit outward face normals, areas and degenerate flags, never NaN.

    A triangle whose area is below `min_area` (m^2) after skinning (collapsed or folded) gets the
    normalised, area-weighted normal of the faces around its corners instead of its own, and +z if that
    is zero too, so downstream shading never sees NaN; its area is reported as is (use the flag to drop
    it, its scattering area is ~0 anyway).

    Args:
        vertices: [..., V, 3] positions (m); leading axes (e.g. frames) are broadcast.
        faces: [T, 3] triangles.
        min_area: area threshold (m^2) for the degenerate flag.

    Returns:
        (normals [..., T, 3], areas [..., T] m^2, degenerate [..., T] bool).
    """
    v = np.asarray(vertices, float)
    a, b, c = (v[..., faces[:, i], :] for i in range(3))
    cr = np.cross(b - a, c - a)
    dbl = np.linalg.norm(cr, axis=-1)
    areas = 0.5 * dbl
    degenerate = ~(areas >= min_area)  # also catches NaN areas
    with np.errstate(invalid="ignore", divide="ignore"):
        normals = cr / np.where(dbl > 0, dbl, 1.0)[..., None]
    if degenerate.any():
        inc = vertex_face_incidence(faces, v.shape[-2])
        lead = v.shape[:-2]
        crf = np.nan_to_num(cr).reshape(-1, len(faces), 3)
        vn = np.stack([inc @ crf[k] for k in range(crf.shape[0])])  # area-weighted vertex normals
        fb = vn[:, faces].sum(axis=2).reshape(*lead, len(faces), 3)
        nb = np.linalg.norm(fb, axis=-1, keepdims=True)
        fallback = np.where(nb > 0, fb / np.where(nb > 0, nb, 1.0), np.array([0.0, 0.0, 1.0]))
        normals = np.where(degenerate[..., None], fallback, normals)
    return normals, areas, degenerate


def blend_points(weights, rest: np.ndarray, mats: np.ndarray) -> np.ndarray:
    """`rtchannel.motion.pose.blend_points` ([F, P, 3]: sum_j w_pj mats[f, j] [rest_p; 1] of weights [P, J],
    rest [P, 3] (m), mats [F, J, 3, 4]); for a mesh (`COMPILED_MIN_POINTS` points or more) in one compiled pass
    over frames and points, ~3x faster and without its [P, F, 12] temporaries: the same products in the same
    order as its sparse product and einsum (the blended matrix row summed over the joints in csr order, then
    (x a0 + z a2) + (y a1 + a3), the two-lane order of numpy's einsum here), so equal to it bit for bit on
    this platform and within a few ulp elsewhere (tests/test_facet_speed_kernels.py). Marker and joint sets
    keep the numpy route (the points backend runs without numba, and imports the pose, not this module)."""
    if len(rest) < COMPILED_MIN_POINTS:
        return pose.blend_points(weights, rest, mats)
    from scipy import sparse

    w = sparse.csr_matrix(weights)
    out = np.empty((mats.shape[0], rest.shape[0], 3))
    _blend(w.indptr.astype(np.int64), w.indices.astype(np.int64), w.data.astype(float),
           np.ascontiguousarray(rest, float), np.ascontiguousarray(mats, float), out)
    return out


COMPILED_MIN_POINTS = 500  # avatar meshes have 1k-10k vertices


@numba.njit(parallel=True, cache=True, nogil=True)
def _blend(indptr, indices, data, rest, mats, out):
    for f in numba.prange(mats.shape[0]):
        b = np.empty((3, 4))
        for p in range(rest.shape[0]):
            b[:] = 0.0
            for e in range(indptr[p], indptr[p + 1]):
                j, w = indices[e], data[e]
                for a in range(3):
                    for c in range(4):
                        b[a, c] += w * mats[f, j, a, c]
            x, y, z = rest[p, 0], rest[p, 1], rest[p, 2]
            for a in range(3):
                out[f, p, a] = (b[a, 0] * x + b[a, 2] * z) + (b[a, 1] * y + b[a, 3])


def face_frames(v, faces):
    """(normals [B, F, 3], areas [B, F], degenerate [B, F], centroids [B, F, 3]) of the triangles `faces`
    [F, 3] of frames v [B, V, 3] in one pass: `face_normals_and_areas` (its cross product, norm and
    threshold in the same order, equal bit for bit; the neighbours' normal of degenerate triangles from it)
    and the centroids ((a + b) + c) / 3."""
    n_b, n_f = v.shape[0], len(faces)
    normals, cent = np.empty((n_b, n_f, 3)), np.empty((n_b, n_f, 3))
    areas, degenerate = np.empty((n_b, n_f)), np.empty((n_b, n_f), np.bool_)
    _face_frames(np.ascontiguousarray(v, float), np.ascontiguousarray(faces, np.int64), DEGENERATE_AREA_M2,
                 normals, areas, degenerate, cent)
    if degenerate.any():
        normals = face_normals_and_areas(v, faces)[0]
    return normals, areas, degenerate, cent


@numba.njit(parallel=True, cache=True, nogil=True)
def _face_frames(v, faces, min_area, normals, areas, degenerate, cent):
    for b in numba.prange(v.shape[0]):
        for f in range(faces.shape[0]):
            p, q, r = v[b, faces[f, 0]], v[b, faces[f, 1]], v[b, faces[f, 2]]
            u0, u1, u2 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
            w0, w1, w2 = r[0] - p[0], r[1] - p[1], r[2] - p[2]
            c0, c1, c2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
            dbl = np.sqrt((c0 * c0 + c1 * c1) + c2 * c2)
            areas[b, f] = 0.5 * dbl
            degenerate[b, f] = not (0.5 * dbl >= min_area)
            den = dbl if dbl > 0 else 1.0
            normals[b, f, 0], normals[b, f, 1], normals[b, f, 2] = c0 / den, c1 / den, c2 / den
            for i in range(3):
                cent[b, f, i] = ((p[i] + q[i]) + r[i]) / 3
