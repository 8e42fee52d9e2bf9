"""OpenCap / OpenSim body kinematics (JSON): per frame the translation [m] and rotation of each body of the
OpenSim model (LaiUhlrich2022 / Rajagopal: pelvis, femur, tibia, talus, calcn, toes, torso, humerus, ulna,
radius, hand), as the OpenCap visualiser stores them: ``{"time": [F], "bodies": {name: {"translation":
[F][3], "rotation": [F][3], ...}}}``, y up, rotations as body-fixed XYZ Euler angles [rad].

An OpenSim body's origin is its proximal joint (femur: hip, tibia: knee, talus: ankle, humerus: shoulder,
ulna: elbow, hand: wrist) and its axes are x anterior, y superior, z to the right; in the default pose every
body frame is the ground's, standing and facing +x. The joints and segment frames become the virtual joints
the C3D joint map retargets (`rigs.JOINT_MAPS["c3d"]`): hip, knee and ankle centres with a lateral point
for the leg's twist, shoulder, elbow, wrist, a fingertip point, neck and head points above the shoulders,
and the pelvis, thorax (torso), head (torso: the model has no head body) and foot (calcaneus) frames.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.source import (MAX_ANGLE_DEG, MAX_COORD_M, SourceMotion, check_extent, check_times,
                                     up_rotation)

MAX_JSON_BYTES = 1 << 30
BODIES = ("pelvis", "femur_l", "femur_r", "tibia_l", "tibia_r", "talus_l", "talus_r", "calcn_l", "calcn_r",
          "torso", "humerus_l", "humerus_r", "ulna_l", "ulna_r", "hand_l", "hand_r")
# offsets [m] of the points the joint map needs beyond the joint centres (typical adult segment sizes)
LATERAL_M = 0.05    # lateral knee / ankle / elbow point from the joint centre
WRIST_HALF_M = 0.03  # radial and ulnar wrist points
FINGER_M = 0.09      # wrist to the middle of the fingers
NECK_M = 0.06        # neck above the shoulders' midpoint
HEAD_M = 0.2         # head centre above the neck


def read_opencap(path, *, up: str | None = None) -> SourceMotion:
    """Import OpenCap body kinematics (JSON) into the project frame (metres, z up), before retargeting.

    Args:
        path: the ``.json`` file.
        up: the file's up axis; default y (OpenSim's ground frame).
    """
    path = Path(path)
    if not path.is_file():
        raise MotionImportError(path, "no such file")
    if path.stat().st_size > MAX_JSON_BYTES:
        raise MotionImportError(path, f"file larger than {MAX_JSON_BYTES >> 20} MiB")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        t = np.asarray(doc["time"], float)
        bodies = doc["bodies"]
        missing = [b for b in BODIES if b not in bodies]
        if missing:
            raise MotionImportError(path, f"not OpenSim full-body kinematics: lacks bodies {', '.join(missing[:6])}")
        trans = {b: np.asarray(bodies[b]["translation"], float) for b in BODIES}
        euler = {b: np.asarray(bodies[b]["rotation"], float) for b in BODIES}
    except MotionImportError:
        raise
    except RecursionError:  # json's decoder recurses per nesting level
        raise MotionImportError(path, "not OpenCap body kinematics JSON (nested too deeply)") from None
    except (ValueError, KeyError, TypeError) as e:
        raise MotionImportError(path, f"not OpenCap body kinematics JSON ({type(e).__name__}: {str(e)[:80]})") from None
    n = t.size
    if t.ndim != 1:
        raise MotionImportError(path, f"time must be a list of numbers, got shape {list(t.shape)[:4]}")
    fps = check_times(path, t)
    max_rad = np.radians(MAX_ANGLE_DEG)
    for b in BODIES:
        if trans[b].shape != (n, 3) or euler[b].shape != (n, 3):
            raise MotionImportError(path, f"body {b}: translation and rotation must be [{n}][3]")
        for what, v, limit, unit in (("translation", trans[b], MAX_COORD_M, "m"),
                                     ("rotation", euler[b], max_rad, "rad")):
            bad = ~(np.abs(v) <= limit).all(axis=1)  # nan compares False: caught too
            if bad.any():
                k = int(np.argmax(bad))
                raise MotionImportError(path, f"body {b}: {what} {np.abs(v[k]).max():.3g} is not finite or beyond "
                                        f"+-{limit:.4g} {unit}", frame=k)
    c = up_rotation(up or "y")
    pos = {b: trans[b] @ c.T for b in BODIES}
    # columns (forward, left, up) of each body frame in the project frame: OpenSim's x, -z, y
    frame = {}
    for b in BODIES:
        r = c @ Rotation.from_euler("XYZ", euler[b]).as_matrix()
        frame[b] = np.stack([r[..., :, 0], -r[..., :, 2], r[..., :, 1]], axis=-1)
    pts: dict[str, np.ndarray] = {}
    for s, side, sign in (("L", "l", 1.0), ("R", "r", -1.0)):
        lateral = lambda body: sign * frame[body][..., :, 1]  # noqa: E731 - left axis, outward on each side
        pts[f"{s}HJC"] = pos[f"femur_{side}"]
        pts[f"{s}KJC"] = pos[f"tibia_{side}"]
        pts[f"{s}AJC"] = pos[f"talus_{side}"]
        pts[f"{s}KNE"] = pts[f"{s}KJC"] + LATERAL_M * lateral(f"femur_{side}")
        pts[f"{s}ANK"] = pts[f"{s}AJC"] + LATERAL_M * lateral(f"tibia_{side}")
        pts[f"{s}SJC"] = pos[f"humerus_{side}"]
        pts[f"{s}EJC"] = pos[f"ulna_{side}"]
        pts[f"{s}ELB"] = pts[f"{s}EJC"] + LATERAL_M * lateral(f"humerus_{side}")
        pts[f"{s}WJC"] = pos[f"hand_{side}"]
        pts[f"{s}WRA"] = pts[f"{s}WJC"] + WRIST_HALF_M * lateral(f"hand_{side}")
        pts[f"{s}WRB"] = pts[f"{s}WJC"] - WRIST_HALF_M * lateral(f"hand_{side}")
        pts[f"{s}FIN"] = pts[f"{s}WJC"] - FINGER_M * frame[f"hand_{side}"][..., :, 2]
    torso_up = frame["torso"][..., :, 2]
    pts["NECK"] = pts["UTHORAX"] = 0.5 * (pts["LSJC"] + pts["RSJC"]) + NECK_M * torso_up
    pts["HEADC"] = pts["NECK"] + HEAD_M * torso_up
    rel = Rotation.from_matrix(np.einsum("fba,fbc->fac", frame["pelvis"], frame["torso"]))
    frames = {"pelvis": frame["pelvis"], "thorax": frame["torso"], "head": frame["torso"],
              "Lfoot": frame["calcn_l"], "Rfoot": frame["calcn_r"]}
    for seg, frac in (("lumbar1", 1 / 3), ("lumbar2", 2 / 3)):
        frames[seg] = frame["pelvis"] @ Rotation.from_rotvec(rel.as_rotvec() * frac).as_matrix()
    check_extent(path, pts)
    info = {"format": "opencap-json", "rig": "c3d", "units": "m", "metres_per_unit": 1.0, "up": up or "y",
            "source_frames": n, "bodies": len(bodies)}
    # the default pose (every body frame the ground's) is the neutral of every frame
    return SourceMotion(str(path), fps, pts, frames, {k: np.eye(3) for k in frames}, "c3d", info)


__all__ = ["read_opencap", "BODIES"]
