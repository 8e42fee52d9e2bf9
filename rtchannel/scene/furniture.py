"""Furniture in a ray-tracing scene: the built-in chair, user meshes, and the scene file that holds them.

A `Furniture` item is a validated description (mesh, ITU radio material, pose, size); `furnished_scene_xml`
writes a Mitsuba scene file (base scene + furniture, content-addressed in a cache folder) that Sionna RT
and the `facets` backend's visibility load like any other scene. `rtchannel.scene.chair_fit.chair_for`
places a chair under a seated person from the motion.

The built-in chair is six boxes (seat board, four legs, a backrest board; the rear legs run up to the top
of the backrest as posts): 72 triangles, so it costs the ray tracer next to nothing per frame. Local frame:
origin on the floor under the seat centre, the sitter faces +x, the backrest is at -x, z up. Dimensions of
a standard adult side (dining) chair:

* seat height 0.45 m by default (EN 1729-1 size mark 7, statures from 1.74 m: 460 mm; dining chairs 17-19 in
  = 0.43-0.48 m, trade guides such as corleydesigns.com "Know your dining chair dimensions"); set from the
  motion by `chair_for`;
* seat 0.44 m wide (16-20 in = 0.41-0.51 m), 0.42 m deep (16-18 in = 0.41-0.46 m), 3 cm board;
* legs 35 mm square (solid-wood chair legs are 30-40 mm);
* backrest board 0.18-0.47 m above the seat (overall height 0.92 m at a 0.45 m seat: 36-42 in = 0.91-1.07 m).

Every length is fixed except the seat height (legs and posts follow it). The material defaults to ITU-R
P.2040 wood (Sionna RT: eps_r' = 1.99, sigma = 0.0047 f_GHz^1.0718 S/m, i.e. 0.14 S/m at 24.125 GHz).
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
import warnings
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from processing.atomic import temporary_sibling
from rtchannel.assets import furniture_dir
from processing.errors import InputError

CHAIR = "chair"
DEFAULT_SEAT_HEIGHT_M = 0.45
SEAT_WIDTH_M = 0.44
SEAT_DEPTH_M = 0.42
SEAT_THICKNESS_M = 0.03
LEG_SECTION_M = 0.035
BACK_BOTTOM_ABOVE_SEAT_M = 0.18
BACK_TOP_ABOVE_SEAT_M = 0.47
CHAIR_MODEL = (f"rtchannel chair v1: seat {SEAT_DEPTH_M} x {SEAT_WIDTH_M} x {SEAT_THICKNESS_M} m, legs "
               f"{LEG_SECTION_M} m square, backrest {BACK_BOTTOM_ABOVE_SEAT_M}-{BACK_TOP_ABOVE_SEAT_M} m above the "
               "seat")
MAX_MESH_TRIANGLES = 20_000  # every triangle costs ray-tracing time every frame
MESH_SUFFIXES = (".ply", ".obj")
# ITU-R P.2040 materials of Sionna RT 2.2 (`sionna.rt.radio_materials.itu.ITU_MATERIALS_PROPERTIES`); each is
# defined over its own frequency ranges, which Sionna checks when it loads the scene at the carrier.
ITU_MATERIALS = ("concrete", "brick", "plasterboard", "wood", "glass", "clear_acrylic", "ceiling_board",
                 "chipboard", "plywood", "marble", "floorboard", "vinyl_tile", "carpet_tile", "asphalt_concrete",
                 "metal", "very_dry_ground", "medium_dry_ground", "wet_ground")
_SCENE_FORMAT = 1  # bump when the generated XML changes, so cached files are not reused


def allowed_mesh_dirs() -> list[Path]:
    """Folders user furniture meshes may come from: `meshes/furniture/` and every folder listed in the
    environment variable ``RTCHANNEL_FURNITURE_DIRS`` (separated by the OS path separator)."""
    extra = [Path(p) for p in os.environ.get("RTCHANNEL_FURNITURE_DIRS", "").split(os.pathsep) if p]
    return [d.resolve() for d in [furniture_dir(), *extra]]


def scene_cache_dir() -> Path:
    """Where generated scene files go: ``$RTCHANNEL_CACHE_DIR/scenes``, else ``$XDG_CACHE_HOME/rtchannel/scenes``
    (default ``~/.cache/rtchannel/scenes``)."""
    root = os.environ.get("RTCHANNEL_CACHE_DIR")
    if root:
        return Path(root) / "scenes"
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "rtchannel" / "scenes"


# ----------------------------------------------------------------------------------------------- geometry
def box_mesh(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Closed box [lo, hi] (m): 8 vertices [8, 3] and 12 outward-wound triangles [12, 3]."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[(lo, hi)[i >> 0 & 1][0], (lo, hi)[i >> 1 & 1][1], (lo, hi)[i >> 2 & 1][2]] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], dtype=np.int64)
    return v, f


def chair_boxes(seat_height: float = DEFAULT_SEAT_HEIGHT_M) -> np.ndarray:
    """The chair's boxes [6, 2, 3] (lo, hi corners, m) in its local frame: seat, 2 front legs, 2 rear legs
    running up as backrest posts, backrest board."""
    h, hd, hw, leg = seat_height, SEAT_DEPTH_M / 2, SEAT_WIDTH_M / 2, LEG_SECTION_M
    top = h + BACK_TOP_ABOVE_SEAT_M
    boxes = [((-hd, -hw, h - SEAT_THICKNESS_M), (hd, hw, h))]
    for y0 in (-hw, hw - leg):
        boxes.append(((hd - leg, y0, 0.0), (hd, y0 + leg, h - SEAT_THICKNESS_M)))  # front leg
        boxes.append(((-hd, y0, 0.0), (-hd + leg, y0 + leg, top)))  # rear leg and backrest post
    boxes.append(((-hd, -hw, h + BACK_BOTTOM_ABOVE_SEAT_M), (-hd + leg, hw, top)))  # backrest board
    return np.array(boxes, dtype=float)


def chair_mesh(seat_height: float = DEFAULT_SEAT_HEIGHT_M) -> tuple[np.ndarray, np.ndarray]:
    """The chair as one triangle mesh in its local frame: vertices [48, 3] (m), faces [72, 3]."""
    parts = [box_mesh(lo, hi) for lo, hi in chair_boxes(seat_height)]
    v = np.concatenate([p[0] for p in parts])
    f = np.concatenate([p[1] + 8 * k for k, p in enumerate(parts)])
    return v, f


def _yaw_matrix(yaw_deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ----------------------------------------------------------------------------------------------- model
class Furniture(BaseModel):
    """One piece of static furniture (validated).

    Attributes:
        mesh: "chair" (the built-in chair, see the module doc) or a ``.ply``/``.obj`` triangle mesh (metres,
            z up, origin on the floor under the object) inside `allowed_mesh_dirs()`; a relative path is
            taken relative to `meshes/furniture/`.
        material: ITU-R P.2040 material name as Sionna RT knows it (`ITU_MATERIALS`), e.g. "wood".
        thickness: slab thickness [m] of the material (Sionna's thin-slab model); a chair board ~3 cm.
        position: where the mesh's local origin goes (x, y, z) [m].
        yaw_deg: rotation about the vertical [deg], counter-clockwise from +x (the chair's sitter faces
            the direction yaw_deg).
        seat_height: chair only: top of the seat above its origin [m] (default 0.45).
        scale: user meshes only: uniform scale factor applied before the rotation.
        name: short name, part of the scene's shape id (letters, digits, _ and -).
        note: provenance, e.g. how the piece was placed (free text, stored with simulations).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    mesh: str = CHAIR
    material: str = "wood"
    thickness: float = Field(0.03, gt=0.0, le=1.0)
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_deg: float = Field(0.0, ge=-720.0, le=720.0)
    seat_height: float | None = Field(None, ge=0.15, le=1.0)
    scale: float = Field(1.0, gt=0.0, le=100.0)
    name: str = Field("", pattern=r"^[A-Za-z0-9_-]{0,40}$")
    note: str = ""

    @field_validator("material")
    @classmethod
    def _itu(cls, v: str) -> str:
        if v not in ITU_MATERIALS:
            raise InputError(f"unknown ITU material {v!r}; choose one of {', '.join(ITU_MATERIALS)}")
        return v

    @field_validator("mesh")
    @classmethod
    def _mesh(cls, v: str) -> str:
        if v == CHAIR:
            return v
        resolve_mesh_path(v)
        return v

    @model_validator(mode="after")
    def _sizes(self) -> "Furniture":
        if self.mesh == CHAIR and self.scale != 1.0:
            raise InputError("the built-in chair is sized by seat_height, not scale")
        if self.mesh != CHAIR and self.seat_height is not None:
            raise InputError("seat_height applies to the built-in chair only; size a user mesh with scale")
        return self

    @property
    def label(self) -> str:
        """The name, or the mesh's stem."""
        return self.name or (CHAIR if self.mesh == CHAIR else Path(self.mesh).stem)

    def local_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices [V, 3] m, faces [T, 3]) in the piece's own frame, scaled."""
        if self.mesh == CHAIR:
            return chair_mesh(DEFAULT_SEAT_HEIGHT_M if self.seat_height is None else self.seat_height)
        v, f = load_mesh_file(resolve_mesh_path(self.mesh))
        return v * self.scale, f

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Local points [..., 3] (m) -> scene coordinates."""
        return np.asarray(points, float) @ _yaw_matrix(self.yaw_deg).T + np.asarray(self.position)

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Scene points [..., 3] (m) -> the piece's local frame."""
        return (np.asarray(points, float) - np.asarray(self.position)) @ _yaw_matrix(self.yaw_deg)

    def world_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices [V, 3] m, faces [T, 3]) placed in the scene."""
        v, f = self.local_mesh()
        return self.to_world(v), f

    def penetration(self, points: np.ndarray, boxes=slice(None)) -> np.ndarray:
        """Chair only: how deep [m] each scene point [..., 3] lies inside the chair's boxes (0 outside);
        `boxes` selects boxes in `chair_boxes` order (seat, legs and posts, backrest)."""
        if self.mesh != CHAIR:
            raise InputError("penetration depth is defined for the built-in chair (boxes) only")
        p = self.to_local(points)
        depth = np.zeros(p.shape[:-1])
        for lo, hi in chair_boxes(DEFAULT_SEAT_HEIGHT_M if self.seat_height is None else self.seat_height)[boxes]:
            depth = np.maximum(depth, np.minimum(p - lo, hi - p).min(axis=-1))
        return depth

    def describe(self) -> dict:
        """JSON-serialisable description (every field, plus the mesh's triangle count and, for a file,
        its resolved path and SHA-256)."""
        d = self.model_dump(mode="json")
        if self.mesh == CHAIR:
            d.update(triangles=12 * len(chair_boxes()), model=CHAIR_MODEL)
        else:
            path = resolve_mesh_path(self.mesh)
            d.update(path=str(path), sha256=_file_sha256(path), triangles=int(len(load_mesh_file(path)[1])))
        return d

    @classmethod
    def from_describe(cls, d: dict) -> "Furniture":
        """The piece `describe()` recorded (the derived keys are ignored)."""
        return cls(**{k: v for k, v in d.items() if k in cls.model_fields})


def resolve_mesh_path(mesh: str | Path) -> Path:
    """The existing ``.ply``/``.obj`` file `mesh` names, inside `allowed_mesh_dirs()`; raises ValueError."""
    p = Path(mesh).expanduser()
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(f"furniture mesh {mesh!r}: expected 'chair' or a {' or '.join(MESH_SUFFIXES)} file")
    p = (p if p.is_absolute() else furniture_dir() / p).resolve()
    allowed = allowed_mesh_dirs()
    if not any(p.is_relative_to(d) for d in allowed):
        raise InputError(f"furniture mesh {p} is outside the allowed folders ({', '.join(map(str, allowed))}); "
                         "copy it to meshes/furniture/ or add its folder to RTCHANNEL_FURNITURE_DIRS")
    if not p.is_file():
        raise InputError(f"furniture mesh {p} does not exist")
    return p


def load_mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices [V, 3] m, faces [T, 3]) of a PLY/OBJ triangle mesh; raises ValueError if empty, not
    finite or over `MAX_MESH_TRIANGLES` triangles."""
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    if not isinstance(mesh, trimesh.Trimesh):  # force="mesh" concatenates a scene into one Trimesh
        raise InputError(f"furniture mesh {path}: not a triangle mesh")
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    if len(f) == 0 or not np.isfinite(v).all():
        raise InputError(f"furniture mesh {path}: no triangles or non-finite vertices")
    if len(f) > MAX_MESH_TRIANGLES:
        raise InputError(f"furniture mesh {path} has {len(f)} triangles (limit {MAX_MESH_TRIANGLES}): every "
                         "triangle costs ray-tracing time each frame; decimate it")
    return v, f


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY (float32 vertices, int32 triangles), written atomically."""
    v = np.ascontiguousarray(vertices, "<f4")
    f = np.ascontiguousarray(faces, "<i4")
    header = (f"ply\nformat binary_little_endian 1.0\ncomment rtchannel furniture (metres, z up)\n"
              f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    rows = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rows["n"], rows["i"] = 3, f
    tmp = temporary_sibling(path)
    tmp.write_bytes(header + v.tobytes() + rows.tobytes())
    os.replace(tmp, path)


# ----------------------------------------------------------------------------------------------- scene file
_FILENAME_TAG = re.compile(r"<string\b[^>]*>")
_VALUE_ATTR = re.compile(r'(\bvalue\s*=\s*")([^"]*)(")')


def _absolute_filenames(xml: str, base_dir: Path) -> str:
    """`xml` with every relative ``<string name="filename" value=...>`` made absolute against `base_dir`
    (the generated file lives elsewhere)."""
    def fix(m):
        tag = m.group(0)
        if not re.search(r'\bname\s*=\s*"filename"', tag):
            return tag
        return _VALUE_ATTR.sub(lambda v: v.group(1) + (v.group(2) if Path(v.group(2)).is_absolute()
                                                       else str((base_dir / v.group(2)).resolve())) + v.group(3), tag)
    return _FILENAME_TAG.sub(fix, xml)


def furnished_scene_xml(base_xml: Path, furniture, cache_dir: Path | None = None) -> Path:
    """A Mitsuba scene file = `base_xml` + `furniture` (each piece a PLY next to it), in a cache folder named
    by the SHA-256 of the content (base XML text, every piece's description and mesh bytes), so equal
    content gives the same path (`rt_scene.get_scene` caches by path) and changed content a new one. Files
    are written atomically; the XML last, so an existing XML means a complete folder."""
    base_xml = Path(base_xml).resolve()
    xml = _absolute_filenames(base_xml.read_text(), base_xml.parent)
    end = xml.rfind("</scene>")
    if end < 0:
        raise InputError(f"{base_xml}: not a Mitsuba scene file (no </scene>)")
    items = list(furniture)
    meshes = [f.world_mesh() for f in items]
    digest = hashlib.sha256(json.dumps({"format": _SCENE_FORMAT, "base": xml,
                                        "furniture": [f.describe() for f in items]}, sort_keys=True).encode())
    for v, f in meshes:  # the exact geometry, whatever produced it
        digest.update(np.ascontiguousarray(v, "<f4").tobytes() + np.ascontiguousarray(f, "<i4").tobytes())
    name = f"{base_xml.stem}-{digest.hexdigest()[:20]}"
    folder = (cache_dir or scene_cache_dir()) / name
    out = folder / "scene.xml"
    if out.is_file():
        return out
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # e.g. a read-only home: the system's temporary folder still works
        folder = Path(tempfile.gettempdir()) / "rtchannel-scenes" / name
        warnings.warn(f"cannot write the scene cache ({exc}); using {folder}", stacklevel=2)
        out = folder / "scene.xml"
        if out.is_file():
            return out
        folder.mkdir(parents=True, exist_ok=True)
    shapes, materials = [], {}
    for k, (item, (v, f)) in enumerate(zip(items, meshes)):
        ply = folder / f"furniture{k}.ply"
        write_ply(ply, v, f)
        mat_id = f"rtchannel-furniture-{item.material}-{item.thickness:g}"
        materials[mat_id] = (f'<bsdf type="itu-radio-material" id="{mat_id}"><string name="type" '
                             f'value="{item.material}"/><float name="thickness" value="{item.thickness!r}"/></bsdf>')
        label = re.sub(r"[^A-Za-z0-9_-]", "_", item.label)
        shapes.append(f'<shape type="ply" id="furniture{k}-{label}"><string name="filename" '
                      f'value={quoteattr(str(ply))}/><boolean name="face_normals" value="true"/>'
                      f'<ref id="{mat_id}" name="bsdf"/></shape>')
    source = str(base_xml).replace("--", "- -")  # "--" may not appear inside an XML comment
    header = f"<!-- generated by rtchannel.scene.furniture from {source}; do not edit -->\n"
    text = header + xml[:end] + "\n    " + "\n    ".join([*materials.values(), *shapes]) + "\n" + xml[end:]
    tmp = temporary_sibling(out)
    tmp.write_text(text)
    os.replace(tmp, out)
    return out


__all__ = ["CHAIR", "Furniture", "ITU_MATERIALS", "allowed_mesh_dirs", "box_mesh", "chair_boxes", "chair_mesh",
           "furnished_scene_xml", "furniture_dir", "load_mesh_file", "resolve_mesh_path", "scene_cache_dir",
           "write_ply"]
