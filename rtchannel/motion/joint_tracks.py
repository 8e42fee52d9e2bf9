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
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.source import (SourceMotion, check_extent, check_fps, guess_up, parse_units,
                                     up_rotation)

REQUIRED = tuple(f"{s}_{j}" for j in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist") for s in ("left", "right"))
OPTIONAL = ("left_heel", "right_heel", "left_toe", "right_toe", "neck", "head", "pelvis")
_JOINTS = {"hip": "hip", "knee": "knee", "ankle": "ankle", "shoulder": "shoulder", "elbow": "elbow",
           "wrist": "wrist", "heel": "heel", "toe": "toe", "bigtoe": "toe"}
_CENTRAL = {"neck": "neck", "head": "head", "nose": "head", "headtop": "head", "pelvis": "pelvis",
            "midhip": "pelvis", "hips": "pelvis", "root": "pelvis"}
LATERAL_M, WRIST_HALF_M, FINGER_M, HEAD_M = 0.05, 0.03, 0.09, 0.2


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


def _read(path: Path) -> tuple[dict[str, np.ndarray], float, str | None, str | None]:
    """(raw joints {file name: [F, 3]}, fps, units, up) of an NPZ or CSV joint file."""
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                pos = np.asarray(z["positions"], float)
                names = [str(x) for x in z["names"]]
                fps = float(z["fps"])
                units = str(z["units"]) if "units" in z.files else None
                up = str(z["up"]) if "up" in z.files else None
        except (OSError, KeyError, ValueError) as e:
            raise MotionImportError(path, f"not a joint-position NPZ (positions, names, fps): {type(e).__name__}") from None
        if pos.ndim != 3 or pos.shape[1:] != (len(names), 3):
            raise MotionImportError(path, f"positions must be [frames, {len(names)}, 3], got {list(pos.shape)}")
        return {n: pos[:, k] for k, n in enumerate(names)}, fps, units, up
    try:
        header = path.read_text(encoding="utf-8").splitlines()[0].split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError, IndexError, UnicodeDecodeError) as e:
        raise MotionImportError(path, f"not a joint-position CSV (time,<name>_x,...): {type(e).__name__}") from None
    if header[0].strip().lower() != "time" or (len(header) - 1) % 3 or data.shape[1] != len(header):
        raise MotionImportError(path, "the header must be time,<name>_x,<name>_y,<name>_z,...", line=1)
    t = data[:, 0]
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise MotionImportError(path, "time must increase")
    joints = {}
    for k in range(1, len(header), 3):
        base = header[k].strip()
        if not base.endswith("_x") or header[k + 1].strip() != base[:-2] + "_y" or header[k + 2].strip() != base[:-2] + "_z":
            raise MotionImportError(path, f"columns {k + 1}-{k + 3} must be <name>_x,<name>_y,<name>_z", line=1)
        joints[base[:-2]] = data[:, k:k + 3]
    return joints, float((len(t) - 1) / (t[-1] - t[0])), None, None


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
    check_fps(fps)
    joints = {}
    for name, v in raw.items():
        c = canonical(name)
        if c is not None and c not in joints:
            joints[c] = v
    missing = [j for j in REQUIRED if j not in joints]
    if missing:
        raise MotionImportError(path, f"joint positions lack {', '.join(missing)} (found: {', '.join(sorted(raw))[:200]})")
    scale = parse_units(units if units is not None else file_units) or 1.0
    head_src = joints.get("head", joints.get("neck", 0.5 * (joints["left_shoulder"] + joints["right_shoulder"])))
    up_axis = up or file_up or guess_up(head_src, 0.5 * (joints["left_ankle"] + joints["right_ankle"]))
    c = up_rotation(up_axis) * scale
    j = {k: v @ c.T for k, v in joints.items()}
    bad = [k for k, v in j.items() if not np.isfinite(v).all()]
    if bad:
        raise MotionImportError(path, f"{bad[0]}: missing or non-finite positions (fill gaps before importing)",
                                frame=int(np.argmax(~np.isfinite(j[bad[0]]).all(axis=1))))
    hips = 0.5 * (j["left_hip"] + j["right_hip"])
    shoulders = 0.5 * (j["left_shoulder"] + j["right_shoulder"])
    neck = j.get("neck", shoulders)
    trunk_up = neck - hips
    left = j["left_hip"] - j["right_hip"]
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
