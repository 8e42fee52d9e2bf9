"""Small triangle-mesh geometry helpers (closest surface points, ray casts) in plain numpy/scipy.

trimesh's proximity queries need the optional `rtree` package; these helpers avoid that dependency and
are vectorised for the mesh sizes used here (<= 27k triangles).
"""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree


def vertex_face_incidence(faces: np.ndarray, n_vertices: int) -> sparse.csr_matrix:
    """Sparse [V, T] matrix with a 1 where vertex v is a corner of triangle t."""
    t = np.repeat(np.arange(len(faces)), 3)
    return sparse.csr_matrix((np.ones(t.size), (faces.ravel(), t)), shape=(n_vertices, len(faces)))


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates [N, 3] of the points of triangles (a, b, c) closest to points p (all [N, 3]).

    Ericson, Real-Time Collision Detection, 5.1.5, vectorised; degenerate triangles fall back to the
    nearest corner-to-corner segment result through the same region tests.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    out = np.empty((len(p), 3))
    done = np.zeros(len(p), bool)
    tiny = 1e-300

    def put(mask, w):
        m = mask & ~done
        out[m] = w[m]
        done[m] = True

    zeros, ones = np.zeros(len(p)), np.ones(len(p))
    put((d1 <= 0) & (d2 <= 0), np.stack([ones, zeros, zeros], 1))
    put((d3 >= 0) & (d4 <= d3), np.stack([zeros, ones, zeros], 1))
    put((d6 >= 0) & (d5 <= d6), np.stack([zeros, zeros, ones], 1))
    v = d1 / np.where(np.abs(d1 - d3) > tiny, d1 - d3, tiny)
    put((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([1 - v, v, zeros], 1))
    w = d2 / np.where(np.abs(d2 - d6) > tiny, d2 - d6, tiny)
    put((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([1 - w, zeros, w], 1))
    den = (d4 - d3) + (d5 - d6)
    w = (d4 - d3) / np.where(np.abs(den) > tiny, den, tiny)
    put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), np.stack([zeros, 1 - w, w], 1))
    s = va + vb + vc
    s = np.where(np.abs(s) > tiny, s, tiny)
    put(np.ones(len(p), bool), np.stack([va / s, vb / s, vc / s], 1))
    out[~np.isfinite(out).all(1)] = (1.0, 0.0, 0.0)
    return out


def closest_points_on_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                           k: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closest surface points of a triangle mesh.

    Candidate triangles are those around the `k` nearest vertices of each query point: exact for
    points close to a well-shaped mesh (the use here: decimated vertices, markers), not a general
    far-field query.

    Args:
        points: query points [N, 3] (m).
        vertices, faces: the mesh ([V, 3] m, [T, 3]).
        k: nearest vertices whose incident triangles are searched.

    Returns:
        (face index [N], barycentric coordinates [N, 3], closest points [N, 3] m, distance [N] m).
    """
    points = np.atleast_2d(np.asarray(points, float))
    k = min(k, len(vertices))
    _, near = cKDTree(vertices).query(points, k=k)
    near = near.reshape(len(points), k)
    inc = vertex_face_incidence(faces, len(vertices)).tocsr()
    best_d = np.full(len(points), np.inf)
    best_f = np.zeros(len(points), int)
    best_b = np.zeros((len(points), 3))
    rows = inc[near.ravel()]
    q_idx = np.repeat(np.arange(len(points)), k)[rows.nonzero()[0]]
    f_idx = rows.nonzero()[1]
    tri = vertices[faces[f_idx]]
    bary = closest_point_on_triangles(points[q_idx], tri[:, 0], tri[:, 1], tri[:, 2])
    cp = np.einsum("ni,nij->nj", bary, tri)
    d = np.linalg.norm(cp - points[q_idx], axis=1)
    order = np.lexsort((d, q_idx))
    first = np.ones(order.size, bool)
    first[1:] = q_idx[order][1:] != q_idx[order][:-1]
    sel = order[first]
    best_d[q_idx[sel]] = d[sel]
    best_f[q_idx[sel]] = f_idx[sel]
    best_b[q_idx[sel]] = bary[sel]
    closest = np.einsum("ni,nij->nj", best_b, vertices[faces[best_f]])
    return best_f, best_b, closest, best_d


def ray_first_hit(origins: np.ndarray, directions: np.ndarray, vertices: np.ndarray,
                  faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First intersection of rays with a mesh (Moller-Trumbore against every triangle).

    Args:
        origins, directions: rays [N, 3] (directions need not be unit length).
        vertices, faces: the mesh.

    Returns:
        (face index [N] or -1 for a miss, barycentric coordinates [N, 3], ray parameter t [N]).
    """
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    e1, e2 = b - a, c - a
    hit_f = np.full(len(origins), -1)
    hit_b = np.zeros((len(origins), 3))
    hit_t = np.full(len(origins), np.inf)
    for i, (o, d) in enumerate(zip(np.asarray(origins, float), np.asarray(directions, float))):
        pv = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pv)
        ok = np.abs(det) > 1e-15
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = o - a
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        v = (qv @ d) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
        good = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        if good.any():
            j = np.flatnonzero(good)[np.argmin(t[good])]
            hit_f[i], hit_t[i] = j, t[j]
            hit_b[i] = (1 - u[j] - v[j], u[j], v[j])
    return hit_f, hit_b, hit_t


def is_closed(v: np.ndarray, f: np.ndarray) -> bool:
    """True if the triangles [T, 3] bound volumes (a closed mesh or a union of closed parts, e.g. boxes):
    with vertices welded by position (1e-6 m), every directed edge is used as often as its reverse."""
    _, weld = np.unique(np.round(v / 1e-6).astype(np.int64), axis=0, return_inverse=True)
    g = weld.ravel()[f]
    edges = np.concatenate([g[:, [0, 1]], g[:, [1, 2]], g[:, [2, 0]]])
    fwd, back = (np.unique(e, axis=0, return_counts=True) for e in (edges, edges[:, ::-1]))
    return len(fwd[0]) == len(back[0]) and all(np.array_equal(x, y) for x, y in zip(fwd, back))


def winding_numbers(points: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Generalised winding number [N] of closed triangle meshes around points [N, 3]: the sum of the signed
    solid angles of the triangles / 4 pi (Van Oosterom & Strackee 1983); the number of volumes containing
    the point (negative for inward winding), also for overlapping closed parts."""
    a, b, c = (v[f[:, i]][None] - points[:, None] for i in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = np.einsum("nti,nti->nt", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("nti,nti->nt", a, b) * lc + np.einsum("nti,nti->nt", a, c) * lb
           + np.einsum("nti,nti->nt", b, c) * la)
    return 2.0 * np.arctan2(det, den).sum(axis=1) / (4 * np.pi)
