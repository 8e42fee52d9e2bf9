"""Named 3-D joint positions over time (what markerless pose estimators produce), solved onto the skeleton.

Two file forms, positions in metres unless ``units`` says otherwise, y or z up (``up``; default: guessed from
head above ankles over the whole take):

- ``.npz``: ``positions`` [F, J, 3], ``names`` [J] (strings), ``fps`` (Hz); optional ``units``, ``up``.
- ``.csv``: a header ``time,<name>_x,<name>_y,<name>_z,...`` and one row per frame (time in seconds,
  uniformly spaced).

Joint names are matched case-insensitively, separators ignored, with a side as a prefix or suffix
(``left_hip``, ``LHip``, ``hip_l``, ``l_hip``): hip, knee, ankle, shoulder, elbow and wrist of both sides
are required; heel, toe (``big_toe``), neck, head (or ``nose``) and pelvis (``mid_hip``) are used when
present. The joints become the C3D joint map's virtual joints (`rigs.JOINT_MAPS["c3d"]`): the pelvis and
thorax frames from the hips, shoulders and the trunk's direction, the feet from heel to toe (else ankle to
toe, else the pelvis's forward axis), and lateral points a few centimetres out for the limbs' twist (the
pose estimators give no segment rotation, so a limb's twist follows the pelvis and thorax).
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from processing.errors import one_line
from rtchannel.errors import ConfigError
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.source import (MAX_SOURCE_FRAMES, SourceMotion, check_extent, check_fps, check_times, guess_up,
                                     parse_units, up_rotation)

REQUIRED = tuple(f"{s}_{j}" for j in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist") for s in ("left", "right"))
OPTIONAL = ("left_heel", "right_heel", "left_toe", "right_toe", "neck", "head", "pelvis")
_JOINTS = {"hip": "hip", "knee": "knee", "ankle": "ankle", "shoulder": "shoulder", "elbow": "elbow",
           "wrist": "wrist", "heel": "heel", "toe": "toe", "bigtoe": "toe"}
_CENTRAL = {"neck": "neck", "head": "head", "nose": "head", "headtop": "head", "pelvis": "pelvis",
            "midhip": "pelvis", "hips": "pelvis", "root": "pelvis"}
LATERAL_M, WRIST_HALF_M, FINGER_M, HEAD_M = 0.05, 0.03, 0.09, 0.2
MAX_CSV_BYTES = 1 << 30  # as a BVH file's text
# the pelvis and thorax frames are built from two directions each (hips' left-right and the trunk's up, the
# shoulders' and the trunk's): a real pair spans ~0.2 m x 0.5 m = 0.1 m^2; below 1 cm x 1 cm the axes are noise
MIN_FRAME_AREA_M2 = 1e-4


def canonical(name: str) -> str | None:
    """The canonical joint name (``left_knee``, ``neck``, ...) of a file's joint name, or None."""
    n = re.sub(r"[^a-z0-9]", "", name.lower())
    if n in _CENTRAL:
        return _CENTRAL[n]
    for side, short in (("left", "l"), ("right", "r")):
        for prefix in (side, short):
            for core in (n[len(prefix):] if n.startswith(prefix) else None,
                         n[:-len(prefix)] if n.endswith(prefix) else None):
                if core in _JOINTS:
                    return f"{side}_{_JOINTS[core]}"
    return None


def _npy_header(zf, member: str):
    """(shape, dtype) of the ``.npy`` member `member` of an open NPZ, read from its header alone (nothing
    allocated); ValueError if the header is not an array's or disagrees with the member's size."""
    from numpy.lib import format as npy

    info = zf.getinfo(member)
    with zf.open(info) as f:
        version = npy.read_magic(f)
        read = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
        shape, _fortran, dtype = read(f)
        header = f.tell()
    if dtype.hasobject:
        raise ValueError(f"{member}: object arrays are not read (pickles)")
    if info.file_size != header + int(np.prod(shape, dtype=object)) * dtype.itemsize:
        raise ValueError(f"{member}: the array header disagrees with its data")
    return shape, dtype


def _check_npz(path: Path) -> None:
    """Shapes, types and sizes of a joint-position NPZ checked from the arrays' headers before anything is
    loaded (a few bytes may claim 70 GiB): positions [F, J, 3] numbers with F <= `MAX_SOURCE_FRAMES`,
    J <= `bvh.MAX_JOINTS` and F x J x 3 <= `bvh.MAX_VALUES`; names [J] strings; fps, units, up single values."""
    import zipfile

    from rtchannel.motion.bvh import MAX_JOINTS, MAX_VALUES

    try:
        with zipfile.ZipFile(path) as zf:
            members = set(zf.namelist())
            lacking = [k for k in ("positions", "names", "fps") if f"{k}.npy" not in members]
            if lacking:
                raise MotionImportError(path, f"not a joint-position NPZ: lacks {', '.join(lacking)} (positions, "
                                        "names, fps)")
            shapes = {k: _npy_header(zf, f"{k}.npy") for k in ("positions", "names", "fps", "units", "up")
                      if f"{k}.npy" in members}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
        raise MotionImportError(path, f"not a joint-position NPZ (positions, names, fps): {one_line(e, 120)}") from None
    (shape, dtype), (n_shape, n_dtype) = shapes["positions"], shapes["names"]
    if len(shape) != 3 or shape[2] != 3 or dtype.kind not in "fiu":
        raise MotionImportError(path, f"positions must be numbers [frames, joints, 3], got {dtype} {list(shape)}")
    if not (2 <= shape[0] <= MAX_SOURCE_FRAMES and 1 <= shape[1] <= MAX_JOINTS
            and shape[0] * shape[1] * 3 <= MAX_VALUES):
        raise MotionImportError(path, f"positions {list(shape)}: 2..{MAX_SOURCE_FRAMES} frames, 1..{MAX_JOINTS} joints "
                                f"and at most {MAX_VALUES} values")
    if len(n_shape) != 1 or n_shape[0] != shape[1] or n_dtype.kind not in "US":
        raise MotionImportError(path, f"names must be {shape[1]} strings (one per joint of positions), got "
                                f"{n_dtype} {list(n_shape)}")
    for key, kinds in (("fps", "fiu"), ("units", "fiuUS"), ("up", "US")):
        if key in shapes and (int(np.prod(shapes[key][0])) != 1 or shapes[key][1].kind not in kinds):
            raise MotionImportError(path, f"{key} must be a single {'number' if kinds == 'fiu' else 'value'}, got "
                                    f"{shapes[key][1]} {list(shapes[key][0])}")


def _read(path: Path) -> tuple[dict[str, np.ndarray], float, str | None, str | None]:
    """(raw joints {file name: [F, 3]}, fps, units, up) of an NPZ or CSV joint file."""
    if path.suffix.lower() == ".npz":
        _check_npz(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                pos = np.asarray(z["positions"], float)
                names = [x.decode("latin-1") if isinstance(x, bytes) else str(x) for x in z["names"].tolist()]
                fps = float(z["fps"].reshape(()))
                units = z["units"].reshape(()).item() if "units" in z.files else None
                up = str(z["up"].reshape(())) if "up" in z.files else None
        except (OSError, KeyError, ValueError, EOFError) as e:
            raise MotionImportError(path, "not a joint-position NPZ (positions, names, fps): "
                                    f"{type(e).__name__}") from None
        if isinstance(units, bytes):
            units = units.decode("latin-1")
        return {n: pos[:, k] for k, n in enumerate(names)}, fps, units, up
    if path.stat().st_size > MAX_CSV_BYTES:
        raise MotionImportError(path, f"file larger than {MAX_CSV_BYTES >> 20} MiB")
    try:
        header = path.read_text(encoding="utf-8-sig").splitlines()[0].split(",")  # a BOM, as spreadsheets write
        with warnings.catch_warnings():  # an empty table is refused below, not warned about
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError, IndexError, UnicodeDecodeError) as e:
        raise MotionImportError(path, f"not a joint-position CSV (time,<name>_x,...): {type(e).__name__}") from None
    if data.size == 0:
        raise MotionImportError(path, "no data rows after the header")
    if header[0].strip().lower() != "time" or (len(header) - 1) % 3 or data.shape[1] != len(header):
        raise MotionImportError(path, "the header must be time,<name>_x,<name>_y,<name>_z,...", line=1)
    fps = check_times(path, data[:, 0])
    joints = {}
    for k in range(1, len(header), 3):
        base = header[k].strip()
        if (not base.endswith("_x") or header[k + 1].strip() != base[:-2] + "_y"
                or header[k + 2].strip() != base[:-2] + "_z"):
            raise MotionImportError(path, f"columns {k + 1}-{k + 3} must be <name>_x,<name>_y,<name>_z", line=1)
        joints[base[:-2]] = data[:, k:k + 3]
    return joints, fps, None, None


def _frame(x, y_hint):
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = y_hint - np.einsum("...i,...i->...", y_hint, x)[..., None] * x
    y = y / np.linalg.norm(y, axis=-1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def read_joint_tracks(path, *, units=None, up: str | None = None) -> SourceMotion:
    """Import a joint-position file (NPZ or CSV, see the module docstring) into the project frame (metres,
    z up), before retargeting."""
    path = Path(path)
    if not path.is_file():
        raise MotionImportError(path, "no such file")
    raw, fps, file_units, file_up = _read(path)
    try:
        check_fps(fps)
    except ConfigError as e:
        raise MotionImportError(path, f"the file's frame rate: {e}") from None
    joints = {}
    for name, v in raw.items():
        c = canonical(name)
        if c is not None and c not in joints:
            joints[c] = v
    missing = [j for j in REQUIRED if j not in joints]
    if missing:
        raise MotionImportError(path, f"joint positions lack {', '.join(missing)} "
                                f"(found: {', '.join(sorted(raw))[:200]})")
    scale = parse_units(units if units is not None else file_units) or 1.0
    bad = [k for k, v in joints.items() if not np.isfinite(v).all()]
    if bad:
        raise MotionImportError(path, f"{bad[0]}: missing or non-finite positions (fill gaps before importing)",
                                frame=int(np.argmax(~np.isfinite(joints[bad[0]]).all(axis=1))))
    check_extent(path, {k: v * scale for k, v in joints.items()})  # before any arithmetic on them
    head_src = joints.get("head", joints.get("neck", 0.5 * (joints["left_shoulder"] + joints["right_shoulder"])))
    up_axis = up or file_up or guess_up(head_src, 0.5 * (joints["left_ankle"] + joints["right_ankle"]))
    rot = up_rotation(up_axis) * scale
    j = {k: v @ rot.T for k, v in joints.items()}
    hips = 0.5 * (j["left_hip"] + j["right_hip"])
    shoulders = 0.5 * (j["left_shoulder"] + j["right_shoulder"])
    neck = j.get("neck", shoulders)
    trunk_up = neck - hips
    left = j["left_hip"] - j["right_hip"]
    for what, a, b in (("hips", left, trunk_up), ("shoulders", j["left_shoulder"] - j["right_shoulder"], trunk_up)):
        flat = np.linalg.norm(np.cross(a, b), axis=-1) < MIN_FRAME_AREA_M2
        if flat.any():
            raise MotionImportError(path, f"the {what} coincide or lie on the trunk's line: no body frame (degenerate "
                                    "joint positions)", frame=int(np.argmax(flat)))
    pelvis = _frame(np.cross(left, trunk_up), left)  # x forward = left x up
    thorax = _frame(np.cross(j["left_shoulder"] - j["right_shoulder"], trunk_up),
                    j["left_shoulder"] - j["right_shoulder"])
    pts = {"LHJC": j["left_hip"], "RHJC": j["right_hip"], "NECK": neck, "UTHORAX": neck,
           "HEADC": j["head"] if "head" in j else neck + HEAD_M * thorax[..., :, 2]}
    frames = {"pelvis": pelvis, "thorax": thorax, "head": thorax}
    for s, side, sign in (("L", "left", 1.0), ("R", "right", -1.0)):
        pts[f"{s}KJC"], pts[f"{s}AJC"] = j[f"{side}_knee"], j[f"{side}_ankle"]
        pts[f"{s}SJC"], pts[f"{s}EJC"], pts[f"{s}WJC"] = j[f"{side}_shoulder"], j[f"{side}_elbow"], j[f"{side}_wrist"]
        out_leg, out_arm = sign * pelvis[..., :, 1], sign * thorax[..., :, 1]
        pts[f"{s}KNE"] = pts[f"{s}KJC"] + LATERAL_M * out_leg
        pts[f"{s}ANK"] = pts[f"{s}AJC"] + LATERAL_M * out_leg
        pts[f"{s}ELB"] = pts[f"{s}EJC"] + LATERAL_M * out_arm
        pts[f"{s}WRA"] = pts[f"{s}WJC"] + WRIST_HALF_M * out_arm
        pts[f"{s}WRB"] = pts[f"{s}WJC"] - WRIST_HALF_M * out_arm
        fore = pts[f"{s}WJC"] - pts[f"{s}EJC"]
        pts[f"{s}FIN"] = pts[f"{s}WJC"] + FINGER_M * fore / np.linalg.norm(fore, axis=-1, keepdims=True)
        toe, heel = j.get(f"{side}_toe"), j.get(f"{side}_heel")
        fwd = (toe - heel if toe is not None and heel is not None else
               toe - pts[f"{s}AJC"] if toe is not None else pelvis[..., :, 0])
        frames[f"{s}foot"] = _frame(fwd, pelvis[..., :, 1])
    rel = Rotation.from_matrix(np.einsum("fba,fbc->fac", pelvis, thorax))
    for k, frac in (("lumbar1", 1 / 3), ("lumbar2", 2 / 3)):
        frames[k] = pelvis @ Rotation.from_rotvec(rel.as_rotvec() * frac).as_matrix()
    check_extent(path, pts)
    info = {"format": "joint-tracks", "rig": "c3d", "units": f"{scale} m/unit", "metres_per_unit": scale,
            "up": up_axis, "source_frames": len(hips), "joints": sorted(j)}
    return SourceMotion(str(path), fps, pts, frames, {k: np.eye(3) for k in frames}, "c3d", info)


__all__ = ["read_joint_tracks", "canonical", "REQUIRED", "OPTIONAL"]
