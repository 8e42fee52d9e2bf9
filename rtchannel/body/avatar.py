"""The skinned avatar: MakeHuman hm08 body mesh, CMU-named rig, skinning weights, levels of detail.

The OBJ's group ``body`` (13,378 quads) is the skin; it is closed (watertight, genus 0, no open eye or
mouth holes: measured with trimesh, every edge has exactly two faces, Euler number 2), and its quads
split into 26,756 consistently outward-wound triangles. Coordinates: the OBJ is decimetres, Y up;
OBJ (x, y, z) is Blender (x, -z, y) / 10, and the project frame is R_z(+90 deg) applied to Blender
plus a lift of ``SOLE_OFFSET_M``, i.e. project = (z, x, y) / 10 + (0, 0, 0.81676): metres, z up,
facing +x, left on +y, soles on z = 0 -- the same conversion skeleton.py applies to the rig.

Levels of detail ("10k", "5k", "2k" triangles) come from quadric edge-collapse decimation
(fast-simplification, aggressiveness 3: the default 7 breaks the 2k/5k meshes' watertightness).
A decimated vertex gets the skinning weights of the closest point of the full surface (barycentric
blend of that triangle's vertex weights, pruned below 1e-3 and renormalised), so every LOD is driven
by the same rig. The LODs are stored in ``meshes/avatar/lod/*.npz`` and committed: they are small
(< 0.5 MB together), make runs bit-identical across machines and simplifier versions, and keep the
compiled simplifier out of the runtime path. A missing or stale file (its ``source_hash`` differs
from the assets and settings below) is rebuilt on first use, which needs fast-simplification.
"""
from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy import sparse

from processing.atomic import atomic_path
from rtchannel.assets import avatar_dir
from rtchannel.body.meshgeom import closest_points_on_mesh
from rtchannel.motion.pose import JOINT_INDEX, JOINT_NAMES, SOLE_OFFSET_M, Rig, avatar_rig
from processing.errors import InputError

LOD_TARGETS = {"10k": 10_000, "5k": 5_000, "2k": 2_000}
LODS = ("full", *LOD_TARGETS)
_DECIMATION_AGGRESSIVENESS = 3.0
_MIN_WEIGHT = 1e-3
_GENERATOR_VERSION = 1


@dataclass(frozen=True)
class Avatar:
    """A skinnable body mesh in its rest pose (project frame).

    Attributes:
        vertices: rest-pose vertex positions [V, 3] in metres.
        faces: triangles [T, 3] (vertex indices, counter-clockwise seen from outside).
        weights: linear-blend-skinning weights, sparse CSR [V, J] (rows sum to 1, J = rig joints).
        rig: the skeleton the weights refer to (same height as the mesh).
        lod: level of detail name ("full", "10k", "5k", "2k").
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: sparse.csr_matrix
    rig: Rig
    lod: str

    @property
    def height(self) -> float:
        """Standing height of the rest mesh (soles to top of head) [m]."""
        return self.rig.height

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def dense_weights(self) -> np.ndarray:
        """Skinning weights as a dense [V, J] array."""
        return self.weights.toarray()

    def scaled(self, height: float) -> "Avatar":
        """This avatar uniformly scaled about the floor point under the origin to `height` metres."""
        rig = self.rig.scaled(height)
        return replace(self, vertices=self.vertices * (height / self.rig.height), rig=rig)


def load_avatar(lod: str = "full", height: float | None = None) -> Avatar:
    """The avatar at level of detail `lod` ("full", "10k", "5k" or "2k"), optionally scaled to `height` m.

    Arrays are shared between calls (cached): treat them as read-only.
    """
    if lod not in LODS:
        raise InputError(f"unknown level of detail {lod!r}; choose one of {', '.join(LODS)}")
    av = _full_avatar() if lod == "full" else _lod_avatar(lod)
    return av if height is None else av.scaled(height)


def _read_body_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """All OBJ vertices (dm, Y up) and the quads [Q, 4] of group ``body`` (0-based, global indices)."""
    verts: list[list[float]] = []
    quads: list[list[int]] = []
    group = None
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("g "):
                group = line[2:].strip()
            elif line.startswith("f ") and group == "body":
                quads.append([int(tok.split("/")[0]) - 1 for tok in line.split()[1:]])
    if any(len(q) != 4 for q in quads):
        raise ValueError(f"{path}: group 'body' is expected to hold quads only")
    return np.asarray(verts), np.asarray(quads, dtype=np.int64)


def _read_weights(path: Path, n_vertices: int) -> sparse.csr_matrix:
    raw = json.loads(path.read_text())["weights"]
    rows, cols, vals = [], [], []
    for bone, pairs in raw.items():
        if bone not in JOINT_INDEX:
            raise ValueError(f"{path}: weights for unknown bone {bone!r}")
        arr = np.asarray(pairs, dtype=float).reshape(-1, 2)
        rows.append(arr[:, 0].astype(np.int64))
        cols.append(np.full(len(arr), JOINT_INDEX[bone]))
        vals.append(arr[:, 1])
    w = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(n_vertices, len(JOINT_NAMES)))
    w.sum_duplicates()
    return w


def _normalise_rows(w: sparse.csr_matrix) -> sparse.csr_matrix:
    w = w.tocsr(copy=True)
    w.data[w.data < _MIN_WEIGHT] = 0.0
    w.eliminate_zeros()
    s = np.asarray(w.sum(axis=1)).ravel()
    if (s <= 0).any():
        raise ValueError(f"{int((s <= 0).sum())} vertices have no skinning weight")
    return sparse.diags(1.0 / s) @ w


def _obj_to_project(v_dm: np.ndarray) -> np.ndarray:
    # OBJ (x, y, z) dm -> Blender (x, -z, y)/10 -> R_z(+90 deg): (-by, bx, bz) = (z, x, y)/10, then lift.
    return np.stack([v_dm[:, 2], v_dm[:, 0], v_dm[:, 1]], axis=1) / 10.0 + (0.0, 0.0, SOLE_OFFSET_M)


@lru_cache(maxsize=1)
def _full_avatar() -> Avatar:
    d = avatar_dir()
    v_all, quads = _read_body_obj(d / "base.obj")
    used = np.unique(quads)
    remap = np.full(len(v_all), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    q = remap[quads]
    # Split along the 0-2 diagonal; both halves keep the quad's outward winding.
    faces = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]).astype(np.int32)
    w = _read_weights(d / "weights.cmu_mb.json", len(v_all))[used]
    vertices = _obj_to_project(v_all[used])
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return Avatar(vertices, faces, _normalise_rows(w), avatar_rig(), "full")


def _source_hash(lod: str) -> str:
    h = hashlib.sha256()
    for name in ("base.obj", "weights.cmu_mb.json"):
        h.update((avatar_dir() / name).read_bytes())
    h.update(f"v{_GENERATOR_VERSION} {lod} {LOD_TARGETS[lod]} agg={_DECIMATION_AGGRESSIVENESS} "
             f"minw={_MIN_WEIGHT}".encode())
    return h.hexdigest()


def lod_path(lod: str) -> Path:
    """Cache file of a decimated level of detail."""
    return avatar_dir() / "lod" / f"avatar_{lod}.npz"


def build_lod(lod: str) -> Avatar:
    """Decimate the full body to the LOD's triangle count and transfer the skinning weights."""
    import fast_simplification

    full = _full_avatar()
    pts, tris = fast_simplification.simplify(
        np.array(full.vertices, dtype=np.float64), np.array(full.faces, dtype=np.int32),
        target_count=LOD_TARGETS[lod], agg=_DECIMATION_AGGRESSIVENESS)
    face, bary, _, _ = closest_points_on_mesh(pts, full.vertices, full.faces)
    corners = full.faces[face]
    n = len(pts)
    w = sparse.csr_matrix((n, full.weights.shape[1]))
    for c in range(3):
        w = w + sparse.diags(bary[:, c]) @ full.weights[corners[:, c]]
    return Avatar(np.asarray(pts, float), np.asarray(tris, np.int32), _normalise_rows(w), avatar_rig(), lod)


def save_lod(av: Avatar, path: Path, source_hash: str) -> None:
    """Write the LOD cache atomically: two processes building the same LOD at once (dataset workers)
    each rename a complete file, and a killed build leaves no torn .npz that `np.load` would fail on."""
    w = av.weights.tocsr()
    with atomic_path(path) as tmp, open(tmp, "wb") as f:  # a file object: np.savez would append .npz to a name
        np.savez_compressed(f, vertices=av.vertices, faces=av.faces, w_data=w.data,
                            w_indices=w.indices.astype(np.int32), w_indptr=w.indptr.astype(np.int32),
                            source_hash=np.array(source_hash))


@lru_cache(maxsize=None)
def _lod_avatar(lod: str) -> Avatar:
    path, want = lod_path(lod), _source_hash(lod)
    if path.exists():
        with np.load(path) as z:
            if str(z["source_hash"]) == want:
                w = sparse.csr_matrix((z["w_data"], z["w_indices"], z["w_indptr"]),
                                      shape=(len(z["vertices"]), len(JOINT_NAMES)))
                av = Avatar(z["vertices"], z["faces"], w, avatar_rig(), lod)
                av.vertices.setflags(write=False)
                av.faces.setflags(write=False)
                return av
    av = build_lod(lod)
    try:
        save_lod(av, path, want)
    except OSError as exc:  # a read-only install still works, only slower on each first use
        warnings.warn(f"could not cache avatar LOD {lod} at {path}: {exc}", stacklevel=2)
    return av


SOLE_MAX_Z_M = 0.02  # rest-pose vertices this close to the floor are the soles


def sole_asset() -> dict[str, np.ndarray]:
    """The full mesh's sole vertices as retargeting needs them (`rtchannel.motion.soles`): rest positions
    [P, 3] (m, at the avatar's height), dense skinning weights [P, J], side [P] (+1 left, -1 right) and the
    avatar height [m]. Retargeting reads them from `meshes/avatar/soles.npz` so that the motion layer
    never loads the body mesh; a test checks that file against this function."""
    av = load_avatar("full")
    low = np.flatnonzero(av.vertices[:, 2] < SOLE_MAX_Z_M)
    side = np.sign(av.vertices[low, 1])
    keep = side != 0
    return {"rest": av.vertices[low[keep]], "weights": av.dense_weights()[low[keep]], "side": side[keep],
            "height": np.float64(av.height)}


__all__ = ["Avatar", "LODS", "LOD_TARGETS", "load_avatar", "build_lod", "lod_path", "sole_asset"]
