"""The ray-tracing scene shared by the `sionna` and `facets` backends.

One Mitsuba/Sionna RT scene per (scene file, body mesh, frequency, skin material): the static geometry
of a scene file (``scenes/room.xml``, ``scenes/free_space.xml`` or a user's Mitsuba 3 XML with
furniture) plus the body mesh as its own shape, id ``"body"``. The body is moved each frame by writing
its vertex positions in place (``mi_scene_params["body.vertex_positions"]`` + ``update()``, which
refits the BVH in ~10 ms for 10k triangles): the scene is never rebuilt, so Dr.Jit's compiled kernels
stay valid and the static geometry is loaded and analysed once.

Also here: the planar static faces (walls, floor, furniture tops) for image-method multipath, batched
ray casts (for visibility tests), and the antenna clearance check (Sionna RT gives garbage for an
antenna closer than ~1 cm to geometry).

The body's material (dry skin at the carrier) is `rtchannel.scene.skin`; walls, floor and furniture carry
their slab (permittivity, conductivity, thickness from the scene file) and an rms roughness
(`roughness_m`, default `material.WALL_ROUGHNESS_M`), one `material.SurfaceMaterial` per static shape.
"""
from __future__ import annotations

import re
import tempfile
import xml.etree.ElementTree as ET
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

from processing.constants import EPSILON_0_F_M as epsilon_0
from rtchannel.errors import RadarPlacementError, SceneFileError
from rtchannel.assets import scenes_dir
from rtchannel.scene.sandbox import load_error_line, load_scene_string, read_scene_xml
from rtchannel.body.meshgeom import closest_point_on_triangles, is_closed, winding_numbers
from rtchannel.scene.material import WALL_ROUGHNESS_M, SurfaceMaterial
from rtchannel.scene.skin import _SKIN_MATERIAL_ID, SkinMaterial, skin_xml
from processing.errors import InputError

SCENES: dict[str, Path] = {"room": scenes_dir() / "room.xml", "free_space": scenes_dir() / "free_space.xml"}
BODY_ID = "body"
MIN_WALL_AREA_M2 = 0.25  # planar faces smaller than this are left to the ray tracer (no image sources)
_PLANE_TOL_M = 1e-3


@dataclass(frozen=True, eq=False)
class Wall:
    """A planar static face, for image-method multipath.

    Attributes:
        name: scene object the face belongs to (with a suffix when one object has several planes).
        point: a point of the plane [3] (m): the polygon's centroid.
        normal: unit normal [3] pointing into the room (towards the side the antennas can be on).
        polygon: corners [K, 3] (m) of the face, in order (convex hull of the coplanar triangles).
        relative_permittivity: complex eps_r' - j sigma / (omega eps0) at the scene frequency.
        thickness: slab thickness [m] of the material (Sionna's thin-slab model).
        area: polygon area [m^2].
        roughness_m: rms height [m] of the surface: its specular reflections (the body's image paths) are
            scaled by the Kirchhoff factor and its clutter scatters S^2 = 1 - factor^2 diffusely
            (`rtchannel.scene.material`); 0 is a smooth wall.
    """

    name: str
    point: np.ndarray
    normal: np.ndarray
    polygon: np.ndarray
    relative_permittivity: complex
    thickness: float = 0.0
    area: float = 0.0
    roughness_m: float = WALL_ROUGHNESS_M

    @property
    def material(self) -> SurfaceMaterial:
        """The wall's `SurfaceMaterial` (Lambertian diffuse part, Kirchhoff roughness)."""
        eta = None if self.relative_permittivity is None else complex(self.relative_permittivity)
        return SurfaceMaterial(eta=eta, thickness=self.thickness or None, roughness_m=float(self.roughness_m))


def resolve_scene(scene) -> Path:
    """Path of a scene: a name in `SCENES`, a Mitsuba XML file or a `rtchannel.scene.spec.Scene`;
    raises ValueError if missing."""
    if hasattr(scene, "xml_path"):
        return scene.xml_path()
    from rtchannel.scene.rooms import is_room_name, room_xml_path

    if is_room_name(scene):
        return room_xml_path(scene)
    path = SCENES.get(str(scene), Path(scene))
    if not path.is_file():
        raise InputError(f"scene '{scene}' is neither one of {', '.join(SCENES)} nor an existing XML file")
    return path.resolve()


def _mi():
    from rtchannel.scene.llvm import import_mitsuba

    return import_mitsuba()


def _to_np(x) -> np.ndarray:
    return np.array(x, copy=True)


def _vec3(mi, a: np.ndarray, kind):
    a = np.ascontiguousarray(a, dtype=np.float32)
    return kind(mi.Float(a[:, 0]), mi.Float(a[:, 1]), mi.Float(a[:, 2]))


class RTScene:
    """Static scene + deformable body for Sionna RT and Mitsuba ray casts.

    Args:
        scene: "room", "free_space" or the path of a Mitsuba 3 XML file whose shapes all have radio
            materials (e.g. ``itu-radio-material``); its shape ids must not be "body".
        body_faces: triangles [T, 3] of the body (or any target mesh).
        body_vertices: initial vertex positions [V, 3] (m).
        frequency_hz: carrier frequency [Hz]; ITU materials are evaluated at it.
        skin: radio material of the body; default dry skin (Gabriel 1996) at `frequency_hz`.
        sionna: load through Sionna RT (`sionna_scene`, for its path solver); False loads with Mitsuba alone
            when the scene allows it (`rtchannel.scene.mitsuba_scene`: 0.4-0.6 s less start-up, same geometry,
            ids and walls; `sionna_scene` is then None), as the facets backend does.
        roughness_m: rms height [m] of the static shapes' surfaces: one number for all, or {shape name: m}
            (shapes not named keep `WALL_ROUGHNESS_M`); None: `WALL_ROUGHNESS_M` everywhere.

    Attributes:
        sionna_scene: the ``sionna.rt.Scene`` (the body is ``sionna_scene.objects["body"]``), or None when
            loaded with Mitsuba alone.
        mi_scene: the underlying ``mitsuba.Scene``.
        walls: planar static faces of at least `MIN_WALL_AREA_M2`.
        body_object_id: the body's Sionna object id (``Paths.objects`` value of body interactions).
        object_names: {Sionna object id: object name} of every shape.
    """

    def __init__(self, scene: str | Path, body_faces: np.ndarray, body_vertices: np.ndarray,
                 frequency_hz: float, skin: SkinMaterial | None = None, sionna: bool = True,
                 roughness_m: float | dict | None = None):
        mi = _mi()
        import drjit as dr

        self.path = resolve_scene(scene)
        self.frequency_hz = float(frequency_hz)
        self.skin = SkinMaterial.at(frequency_hz) if skin is None else skin
        self.body_faces = np.asarray(body_faces, dtype=np.int64)
        self._roughness = roughness_m
        verts = np.asarray(body_vertices, dtype=np.float64)
        if verts.ndim != 2 or verts.shape[1] != 3 or self.body_faces.ndim != 2 or self.body_faces.shape[1] != 3:
            raise InputError("body_vertices must be [V, 3] and body_faces [T, 3]")
        xml = read_scene_xml(self.path)  # sandbox: only files under the allowed roots, one-line errors
        if re.search(r'id\s*=\s*"(mesh-)?body"', xml):
            raise InputError(f"{self.path}: shape id 'body' is reserved for the avatar")
        end = xml.rfind("</scene>")
        if end < 0:
            raise InputError(f"{self.path}: not a Mitsuba scene file (no </scene>)")
        self.sionna_scene: Any = None  # a sionna.rt.Scene once loaded through Sionna RT
        with tempfile.TemporaryDirectory() as tmp:
            ply = Path(tmp) / "body.ply"
            self._body_mesh(mi, verts).write_ply(str(ply))
            body_xml = (f'{skin_xml(self.skin)}<shape type="ply" id="{BODY_ID}">'
                        f'<string name="filename" value="{ply}"/><boolean name="face_normals" value="true"/>'
                        f'<ref id="{_SKIN_MATERIAL_ID}" name="bsdf"/></shape>')
            resolver = mi.FileResolver(mi.file_resolver())
            resolver.append(str(self.path.parent))
            old = mi.file_resolver()
            try:
                mi.set_file_resolver(resolver)
                shapes = None if sionna else self._load_mitsuba(mi, dr, xml[:end] + body_xml + xml[end:])
                if shapes is None:
                    shapes = self._load_sionna(mi, dr, xml[:end] + body_xml + xml[end:])
            finally:
                mi.set_file_resolver(old)
        body = next(mesh for name, mesh, _, _ in shapes if name == BODY_ID)
        self._body_key = f"{body.id()}.vertex_positions"
        self.body_object_id = next(oid for name, _, _, oid in shapes if name == BODY_ID)
        self.object_names = {oid: name for name, _, _, oid in shapes}
        self._dr = dr
        self._static = self._static_meshes(mi, dr, [(n, m, slab) for n, m, slab, _ in shapes if n != BODY_ID])
        self.walls = self._find_walls()
        self.body_vertices = verts.copy()
        self._check_body_vertex_order(mi, dr, body, verts)

    def _load_sionna(self, mi, dr, xml: str) -> list[tuple]:
        """Load through Sionna RT (`sionna_scene` set; needed by the sionna backend); [(name, mesh, (eps_r',
        sigma, thickness), object id)] per shape."""
        import sionna.rt as rt
        from sionna.rt.radio_materials import scattering_pattern_registry

        # merge_shapes=False keeps one object per shape, so errors can name the nearest object.
        self.sionna_scene = load_scene_string(rt.load_scene_from_string, xml, self.path, merge_shapes=False)
        self.sionna_scene.frequency = self.frequency_hz
        body = self.sionna_scene.objects[BODY_ID]
        patterns: dict[str, dict[str, float]] = {
            "lambertian": {}, "directive": {"alpha_r": self.skin.alpha_r},
            "backscattering": {"alpha_r": self.skin.alpha_r, "alpha_i": self.skin.alpha_i,
                               "lambda_": self.skin.lambda_}}
        pattern_args = patterns[self.skin.scattering_pattern]
        pattern = scattering_pattern_registry.get(self.skin.scattering_pattern)
        body.radio_material.scattering_pattern = pattern(**pattern_args)
        self.mi_scene = self.sionna_scene.mi_scene
        self._params = self.sionna_scene.mi_scene_params
        out = []
        for name, o in self.sionna_scene.objects.items():
            m = o.radio_material
            slab = (float(m.relative_permittivity[0]), float(m.conductivity[0]), float(m.thickness[0]))
            out.append((name, o.mi_mesh, slab, int(o.object_id)))
        return out

    def _load_mitsuba(self, mi, dr, xml: str) -> list[tuple] | None:
        """Load with Mitsuba alone (`rtchannel.scene.mitsuba_scene`: no `import sionna.rt`); same list as
        `_load_sionna`, or None when the scene needs Sionna RT's loader."""
        from rtchannel.scene import mitsuba_scene as ms

        try:
            text = ms.rewrite_materials(xml)
            scene, shapes = load_scene_string(ms.load, text, self.path, mi=mi)
        except (ms.NeedsSionna, ET.ParseError):
            return None
        try:
            slabs = [ms.slab_parameters(mi, dr, values, self.frequency_hz) for _, _, values in shapes]
        except ValueError as e:
            raise SceneFileError(load_error_line(self.path, e)) from None
        self.mi_scene = scene
        self._params = mi.traverse(scene)
        return [(name, mesh, slab, ms.object_id(mi, dr, mesh)) for (name, mesh, _), slab in zip(shapes, slabs)]

    # ------------------------------------------------------------------ construction helpers
    def _body_mesh(self, mi, verts):
        mesh = mi.Mesh(BODY_ID, len(verts), len(self.body_faces), has_vertex_normals=False)
        p = mi.traverse(mesh)
        p["vertex_positions"] = mi.Float(np.ascontiguousarray(verts, np.float32).ravel())
        p["faces"] = mi.UInt32(np.ascontiguousarray(self.body_faces, np.uint32).ravel())
        p.update()
        return mesh

    @staticmethod
    def _check_body_vertex_order(mi, dr, mesh, verts):
        pos = np.stack([_to_np(c) for c in mesh.vertex_position(dr.arange(mi.UInt32, mesh.vertex_count()))], axis=1)
        if pos.shape != verts.shape or not np.allclose(pos, verts, atol=1e-4):
            raise RuntimeError("the body mesh was reordered on load; in-place vertex updates would be wrong")

    def roughness(self, name: str) -> float:
        """rms height [m] of the static shape `name` (`roughness_m` of the constructor)."""
        r = self._roughness
        if isinstance(r, dict):
            r = r.get(name, WALL_ROUGHNESS_M)
        r = WALL_ROUGHNESS_M if r is None else float(r)
        if not (np.isfinite(r) and r >= 0):
            raise InputError(f"roughness_m of '{name}' must be a finite rms height >= 0 m, got {r}")
        return r

    def material(self, name: str) -> SurfaceMaterial:
        """The `SurfaceMaterial` of the static shape `name` at the scene frequency (slab and roughness)."""
        eps, sigma, thickness = next(slab for n, _, _, slab in self._static if n == name)
        return SurfaceMaterial.from_slab(eps, sigma, thickness, self.frequency_hz, self.roughness(name))

    @property
    def static_meshes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """(name, vertices [V, 3] m, faces [T, 3]) of every static shape."""
        return [(n, v, f) for n, v, f, _ in self._static]

    @staticmethod
    def _static_meshes(mi, dr, shapes) -> list[tuple[str, np.ndarray, np.ndarray, tuple]]:
        """(name, vertices, faces, (eps_r', sigma, thickness)) of every (name, mesh, slab) in `shapes`."""
        out = []
        for name, m, slab in shapes:
            v = np.stack([_to_np(c) for c in m.vertex_position(dr.arange(mi.UInt32, m.vertex_count()))], axis=1)
            f = np.stack([_to_np(c) for c in m.face_indices(dr.arange(mi.UInt32, m.face_count()))], axis=1)
            out.append((name, v.astype(np.float64), f.astype(np.int64), slab))
        return out

    def _find_walls(self) -> list[Wall]:
        if not self._static:
            return []
        all_v = np.concatenate([v for _, v, _, _ in self._static])
        walls = []
        for name, v, f, mat in self._static:
            a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
            cr = np.cross(b - a, c - a)
            dbl = np.linalg.norm(cr, axis=1)
            ok = dbl > 1e-10
            n = cr[ok] / dbl[ok, None]
            # Canonical sign so both windings of one plane group together.
            sign = np.sign(n[np.arange(len(n)), np.argmax(np.abs(n), axis=1)])
            key_n = n * sign[:, None]
            key_d = np.einsum("ij,ij->i", key_n, a[ok])
            keys = np.round(np.column_stack([key_n * 1e3, key_d / _PLANE_TOL_M])).astype(np.int64)
            _, group = np.unique(keys, axis=0, return_inverse=True)
            tri = np.flatnonzero(ok)
            n_planes = 0
            for g in np.unique(group):
                sel = tri[group == g]
                # Connected pieces of a plane (two table tops at one height are two faces).
                ff = f[sel]
                adj = csr_matrix((np.ones(3 * len(ff)), (np.repeat(np.arange(len(ff)), 3), ff.ravel())),
                                 shape=(len(ff), len(v)))
                ncomp, lab = connected_components(adj @ adj.T, directed=False)
                for comp in range(ncomp):
                    wall = self._wall_from(name, v, f[sel[lab == comp]], cr[sel[lab == comp]], mat, all_v)
                    if wall is not None:
                        walls.append(wall)
                        n_planes += 1
            if n_planes > 1:
                mine = [w for w in walls if w.name == name]
                for k, w in enumerate(mine):
                    object.__setattr__(w, "name", f"{name}#{k}")
        return walls

    def _wall_from(self, name, v, faces, crosses, mat, all_v) -> Wall | None:
        n = crosses.sum(axis=0)
        if np.linalg.norm(n) == 0:  # a closed flat sliver; use any one triangle's orientation
            n = crosses[0]
        n = n / np.linalg.norm(n)
        pts = v[np.unique(faces)]
        origin = pts.mean(axis=0)
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        uv = np.column_stack([(pts - origin) @ e1, (pts - origin) @ e2])
        try:
            hull = ConvexHull(uv)
        except Exception:  # noqa: BLE001 - collinear points: no area
            return None
        if hull.volume < MIN_WALL_AREA_M2:  # 2-D hull "volume" is its area
            return None
        poly_uv = uv[hull.vertices]
        polygon = origin + poly_uv[:, :1] * e1 + poly_uv[:, 1:] * e2
        centroid = polygon.mean(axis=0)
        # A supporting plane of all static geometry (wall, floor) faces the side the geometry is on;
        # other faces (furniture) keep their mesh winding.
        side = (all_v - centroid) @ n
        if side.max() <= _PLANE_TOL_M and side.min() < -_PLANE_TOL_M:
            n = -n
        omega = 2 * np.pi * self.frequency_hz
        eps_r, sigma, thickness = mat
        eps = complex(eps_r, -sigma / (omega * epsilon_0))
        return Wall(name=name, point=centroid, normal=n, polygon=polygon, relative_permittivity=eps,
                    thickness=thickness, area=float(hull.volume), roughness_m=self.roughness(name))

    # ------------------------------------------------------------------ per-frame API
    def set_body(self, vertices: np.ndarray) -> None:
        """Move the body to `vertices` [V, 3] (m) in place (refits the BVH; no recompilation)."""
        v = np.asarray(vertices, dtype=np.float64)
        if v.shape != self.body_vertices.shape:
            raise InputError(f"body vertices must have shape {self.body_vertices.shape}, got {v.shape}")
        mi = _mi()
        self._params[self._body_key] = mi.Float(np.ascontiguousarray(v, np.float32).ravel())
        self._params.update()
        self.body_vertices = v.copy()

    def check_clearance(self, points: np.ndarray, min_distance: float = 0.01) -> None:
        """Raise RadarPlacementError if any point [N, 3] (m) is closer than `min_distance` (m) to geometry.

        The message names the point, its distance and the nearest object (a static shape or "body"). A point
        inside a closed static shape (furniture, a cube; winding number > 1/2) is rejected too, however far
        from its surface.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        for name, v, f, _ in self._static:
            if is_closed(v, f):
                for p in pts[np.abs(winding_numbers(pts, v, f)) > 0.5]:
                    raise RadarPlacementError(f"antenna at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is inside '{name}'")
        meshes = [(n, v, f) for n, v, f, _ in self._static] + [(BODY_ID, self.body_vertices, self.body_faces)]
        for p in pts:
            best, who = np.inf, ""
            for name, v, f in meshes:
                # A mesh whose bounding box is farther than min_distance can neither violate the limit nor
                # be the nearest violating object: skip the exact point-triangle distances.
                lo, hi = v.min(axis=0), v.max(axis=0)
                if np.linalg.norm(np.maximum(0.0, np.maximum(lo - p, p - hi))) >= min_distance:
                    continue
                a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
                bary = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)
                q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
                d = float(np.nan_to_num(np.linalg.norm(q - p, axis=1), nan=np.inf).min(initial=np.inf))
                if d < best:
                    best, who = d, name
            if best < min_distance:
                raise RadarPlacementError(
                    f"antenna at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is {best * 100:.2f} cm from '{who}' "
                    f"(minimum {min_distance * 100:g} cm)")

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_t=np.inf) -> dict[str, np.ndarray]:
        """First hits of a batch of rays against the whole scene (static geometry and body).

        Args:
            origins: [N, 3] (m). directions: [N, 3] (normalised here). max_t: scalar or [N] (m).

        Returns:
            {"hit": bool [N], "t": float [N] (m, inf for a miss), "body": bool [N] (hit the body),
             "prim": int [N] (triangle index within the hit shape, -1 for a miss)}.
        """
        mi, dr = _mi(), self._dr
        o = np.atleast_2d(np.asarray(origins, np.float64))
        d = np.atleast_2d(np.asarray(directions, np.float64))
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        n = len(o)
        ray = mi.Ray3f(_vec3(mi, o, mi.Point3f), _vec3(mi, d, mi.Vector3f))
        mt = np.broadcast_to(np.asarray(max_t, np.float64), (n,))
        ray.maxt = mi.Float(np.minimum(mt, np.finfo(np.float32).max).astype(np.float32))
        pi = self.mi_scene.ray_intersect_preliminary(ray, coherent=False)
        hit = _to_np(pi.is_valid()).astype(bool)
        sid = _to_np(dr.reinterpret_array(mi.UInt32, pi.shape)).astype(np.int64)
        t = np.where(hit, _to_np(pi.t).astype(np.float64), np.inf)
        prim = np.where(hit, _to_np(pi.prim_index).astype(np.int64), -1)
        return {"hit": hit, "t": t, "body": hit & (sid == self.body_object_id), "prim": prim}


_CACHE: "OrderedDict[tuple, tuple[RTScene, np.ndarray]]" = OrderedDict()  # key -> (scene, rest vertices)
_CACHE_SIZE = 4


def get_scene(scene: str | Path, lod: str, height: float, frequency_hz: float,
              skin: SkinMaterial | None = None, sionna: bool = True, roughness_m: float | None = None) -> RTScene:
    """Cached `RTScene` with the avatar (`lod`, scaled to `height` m) as body, so batch workers keep the
    scene and Dr.Jit's compiled kernels warm. The body is returned in the rest pose (a cached scene is
    reset, ~10 ms, since a previous user left it in its last pose); call `set_body`. `sionna=False` (the
    facets backend) may get a scene loaded without Sionna RT (`RTScene`), or a cached one loaded with it.
    roughness_m: the static shapes' rms height [m] (None: `WALL_ROUGHNESS_M`)."""
    from rtchannel.body.avatar import load_avatar

    key = (str(resolve_scene(scene)), lod, round(float(height), 6), float(frequency_hz), skin,
           None if roughness_m is None else float(roughness_m))
    for k in [key + (True,)] + ([] if sionna else [key + (False,)]):
        if k in _CACHE:
            _CACHE.move_to_end(k)
            sc, rest = _CACHE[k]
            if not np.array_equal(sc.body_vertices, rest):
                sc.set_body(rest)
            return sc
    av = load_avatar(lod, height)
    sc = RTScene(scene, av.faces, av.vertices, frequency_hz, skin, sionna=sionna, roughness_m=roughness_m)
    _CACHE[key + (sionna,)] = (sc, sc.body_vertices.copy())
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return sc


__all__ = ["SCENES", "RadarPlacementError", "Wall", "RTScene", "get_scene",
           "resolve_scene", "BODY_ID", "MIN_WALL_AREA_M2"]
