"""Facet visibility for the `facets` backend: batched Mitsuba shadow rays on the shared scene.

Every test is an occlusion (any-hit) ray that stops just short of its target, so nothing but real
occluders (other body triangles, walls, furniture) can block it:

- direct: a facet facing the antenna is visible when the segment antenna -> centroid is free;
- via a wall: a facet facing the antenna's image, whose reflection point q lies on the wall polygon
  (`wall_images.reflection_points`), is visible when both q -> centroid and antenna -> q are free.

Image legs are only traced for facets the caller still needs (those visible directly from the other
end of some link), which halves the ray count. All rays of one phase go to Mitsuba in one call.

The scene is an `rtchannel.rt_scene.RTScene` (or anything with ``mi_scene`` or a ``cast`` method).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from rtchannel.backends.wall_images import incidence_cosine, mirror, reflection_points

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
    from rtchannel.llvm import import_mitsuba

    mi = import_mitsuba()
    o = np.ascontiguousarray(origins, np.float32)
    d = np.ascontiguousarray(directions, np.float32)
    ray = mi.Ray3f(mi.Point3f(mi.Float(o[:, 0]), mi.Float(o[:, 1]), mi.Float(o[:, 2])),
                   mi.Vector3f(mi.Float(d[:, 0]), mi.Float(d[:, 1]), mi.Float(d[:, 2])))
    ray.maxt = mi.Float(np.maximum(np.asarray(max_t, np.float64), 0.0).astype(np.float32))
    return np.array(mi_scene.ray_test(ray), dtype=bool)


class _Batch:
    """Collects segments to test, then answers them with one `occluded` call."""

    def __init__(self):
        self.o, self.d, self.t, self.sizes = [], [], [], []

    def add(self, start: np.ndarray, end: np.ndarray, stop: float) -> int:
        start = np.broadcast_to(start, end.shape)
        d = end - start
        dist = np.linalg.norm(d, axis=1)
        self.o.append(start)
        self.d.append(d / np.where(dist > 0, dist, 1.0)[:, None])
        self.t.append(dist - stop)
        self.sizes.append(len(end))
        return len(self.sizes) - 1

    def run(self, scene) -> list[np.ndarray]:
        """Per added block: bool [n], True where the segment is free."""
        if not self.sizes or sum(self.sizes) == 0:
            return [np.ones(s, bool) for s in self.sizes]
        t = np.concatenate(self.t)
        free = ~occluded(scene, np.concatenate(self.o), np.concatenate(self.d), t) & (t > 0)
        return np.split(free, np.cumsum(self.sizes)[:-1])


def direct_visibility(scene, centroids: np.ndarray, normals: np.ndarray, usable: np.ndarray,
                      sources: np.ndarray) -> list[np.ndarray]:
    """[F] bool per source: facet faces the source and the line of sight to its centroid is free."""
    batch, idxs = _Batch(), []
    for pos in sources:
        idx = np.flatnonzero(usable & (np.einsum("ij,ij->i", normals, pos - centroids) > 0))
        batch.add(pos, centroids[idx], _STOP)
        idxs.append(idx)
    out = []
    for idx, free in zip(idxs, batch.run(scene)):
        m = np.zeros(len(centroids), bool)
        m[idx[free]] = True
        out.append(m)
    return out


@dataclass
class WallVisibility:
    """Facets seen from one source through one wall.

    Attributes:
        image: the source's mirror image [3] (m).
        mask: [F] bool, facet visible through the wall.
        cos_w: [F] incidence cosine at the reflection point (0 where not visible).
    """

    image: np.ndarray
    mask: np.ndarray
    cos_w: np.ndarray


def image_visibility(scene, centroids: np.ndarray, normals: np.ndarray, needed: list[np.ndarray],
                     sources: np.ndarray, walls, keep=None) -> list[list[WallVisibility | None]]:
    """Per source and wall, the facets visible through the wall (None: the source is behind it).

    Args:
        needed: per source, [F] bool of facets worth testing (e.g. visible from the link's other end).
        keep: optional callable (source index, facet indices, image [3]) -> bool mask, a last filter
            before rays are cast (e.g. a gain bound).
    """
    batch, jobs = _Batch(), []
    out = [[None] * len(walls) for _ in sources]
    for s, pos in enumerate(sources):
        cand_all = np.flatnonzero(needed[s])
        if cand_all.size == 0:
            continue
        c = centroids[cand_all]
        for w, wall in enumerate(walls):
            front = np.flatnonzero(np.einsum("ij,ij->i", normals[cand_all], mirror(pos, wall) - c) > 0)
            image, q, valid = reflection_points(c[front], pos, wall)
            if keep is not None and valid.any():
                valid[valid] = keep(s, cand_all[front[valid]], image)
            sel = front[valid]
            if sel.size == 0:
                continue
            q = q[valid]
            nw = np.asarray(wall.normal, float)
            a = batch.add(q + _WALL_LIFT * nw, c[sel], _STOP)
            b = batch.add(pos, q, _LEG_STOP)
            cos_w = incidence_cosine(q, pos, wall)
            jobs.append((s, w, image, cand_all[sel], cos_w, a, b))
    free = batch.run(scene)
    f = len(centroids)
    for s, w, image, idx, cos_w, a, b in jobs:
        ok = free[a] & free[b]
        mask = np.zeros(f, bool)
        mask[idx[ok]] = True
        cw = np.zeros(f)
        cw[idx[ok]] = cos_w[ok]
        out[s][w] = WallVisibility(image, mask, cw)
    return out


class FrameBatchCaster:
    """Ray casts for many frames of a deforming body with one BVH build per `batch` frames.

    Each Mitsuba BVH update carries a per-call overhead on top of its per-triangle build cost (10-20 ms
    for a 10k-triangle body), so `batch` copies of the scene (the static geometry and the body at `batch` different frames) are laid out side
    by side on a grid of cells `cell` metres apart and built together; a ray for frame slot b is shifted
    into cell b. Cells are wider than everything (static geometry, body over the whole motion, antennas)
    plus a margin, so no ray leaves its cell before its max_t; coordinates stay within a few cells (float32
    resolution ~4e-6 m at 50 m, well under the 1e-4 m ray stops). Batching 16 frames cut the BVH time by
    ~40 % in benchmarks/bench_facets.py.

    Args:
        static: list of (vertices [V, 3], faces [T, 3]) of the static geometry.
        faces: body triangles [F, 3]; n_vertices: body vertex count.
        bounds: (lo [3], hi [3]) box (m) containing everything rays may travel through.
        batch: frames per BVH build.
    """

    def __init__(self, static, faces: np.ndarray, n_vertices: int, bounds, batch: int = 16):
        from rtchannel.llvm import import_mitsuba

        mi = self._mi = import_mitsuba()
        lo, hi = (np.asarray(b, float) for b in bounds)
        self.cell = float(np.max(hi - lo)) + 2.0
        side = int(np.ceil(np.sqrt(batch)))
        grid = np.array([(i % side, i // side) for i in range(batch)], float)
        self.offsets = np.column_stack([grid * self.cell, np.zeros(batch)]) - lo * [1, 1, 0]
        self.batch, self.n_vertices = batch, n_vertices
        f = np.asarray(faces, np.int64)
        body_faces = (f[None] + n_vertices * np.arange(batch)[:, None, None]).reshape(-1, 3)
        shapes = {"type": "scene", "body": self._mesh("body", np.zeros((batch * n_vertices, 3)), body_faces)}
        if static:
            sv = np.concatenate([v for v, _ in static])
            base = np.cumsum([0] + [len(v) for v, _ in static])[:-1]
            sf = np.concatenate([np.asarray(fc, np.int64) + b for (_, fc), b in zip(static, base)])
            allv = np.concatenate([sv + o for o in self.offsets])
            allf = np.concatenate([sf + len(sv) * i for i in range(batch)])
            shapes["static"] = self._mesh("static", allv, allf)
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
        v[len(frames):] = frames[-1]  # unused cells: any pose
        v += self.offsets[:, None, :]
        self._params["body.vertex_positions"] = self._mi.Float(np.ascontiguousarray(v, np.float32).ravel())
        self._params.update()

    def view(self, slot: int) -> "_CellView":
        """A scene-like object whose `occluded` casts in cell `slot`."""
        return _CellView(self, slot)


class _CellView:
    def __init__(self, caster: FrameBatchCaster, slot: int):
        self.caster, self.slot = caster, slot

    def occluded(self, origins, directions, max_t):
        c = self.caster
        return occluded(c, np.asarray(origins, float) + c.offsets[self.slot], directions, max_t)


_CASTERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def caster_for(scene, faces, vertices, sources, batch) -> FrameBatchCaster:
    """A `FrameBatchCaster` with the scene's static geometry, reused while the motion fits its cells."""
    static = [(v, f) for _, v, f in scene.static_meshes]
    if not static and getattr(scene, "walls", None):
        static = [(w.polygon, np.array([[0, i, i + 1] for i in range(1, len(w.polygon) - 1)])) for w in scene.walls]
    pts = [vertices.min(axis=(0, 1)), vertices.max(axis=(0, 1)), sources.min(axis=0), sources.max(axis=0)]
    pts += [v.min(axis=0) for v, _ in static] + [v.max(axis=0) for v, _ in static]
    lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
    cached = _CASTERS.get(scene)
    if (cached is not None and cached.batch == batch and cached.n_vertices == vertices.shape[1]
            and cached.n_faces == len(faces) and np.all(lo >= cached.lo) and np.all(hi <= cached.hi)):
        return cached
    lo, hi = lo - 2.0, hi + 2.0  # room for the next motion
    caster = FrameBatchCaster(static, faces, vertices.shape[1], (lo, hi), batch)
    caster.lo, caster.hi, caster.n_faces = lo, hi, len(faces)
    _CASTERS[scene] = caster
    return caster


def check_body_clearance(times, vertices, faces, sources, min_distance: float = 0.01):
    """Raise RadarPlacementError when an antenna is within `min_distance` (m) of, or inside, the body.

    Only frames whose nearest vertex is closer than 0.5 m get the exact point-triangle test; inside is
    judged by the outward normal of the closest triangle."""
    from rtchannel.meshgeom import closest_point_on_triangles
    from rtchannel.rt_scene import RadarPlacementError

    for p in sources:
        near = np.flatnonzero(np.einsum("kvi,kvi->kv", vertices - p, vertices - p).min(axis=1) < 0.25)
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
                    f"(minimum clearance {min_distance * 100:g} cm)")
