"""Facet visibility for the `facets` backend: batched Embree shadow rays on the shared scene's geometry.

Every test is an occlusion (any-hit) ray that stops just short of its target, so nothing but real
occluders (other body triangles, walls, furniture) can block it:

- direct: a facet facing the antenna is visible when the segment antenna -> centroid is free;
- via a wall: a facet facing the antenna's image, whose reflection point q lies on the wall polygon
  (`wall_images.reflection_points`), is visible when both q -> centroid and antenna -> q are free.

Image legs are only traced for facets the caller still needs (those visible directly from the other
end of some link), which halves the ray count; through walls with double-bounce paths (both
antennas mirrored) every facet facing the image is traced, as such a path needs no direct line of
sight. The rays of every traced frame of a BVH batch (see `FrameBatchCaster`) go to the ray caster in
two calls: all direct rays, then all image legs; casting is cheap (~1e7 rays/s per core), so the
Python/numpy work around it is kept vectorised over frames and facets. The caster is Mitsuba's Embree,
called directly (`rtchannel.backends.embree`), or Mitsuba itself where that library is not callable; both
give the same answers (tests/test_facet_speed.py).

The scene is an `rtchannel.scene.rt_scene.RTScene` (or anything with ``mi_scene`` or a ``cast`` method).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numba
import numpy as np

from rtchannel.backends.wall_images import mirror

_STOP = 1e-4  # m: rays stop this short of their target triangle, so it never counts as its own occluder
_WALL_LIFT = 1e-4  # m: rays leaving a wall start this far into the room, not on the plane
_LEG_STOP = 1e-3  # m: antenna -> wall rays stop this short of the wall


def occluded(scene, origins: np.ndarray, directions: np.ndarray, max_t: np.ndarray) -> np.ndarray:
    """Any-hit test of rays [N, 3] (unit directions) up to max_t [N] (m) against the whole scene."""
    n = len(origins)
    if n == 0:
        return np.zeros(0, bool)
    if hasattr(scene, "occluded"):
        return scene.occluded(origins, directions, max_t)
    mi_scene = getattr(scene, "mi_scene", None)
    if mi_scene is None:
        mi_scene = getattr(scene, "scene", None)
    if mi_scene is None:
        return scene.cast(origins, directions, max_t)["hit"]
    from rtchannel.scene.llvm import import_mitsuba

    mi = import_mitsuba()
    o = np.asarray(origins, np.float32).T.copy()
    d = np.asarray(directions, np.float32).T.copy()
    ray = mi.Ray3f(mi.Point3f(mi.Float(o[0]), mi.Float(o[1]), mi.Float(o[2])),
                   mi.Vector3f(mi.Float(d[0]), mi.Float(d[1]), mi.Float(d[2])))
    ray.maxt = mi.Float(np.maximum(np.asarray(max_t, np.float32), 0.0))
    return np.array(mi_scene.ray_test(ray), dtype=bool)


def _segments_free(caster, cell, start, end, stop):
    """Free [N] of segments start -> end [N, 3] (m) in the given cells, stopping `stop` (m, scalar or [N])
    short."""
    if hasattr(caster, "free_segments"):
        return caster.free_segments(cell, start, end, stop)
    d = end - start
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    d /= np.where(dist > 0, dist, 1.0)[:, None]
    t = dist - stop
    return ~caster.occluded_cells(start, d, t, cell) & (t > 0)


@numba.njit(cache=True, nogil=True)
def _facing(normals, centroids, usable, sources):
    """(flat index into [S, B, F], s, b, f) of the usable facets facing each source: n . (p - c) > 0, summed
    in numpy einsum's order."""
    n_b, n_f = usable.shape
    size = sources.shape[0] * n_b * n_f
    at, ss = np.empty(size, np.int64), np.empty(size, np.int64)
    bs, fs = np.empty(size, np.int64), np.empty(size, np.int64)
    n = 0
    for s in range(sources.shape[0]):
        p = sources[s]
        for b in range(n_b):
            for f in range(n_f):
                if usable[b, f]:
                    nn, c = normals[b, f], centroids[b, f]
                    if (nn[0] * (p[0] - c[0]) + nn[2] * (p[2] - c[2])) + nn[1] * (p[1] - c[1]) > 0:
                        at[n], ss[n], bs[n], fs[n] = (s * n_b + b) * n_f + f, s, b, f
                        n += 1
    return at[:n], ss[:n], bs[:n], fs[:n]


@numba.njit(cache=True, nogil=True)
def _wall_hits(centroids, normals, need, h_c, h_src, image, poly, edge_n):
    """(b [N], f [N], q [N, 3]) of the needed facets with h_c > 0 facing `image` whose reflection point q
    (on centroid -> image at h_c / (h_c + h_src)) is inside the convex polygon (`in_convex_polygon`'s edge
    test with edge normals edge_n [K, 3], either winding): numpy's formulas and summation order, fused."""
    n_b, n_f = need.shape
    bs, fs, qs = np.empty(n_b * n_f, np.int64), np.empty(n_b * n_f, np.int64), np.empty((n_b * n_f, 3))
    n = 0
    tol = 1e-9
    for b in range(n_b):
        for f in range(n_f):
            h = h_c[b, f]
            if not (need[b, f] and h > 0):
                continue
            c, nn = centroids[b, f], normals[b, f]
            d0, d1, d2 = image[0] - c[0], image[1] - c[1], image[2] - c[2]
            if not (nn[0] * d0 + nn[2] * d2) + nn[1] * d1 > 0:
                continue
            frac = h / (h + h_src)
            q0, q1, q2 = c[0] + frac * d0, c[1] + frac * d1, c[2] + frac * d2
            above, below = True, True
            for k in range(poly.shape[0]):
                e = edge_n[k]
                sk = (e[0] * (q0 - poly[k, 0]) + e[2] * (q2 - poly[k, 2])) + e[1] * (q1 - poly[k, 1])
                above &= sk >= -tol
                below &= sk <= tol
            if above or below:
                bs[n], fs[n] = b, f
                qs[n, 0], qs[n, 1], qs[n, 2] = q0, q1, q2
                n += 1
    return bs[:n], fs[:n], qs[:n]


@dataclass
class BatchVisibility:
    """Visibility of the facets of the B frames of one BVH batch.

    Attributes:
        direct: [S, B, F] bool, facet faces source s and its line of sight is free.
        images: {(s, w): (b [N], f [N], cos_w [N])}, facets seen from source s through wall w, with the
            incidence cosine at the reflection point.
    """

    direct: np.ndarray
    images: dict


def batch_visibility(caster, centroids, normals, usable, sources, walls, pairs, every_facet=()) -> BatchVisibility:
    """Visibility of facets (centroids, normals [B, F, 3], usable [B, F]) of the frames loaded in
    `caster`'s cells 0..B-1 from `sources` [S, 3] (m), directly and through `walls`.

    pairs: (tx source, rx source) of each link; image legs are traced only for facets visible directly
    from the other end of some link, except through the walls indexed in `every_facet` (double-bounce
    paths need a facet seen through two images, whether or not an antenna sees it directly)."""
    n_b, n_f = usable.shape
    direct = np.zeros((len(sources), n_b, n_f), bool)
    if hasattr(caster, "free_direct"):  # facing test and rays in compiled passes, no [N, 3] copies
        sources = np.ascontiguousarray(sources, float)
        at, s_idx, b, f = _facing(np.ascontiguousarray(normals, float), np.ascontiguousarray(centroids, float),
                                  np.ascontiguousarray(usable), sources)
        direct.ravel()[at[caster.free_direct(sources, s_idx, centroids, b, f, _STOP)]] = True
    else:
        parts = []
        for s, pos in enumerate(sources):
            b, f = np.nonzero(usable & (np.einsum("bfi,bfi->bf", normals, pos - centroids) > 0))
            parts.append((s, b, f))
        cell = np.concatenate([b for _, b, _ in parts])
        end = np.concatenate([centroids[b, f] for _, b, f in parts])
        start = np.repeat(sources, [b.size for _, b, _ in parts], axis=0)
        free = np.split(_segments_free(caster, cell, start, end, _STOP),
                        np.cumsum([b.size for _, b, _ in parts])[:-1])
        for (s, b, f), ok in zip(parts, free):
            direct[s, b[ok], f[ok]] = True
    images: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    if not walls:
        return BatchVisibility(direct, images)
    needed = np.zeros_like(direct)
    for s_tx, s_rx in pairs:
        needed[s_tx] |= direct[s_rx]
        needed[s_rx] |= direct[s_tx]
    jobs, starts, ends, stops, cells, heights = [], [], [], [], [], {}
    for s, pos in enumerate(sources):
        for w, wall in enumerate(walls):
            nw = np.asarray(wall.normal, float)
            h_src = float((pos - wall.point) @ nw)
            if not h_src > 0:
                continue
            image = mirror(pos, wall)
            if w not in heights:  # the centroids' heights above the wall, shared by every source
                heights[w] = (centroids - wall.point) @ nw
            h_c = heights[w]
            need = usable if w in every_facet else needed[s]
            # facets above the wall, facing the image, whose reflection point lies on the wall polygon
            poly = np.asarray(wall.polygon, float)
            b, f, q = _wall_hits(np.ascontiguousarray(centroids, float), np.ascontiguousarray(normals, float),
                                 np.ascontiguousarray(need), np.ascontiguousarray(h_c, float), h_src, image, poly,
                                 np.cross(np.roll(poly, -1, axis=0) - poly, nw))
            c = centroids[b, f]
            if b.size == 0:
                continue
            leg = q - pos
            cos_w = np.abs(leg @ nw) / np.maximum(np.sqrt(np.einsum("ij,ij->i", leg, leg)), 1e-300)
            jobs.append((s, w, b, f, cos_w))
            starts += [q + _WALL_LIFT * nw, np.broadcast_to(pos, q.shape)]
            ends += [c, q]
            stops += [np.full(b.size, _STOP), np.full(b.size, _LEG_STOP)]
            cells += [b, b]
    if jobs:
        free = _segments_free(caster, np.concatenate(cells), np.concatenate(starts), np.concatenate(ends),
                              np.concatenate(stops))
        at = 0
        for s, w, b, f, cos_w in jobs:
            n = b.size
            ok = free[at:at + n] & free[at + n:at + 2 * n]
            at += 2 * n
            images[(s, w)] = (b[ok], f[ok], cos_w[ok])
    return BatchVisibility(direct, images)


class FrameBatchCaster:
    """Ray casts for many frames of a deforming body with one BVH build per `batch` frames.

    Each BVH update carries a per-call overhead on top of its per-triangle build cost (Mitsuba's: 10-20 ms for a
    10k-triangle body), so `batch` copies of the scene (the static geometry and the body at `batch` different
    frames) are laid out side by side on a grid of cells `cell` metres apart and built together; a ray for frame
    slot b is shifted into cell b. Cells are wider than everything (static geometry, body over the whole motion,
    antennas) plus a margin, so no ray leaves its cell before its max_t; coordinates stay within a few cells
    (float32 resolution ~4e-6 m at 50 m, well under the 1e-4 m ray stops). Batching 16 frames cut the BVH time
    by ~40 % in benchmarks/bench_facets.py.

    Args:
        static: list of (vertices [V, 3], faces [T, 3]) of the static geometry.
        faces: body triangles [F, 3]; n_vertices: body vertex count.
        bounds: (lo [3], hi [3]) box (m) containing everything rays may travel through.
        batch: frames per BVH build.
        embree: cast through Embree directly (`rtchannel.backends.embree`; same library as Mitsuba's, ~3x
            cheaper BVH updates) when it is available; False: through Mitsuba.
    """

    lo: np.ndarray  # the box [3] (m) `caster_for` checks a motion against, set by it
    hi: np.ndarray

    def __init__(self, static, faces: np.ndarray, n_vertices: int, bounds, batch: int = 16, embree: bool = True):
        from rtchannel.backends import embree as _embree
        from rtchannel.scene.llvm import import_mitsuba

        mi = self._mi = import_mitsuba()
        lo, hi = (np.asarray(b, float) for b in bounds)
        self.cell = float(np.max(hi - lo)) + 2.0
        side = int(np.ceil(np.sqrt(batch)))
        grid = np.array([(i % side, i // side) for i in range(batch)], float)
        self.offsets = np.column_stack([grid * self.cell, np.zeros(batch)]) - lo * [1, 1, 0]
        self.batch, self.n_vertices = batch, n_vertices
        f = np.asarray(faces, np.int64)
        body_faces = (f[None] + n_vertices * np.arange(batch)[:, None, None]).reshape(-1, 3)
        cells = None
        if static:
            sv = np.concatenate([v for v, _ in static])
            base = np.cumsum([0] + [len(v) for v, _ in static])[:-1]
            sf = np.concatenate([np.asarray(fc, np.int64) + b for (_, fc), b in zip(static, base)])
            cells = (np.concatenate([sv + o for o in self.offsets]),
                     np.concatenate([sf + len(sv) * i for i in range(batch)]))
        if embree and _embree.available():  # the same Embree, without Mitsuba's per-update overhead
            self._embree: _embree.EmbreeScene | None = _embree.EmbreeScene(cells, body_faces, batch * n_vertices)
            return
        self._embree = None
        shapes = {"type": "scene", "body": self._mesh("body", np.zeros((batch * n_vertices, 3)), body_faces)}
        if cells is not None:
            shapes["static"] = self._mesh("static", *cells)
        self.scene = mi.load_dict(shapes)
        self._params = mi.traverse(self.scene)

    def _mesh(self, name, v, f):
        mi = self._mi
        mesh = mi.Mesh(name, len(v), len(f), has_vertex_normals=False)
        p = mi.traverse(mesh)
        p["vertex_positions"] = mi.Float(np.ascontiguousarray(v, np.float32).ravel())
        p["faces"] = mi.UInt32(np.ascontiguousarray(f, np.uint32).ravel())
        p.update()
        return mesh

    def load(self, frames: np.ndarray) -> None:
        """Place up to `batch` body poses [B, V, 3] (m) in the cells (one BVH build)."""
        v = np.empty((self.batch, self.n_vertices, 3))
        v[:len(frames)] = frames
        # Unused cells of a last, partial batch: Embree skips triangles with non-finite corners, so they cost
        # no build time; Mitsuba's route gets any pose instead.
        v[len(frames):] = np.nan if self._embree is not None else frames[-1]
        v += self.offsets[:, None, :]
        if self._embree is not None:
            self._embree.set_body(v.reshape(-1, 3))
            return
        self._params["body.vertex_positions"] = self._mi.Float(np.ascontiguousarray(v, np.float32).ravel())
        self._params.update()

    def clear(self) -> None:
        """Leave only the static geometry in every cell: the body's triangles are dropped (Embree skips
        non-finite corners) or, through Mitsuba, collapsed onto one point (zero area, never hit)."""
        if self._embree is not None:
            self._embree.set_body(np.full((self.batch * self.n_vertices, 3), np.nan))
            return
        v = np.broadcast_to(self.offsets[:1] - 1.0, (self.batch * self.n_vertices, 3))
        self._params["body.vertex_positions"] = self._mi.Float(np.ascontiguousarray(v, np.float32).ravel())
        self._params.update()

    def free_segments(self, cells, start, end, stop) -> np.ndarray:
        """Free [N] of segments start -> end [N, 3] (m) in cells [N], stopping `stop` (m, scalar or [N]) short
        (`_segments_free`): through Embree, rays are laid out in one compiled pass."""
        if self._embree is None:
            return _segments_free(_NumpyRoute(self), cells, start, end, stop)
        from rtchannel.backends.embree import pack_rays

        n = len(end)
        rays, valid = np.empty((n, 12), np.float32), np.empty(n, bool)  # `embree.new_rays`' layout, all written
        pack_rays(np.ascontiguousarray(start, float), np.zeros(0, np.int64), np.ascontiguousarray(end, float),
                  np.atleast_1d(np.asarray(stop, float)), np.asarray(cells, np.int64), self.offsets, rays,
                  rays.view(np.uint32), valid)
        return ~self._embree.occluded_rays(rays) & valid

    def free_direct(self, sources, s_idx, centroids, b, f, stop: float) -> np.ndarray:
        """`free_segments` of sources[s_idx] -> centroids[b, f] ([B, F, 3]) in cells b, read in place."""
        if self._embree is None:
            return _segments_free(_NumpyRoute(self), b, sources[s_idx], centroids[b, f], stop)
        from rtchannel.backends.embree import pack_direct

        n = len(b)
        rays, valid = np.empty((n, 12), np.float32), np.empty(n, bool)
        pack_direct(sources, np.asarray(s_idx, np.int64), np.ascontiguousarray(centroids, float),
                    np.asarray(b, np.int64), np.asarray(f, np.int64), float(stop), self.offsets, rays,
                    rays.view(np.uint32), valid)
        return ~self._embree.occluded_rays(rays) & valid

    def occluded_cells(self, origins, directions, max_t, cells) -> np.ndarray:
        """Any-hit test of rays [N, 3] (unit directions, up to max_t [N] m) in cells [N] (frame slots)."""
        origins = np.asarray(origins, float) + self.offsets[cells]
        if self._embree is not None:
            return self._embree.occluded(origins, directions, max_t)
        return occluded(self, origins, directions, max_t)


class _NumpyRoute:
    """A caster seen without `free_segments` (the Mitsuba route takes the numpy ray set-up)."""

    def __init__(self, caster):
        self.occluded_cells = caster.occluded_cells


_CASTERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def caster_for(scene, faces, vertices, sources, batch, purpose: str = "paths") -> FrameBatchCaster:
    """A `FrameBatchCaster` with the scene's static geometry, reused while the motion fits its cells; one per
    body mesh and `purpose`, so that work running side by side (the clutter's shadows and the wall images on
    the same coarse mesh) never shares a caster."""
    static = [(v, f) for _, v, f in scene.static_meshes]
    if not static and getattr(scene, "walls", None):
        static = [(w.polygon, np.array([[0, i, i + 1] for i in range(1, len(w.polygon) - 1)])) for w in scene.walls]
    # per coordinate: a reduction over one strided axis is ~10x faster than over axes (0, 1) of [K, V, 3]
    pts = [[vertices[..., i].min() for i in range(3)], [vertices[..., i].max() for i in range(3)],
           sources.min(axis=0), sources.max(axis=0)]
    pts += [v.min(axis=0) for v, _ in static] + [v.max(axis=0) for v, _ in static]
    lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
    mine = _CASTERS.setdefault(scene, {})  # one per body mesh (the direct and the image LOD)
    key = (batch, vertices.shape[1], len(faces), purpose)
    cached = mine.get(key)
    if cached is not None and np.all(lo >= cached.lo) and np.all(hi <= cached.hi):
        return cached
    lo, hi = lo - 2.0, hi + 2.0  # room for the next motion
    caster = FrameBatchCaster(static, faces, vertices.shape[1], (lo, hi), batch)
    caster.lo, caster.hi = lo, hi
    mine[key] = caster
    return caster


def check_body_clearance(times, vertices, faces, sources, min_distance: float = 0.01):
    """Raise RadarPlacementError when an antenna is within `min_distance` (m) of, or inside, the body.

    Only frames whose nearest vertex is closer than 0.5 m get the exact point-triangle test; inside is
    judged by the outward normal of the closest triangle."""
    from rtchannel.body.meshgeom import closest_point_on_triangles
    from rtchannel.errors import MOVE_THE_PERSON, RadarPlacementError

    for p in sources:
        near = np.flatnonzero(_nearest_d2(np.ascontiguousarray(vertices, float), np.asarray(p, float)) < 0.25)
        for k in near:
            a, b, c = (vertices[k][faces[:, i]] for i in range(3))
            bary = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)
            q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
            d = np.linalg.norm(q - p, axis=1)
            j = int(np.argmin(d))
            inside = float(np.dot(p - q[j], np.cross(b[j] - a[j], c[j] - a[j]))) < 0
            if d[j] < min_distance or inside:
                where = "inside" if inside else f"{d[j] * 100:.2f} cm from"
                raise RadarPlacementError(
                    f"antenna at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is {where} the body at t = {times[k]:.2f} s "
                    f"(minimum clearance {min_distance * 100:g} cm){MOVE_THE_PERSON}")


@numba.njit(cache=True, nogil=True)
def _nearest_d2(vertices, p):
    """Squared distance [K] (m^2) from p [3] to the nearest vertex of each frame of vertices [K, V, 3], in
    one pass (no [K, V] temporaries; the test only picks frames to check)."""
    out = np.empty(vertices.shape[0])
    for k in range(vertices.shape[0]):  # serial: ~1 ms, less than waking threads
        best = np.inf
        for v in range(vertices.shape[1]):
            d2 = ((vertices[k, v, 0] - p[0]) ** 2 + (vertices[k, v, 1] - p[1]) ** 2) + (vertices[k, v, 2] - p[2]) ** 2
            best = min(best, d2)
        out[k] = best
    return out
