"""Partial shadows of the static clutter: single knife-edge diffraction by the body (ITU-R P.526).

A segment antenna -> clutter patch that passes the body at distance h from its edge (h > 0: the edge covers
the line of sight, h < 0: clearance) at distances d1 from the antenna and d2 from the patch has the
diffraction parameter

    nu = h sqrt(2 (d1 + d2) / (lambda d1 d2)) = sqrt(2) h / r1,   r1 = sqrt(lambda d1 d2 / (d1 + d2))

(r1 the first Fresnel zone's radius there), and its field is scaled by 10^(-J(nu)/20) with ITU-R P.526-15
eq. (31): J(nu) = 6.9 + 20 log10(sqrt((nu - 0.1)^2 + 1) + nu - 0.1) for nu > -0.78, else 0. The loss goes
smoothly from 0 dB (clear by more than 0.55 r1) through 6.0 dB (grazing, nu = 0: half the field) to deep
shadow (about 20.5 dB at nu = 2.4).

The body is a mesh, not a half-plane: `shadow_nu` estimates h for each segment from the body's silhouette
vertices as seen from the antenna (vertices shared by a triangle facing it and one facing away: the edges
that bound the body in every plane across a segment from the antenna), in the plane across the segment, each
scaled by the Fresnel radius at its own distance along the segment (so a vertex near either end, where the
zone is thin, counts for less): a clear segment (the ray cast found no hit) takes the nearest one's
clearance; a blocked one the shortest way out of the body, the least, over `N_DIRECTIONS` directions across
the segment, of how far the silhouette vertices within a strip of half-width `STRIP` (in r1) along that
direction reach (the outer outline: an arm's own edge in front of the trunk does not end the shadow; no
outline vertex within reach along a direction counts as the cap). nu is capped at `NU_MAX`: deeper shadows take
J(NU_MAX) = 22.6 dB, far below anything the MTI leaves of the clutter (the binary shadow it replaced was -inf
dB there); the cap bounds the vertices a blocked segment must visit (its window grows with NU_MAX^2). Cost on
the 5 s bench walk (two radars, 2k shadow mesh): ~70k segments near the body, 0.26 s of CPU over both cores.
"""
from __future__ import annotations

import math

import numba
import numpy as np

NU_CLEAR = -0.78  # ITU-R P.526: no loss at or below this clearance
NU_MAX = 3.0  # deepest shadow evaluated (J = 22.6 dB); caps the vertices a blocked segment must look at
N_DIRECTIONS = 8  # directions across the segment in which a blocked line of sight may leave the body
STRIP = 0.5  # half-width [r1] of the strip of vertices that bounds the body along one direction


def itu_j_db(nu):
    """Knife-edge diffraction loss J(nu) [dB] (ITU-R P.526 eq. (31); 0 for nu <= -0.78)."""
    nu = np.asarray(nu, float)
    x = nu - 0.1
    j = 6.9 + 20.0 * np.log10(np.sqrt(x * x + 1.0) + x)
    return np.where(nu > NU_CLEAR, j, 0.0)


def knife_edge_amplitude(nu):
    """Field factor 10^(-J(nu)/20) of a knife edge at diffraction parameter nu (1 clear, 0.5 grazing)."""
    return 10.0 ** (-itu_j_db(nu) / 20.0)


def fresnel_nu(h, d1, d2, wavelength: float):
    """Diffraction parameter nu = h sqrt(2 (d1 + d2) / (lambda d1 d2)) of an edge h [m] above the line of sight
    at distances d1, d2 [m] from its ends (wavelength [m])."""
    return np.asarray(h, float) * np.sqrt(2.0 * (np.asarray(d1) + d2) / (wavelength * np.asarray(d1) * d2))


def box_margin_m(wavelength: float, max_length_m: float) -> float:
    """Distance [m] beyond which a body cannot shadow a segment of at most `max_length_m`: the clearance at
    nu = -0.78 with the widest Fresnel zone (mid-segment, r1 = sqrt(lambda L) / 2)."""
    return -NU_CLEAR / math.sqrt(2.0) * 0.5 * math.sqrt(wavelength * max(max_length_m, 0.0))


def segment_amplitudes(pos, targets, verts, frame, hit, wavelength: float, faces=None) -> np.ndarray:
    """Knife-edge field factors [N] of segments pos [3] -> targets [N, 3] (m) past the body vertices
    verts [B, V, 3] (m) of frame[N] (indices into B), given whether a ray cast found each blocked (hit [N]);
    faces [F, 3]: the body's triangles (its silhouette from `pos` is used), None: every vertex counts."""
    return knife_edge_amplitude(shadow_nu(pos, targets, verts, frame, hit, wavelength, faces))


def silhouette(pos, verts, faces) -> np.ndarray:
    """[B, V] vertices of verts [B, V, 3] on the silhouette seen from pos [3]: shared by a triangle of faces
    [F, 3] facing pos and one facing away."""
    v = np.asarray(verts, float)
    a, b, c = v[:, faces[:, 0]], v[:, faces[:, 1]], v[:, faces[:, 2]]
    front = np.einsum("bfi,bfi->bf", np.cross(b - a, c - a), np.asarray(pos, float) - a) > 0
    out = np.zeros(v.shape[:2], np.int8)
    for k in range(3):  # bit 1: a front face uses the vertex, bit 2: a back face does
        np.bitwise_or.at(out, (np.arange(len(v))[:, None], faces[:, k][None, :]), np.where(front, 1, 2).astype(np.int8))
    return out == 3


def shadow_nu(pos, targets, verts, frame, hit, wavelength: float, faces=None) -> np.ndarray:
    """Diffraction parameters nu [N] of segments pos [3] -> targets [N, 3] past verts[frame[i]] (module doc)."""
    pos = np.asarray(pos, float)
    verts = np.ascontiguousarray(verts, float)
    frame = np.ascontiguousarray(frame, np.int64)
    out = np.full(len(frame), NU_CLEAR - 1.0)
    if not len(frame):
        return out
    # per frame: the (silhouette) vertices sorted by azimuth about the body's mean bearing, so a segment visits
    # only the vertices within its angular window; the others sort to the end, past `count`
    d = verts - pos
    bearing = np.arctan2(d[..., 1].mean(axis=1), d[..., 0].mean(axis=1))
    az = np.angle(np.exp(1j * (np.arctan2(d[..., 1], d[..., 0]) - bearing[:, None])))
    if faces is not None:
        az = np.where(silhouette(pos, verts, np.asarray(faces, np.int64)), az, np.inf)
    order = np.argsort(az, axis=1)
    az_sorted = np.take_along_axis(az, order, axis=1)
    dist = np.linalg.norm(d, axis=-1)
    el_sorted = np.take_along_axis(np.arcsin(np.clip(d[..., 2] / np.maximum(dist, 1e-12), -1, 1)), order, axis=1)
    t = np.asarray(targets, float) - pos
    t_az = np.angle(np.exp(1j * (np.arctan2(t[:, 1], t[:, 0]) - bearing[frame])))
    t_el = np.arcsin(np.clip(t[:, 2] / np.linalg.norm(t, axis=1), -1, 1))
    # the vertices relative to pos in that order: a segment's window is read in sequence
    rel = np.ascontiguousarray(np.take_along_axis(d, order[..., None], axis=1))
    _nu_kernel(pos, np.ascontiguousarray(targets, float), rel, az_sorted, np.ascontiguousarray(el_sorted),
               dist.min(axis=1), frame, np.ascontiguousarray(hit, np.bool_), t_az, t_el, float(wavelength), out,
               max(1, min(len(frame), 64 * numba.get_num_threads())))
    return out


@numba.njit(cache=True, nogil=True, fastmath={"nnan", "ninf", "nsz"})
def _outline(xs, ys, m, cs, sn, r_cap):
    """min over the directions (cs[j], sn[j]) of how far the points (xs, ys)[:m] within a strip of half-width
    `STRIP` along each reach (a direction without one, or reaching past it: r_cap), capped at r_cap.

    One direction at a time over all points, branch-free, so the loop vectorises; the flags allow no
    reassociation or contraction, so every value is the same as evaluated point by point (no NaN or inf here).
    """
    h = r_cap
    for j in range(cs.shape[0]):
        c, s = cs[j], sn[j]
        top = -1.0
        for k in range(m):
            along = xs[k] * c + ys[k] * s
            inside = (along >= 0.0) & (abs(ys[k] * c - xs[k] * s) < STRIP)
            top = max(top, along if inside else -1.0)
        h = min(h, top if top >= 0.0 else r_cap)
    return h


@numba.njit(parallel=True, cache=True, nogil=True)
def _nu_kernel(pos, targets, rel, az_sorted, el_sorted, d_min, frame, hit, t_az, t_el, wavelength, out, n_chunks):
    n_dir = N_DIRECTIONS
    cs = np.empty(n_dir)
    sn = np.empty(n_dir)
    for j in range(n_dir):
        cs[j] = np.cos(2 * np.pi * j / n_dir)
        sn[j] = np.sin(2 * np.pi * j / n_dir)
    r_cap = NU_MAX / np.sqrt(2.0)
    r_clear = -NU_CLEAR / np.sqrt(2.0)
    n, n_v = frame.shape[0], rel.shape[1]
    for chunk in numba.prange(n_chunks):
        xs = np.empty(n_v)  # a blocked segment's outline vertices in its plane [r1], for `_outline`
        ys = np.empty(n_v)
        for i in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
            b = frame[i]
            ux, uy, uz = targets[i, 0] - pos[0], targets[i, 1] - pos[1], targets[i, 2] - pos[2]
            length = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux, uy, uz = ux / length, uy / length, uz / length
            # e1 horizontal across the segment, e2 = u x e1 (up-ish); z for a vertical segment
            hn = np.sqrt(ux * ux + uy * uy)
            if hn > 1e-9:
                e1x, e1y, e1z = -uy / hn, ux / hn, 0.0
            else:
                e1x, e1y, e1z = 1.0, 0.0, 0.0
            e2x, e2y, e2z = uy * e1z - uz * e1y, uz * e1x - ux * e1z, ux * e1y - uy * e1x
            blocked = hit[i]
            reach = r_cap if blocked else r_clear
            # angular window: a vertex at distance s along the segment matters within reach * r1(s) of it, and
            # r1(s) / s = sqrt(lambda (L - s) / (s L)) is largest at the nearest vertex
            s0 = min(max(d_min[b], 1e-3), length)
            # 10 %: sin < angle
            half_el = 1.1 * reach * np.sqrt(wavelength * max(length - s0, 0.0) / (s0 * length)) + 1e-6
            half = min(half_el / max(hn, 1e-3), np.pi)  # in azimuth: wider for steep segments
            lo = np.searchsorted(az_sorted[b], t_az[i] - half)
            hi = np.searchsorted(az_sorted[b], t_az[i] + half)
            best = 1e300  # clear: smallest normalised distance^2
            m = 0
            for q in range(lo, hi):
                if abs(el_sorted[b, q] - t_el[i]) > half_el:
                    continue
                dx, dy, dz = rel[b, q, 0], rel[b, q, 1], rel[b, q, 2]
                s = dx * ux + dy * uy + dz * uz
                if s <= 0.0 or s >= length:
                    continue
                r1 = np.sqrt(wavelength * s * (length - s) / length)
                wx, wy, wz = dx - s * ux, dy - s * uy, dz - s * uz
                x = (wx * e1x + wy * e1y + wz * e1z) / r1
                y = (wx * e2x + wy * e2y + wz * e2z) / r1
                if blocked:
                    xs[m] = x
                    ys[m] = y
                    m += 1
                else:
                    best = min(best, x * x + y * y)
            if blocked:
                # the reach of the body along each direction (no outline vertex along one within the window:
                # the body reaches past the cap there)
                out[i] = min(np.sqrt(2.0) * _outline(xs, ys, m, cs, sn, r_cap), NU_MAX)
            else:
                out[i] = -np.sqrt(2.0) * np.sqrt(best) if best < 1e300 else NU_CLEAR - 1.0


__all__ = ["itu_j_db", "knife_edge_amplitude", "fresnel_nu", "shadow_nu", "segment_amplitudes", "box_margin_m",
           "NU_MAX", "NU_CLEAR"]
