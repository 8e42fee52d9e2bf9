"""BVH import (hierarchy through bvhio, channel data through numpy) and BVH export of a `Motion`.

bvhio parses the HIERARCHY section. Its key-frame reader is not used: it builds one Python object per
joint and frame (slow for the ~100-joint iClone rig) and loops forever on a file cut inside the
hierarchy, so the file is checked first and the MOTION block is parsed here with line-numbered errors.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.rigs import cc_neutral
from rtchannel.motion.source import SourceMotion, guess_units, guess_up, parse_units, up_rotation
from rtchannel.body.skeleton import Motion

END = "/End"  # suffix naming a joint's End Site point


def _check_structure(path: Path, lines: list[str]) -> int:
    """Index of the MOTION line; raise if the hierarchy is cut or unbalanced (bvhio would hang)."""
    depth, motion_at = 0, None
    for i, line in enumerate(lines):
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "MOTION":
            motion_at = i
            break
        depth += tok.count("{") - tok.count("}")
        if depth < 0:
            raise MotionImportError(path, "unbalanced '}' in the HIERARCHY section", line=i + 1)
    if not lines or lines[0].split()[:1] != ["HIERARCHY"]:
        raise MotionImportError(path, "not a BVH file (first line must be HIERARCHY)", line=1)
    if motion_at is None:
        raise MotionImportError(path, "file ends inside the HIERARCHY section (no MOTION line): "
                                "truncated?", line=len(lines))
    if depth != 0:
        raise MotionImportError(path, "HIERARCHY has unbalanced braces (truncated?)", line=motion_at + 1)
    if len(lines) < motion_at + 3:
        raise MotionImportError(path, "MOTION header (Frames, Frame Time) is missing", line=len(lines))
    return motion_at


def _read_hierarchy(path: Path):
    import warnings

    with warnings.catch_warnings():  # bvhio's "import glm" deprecation notice is not the user's concern
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        import bvhio

    try:
        return bvhio.readAsBvh(str(path), loadKeyFrames=False)
    except SyntaxError as exc:
        line = exc.args[1][1] if len(exc.args) > 1 and isinstance(exc.args[1], tuple) else None
        raise MotionImportError(path, f"malformed BVH: {exc.args[0]}", line=line) from None
    except (ValueError, IndexError, TypeError) as exc:
        raise MotionImportError(path, f"malformed BVH hierarchy: {exc}") from None


def _parse_frames(path: Path, lines: list[str], first: int, n_frames: int, n_channels: int) -> np.ndarray:
    rows = [(i, ln) for i, ln in enumerate(lines[first:], start=first) if ln.strip()]
    for k, (i, ln) in enumerate(rows[:n_frames]):
        if len(ln.split()) != n_channels:
            raise MotionImportError(path, f"expected {n_channels} channel values, found {len(ln.split())} "
                                    "(truncated or corrupted line)", line=i + 1, frame=k)
    if len(rows) < n_frames:
        last = rows[-1][0] + 1 if rows else first
        raise MotionImportError(path, f"truncated: header says {n_frames} frames, file holds {len(rows)} "
                                f"(frame {len(rows)} is missing)", line=last + 1, frame=len(rows))
    try:
        data = np.array(" ".join(ln for _, ln in rows[:n_frames]).split(), dtype=float)
    except ValueError:
        for k, (i, ln) in enumerate(rows[:n_frames]):
            for tok in ln.split():
                try:
                    float(tok)
                except ValueError:
                    raise MotionImportError(path, f"not a number: {tok!r}", line=i + 1, frame=k) from None
        raise
    data = data.reshape(n_frames, n_channels)
    bad = ~np.isfinite(data)
    if bad.any():
        k = int(np.argwhere(bad)[0, 0])
        raise MotionImportError(path, "non-finite channel value", line=rows[k][0] + 1, frame=k)
    return data


def read_bvh_raw(path) -> dict:
    """Parse a BVH file: joints, parents, offsets, channels, end sites, frame time, channel data.

    Returns a dict with ``names`` [J], ``parents`` [J], ``offsets`` [J, 3] and ``end_sites`` {index:
    [3]} (file units), ``channels`` (list per joint), ``frame_time`` (s), ``data`` [F, C].
    """
    path = Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise MotionImportError(path, f"cannot read file: {exc.strerror or exc}") from None
    motion_at = _check_structure(path, lines)
    bvh = _read_hierarchy(path)
    names, parents, offsets, channels, ends = [], [], [], [], {}

    def walk(joint, parent):
        idx = len(names)
        names.append(joint.Name)
        parents.append(parent)
        offsets.append([joint.Offset.x, joint.Offset.y, joint.Offset.z])
        channels.append(list(joint.Channels))
        if not joint.Children:
            ends[idx] = np.array([joint.EndSite.x, joint.EndSite.y, joint.EndSite.z])
        for child in joint.Children:
            walk(child, idx)

    walk(bvh.Root, -1)
    if not bvh.FrameTime > 0:
        raise MotionImportError(path, f"Frame Time must be positive, got {bvh.FrameTime}", line=motion_at + 3)
    n_ch = sum(len(c) for c in channels)
    data = _parse_frames(path, lines, motion_at + 3, int(bvh.FrameCount), n_ch)
    return dict(names=names, parents=np.array(parents), offsets=np.array(offsets, float), channels=channels,
                end_sites=ends, frame_time=float(bvh.FrameTime), data=data)


def forward_kinematics_bvh(raw: dict) -> tuple[np.ndarray, np.ndarray]:
    """Global joint orientations [F, J, 3, 3] and positions [F, J, 3] (file units and axes)."""
    data = raw["data"]
    f, j = len(data), len(raw["names"])
    rot, pos = np.empty((f, j, 3, 3)), np.empty((f, j, 3))
    col = 0
    for k, (chans, parent) in enumerate(zip(raw["channels"], raw["parents"])):
        local_p = np.tile(raw["offsets"][k], (f, 1))
        order, angles = "", []
        for ch in chans:
            if ch.endswith("position"):
                local_p[:, "XYZ".index(ch[0].upper())] = data[:, col]
            elif ch.endswith("rotation"):
                order += ch[0].upper()
                angles.append(data[:, col])
            col += 1
        # BVH channels rotate about the moving axes in the listed order: intrinsic Euler angles.
        local_r = (Rotation.from_euler(order, np.stack(angles, 1), degrees=True).as_matrix()
                   if order else np.broadcast_to(np.eye(3), (f, 3, 3)))
        if parent < 0:
            rot[:, k], pos[:, k] = local_r, local_p
        else:
            rot[:, k] = rot[:, parent] @ local_r
            pos[:, k] = pos[:, parent] + np.einsum("fab,fb->fa", rot[:, parent], local_p)
    return rot, pos


def _rig_kind(names: list[str]) -> str:
    if "CC_Base_Hip" in names:
        return "cc"
    if {"Hips", "LeftUpLeg", "RightUpLeg", "LeftLeg", "LeftFoot"} <= set(names):
        return "cmu"
    raise ValueError("unknown BVH skeleton: expected the CMU/cgspeed rig (Hips, LeftUpLeg, ...) or the "
                     "iClone CC_Base_* rig")


_LEG = {"cc": ("CC_Base_L_Thigh", "CC_Base_L_Calf", "CC_Base_L_Foot", "CC_Base_Head"),
        "cmu": ("LeftUpLeg", "LeftLeg", "LeftFoot", "Head")}


def read_bvh(path, *, units=None, up=None) -> SourceMotion:
    """Import a BVH file into the project frame (metres, z up), before retargeting.

    Args:
        path: the .bvh file.
        units: file unit ("m", "cm", "mm", "in", "cmu") or metres per unit; guessed from the leg length
            when None.
        up: the file's up axis ("y", "z", "-y", ...); guessed from head-above-feet when None.
    """
    path = Path(path)
    raw = read_bvh_raw(path)
    names = raw["names"]
    try:
        kind = _rig_kind(names)
    except ValueError as exc:
        raise MotionImportError(path, str(exc)) from None
    rot, pos = forward_kinematics_bvh(raw)
    idx = {n: i for i, n in enumerate(names)}
    hip, knee, ankle, head = (idx[n] for n in _LEG[kind])
    leg = float(np.linalg.norm(raw["offsets"][knee]) + np.linalg.norm(raw["offsets"][ankle]))
    scale = parse_units(units)
    unit_name = units if isinstance(units, str) else None
    if scale is None:
        unit_name = guess_units(leg)
        if unit_name is None:
            raise MotionImportError(path, f"cannot guess the length unit from a leg length of {leg:g} "
                                    "file units; pass units=")
        scale = parse_units(unit_name)
    up_axis = up or guess_up(pos[:, head], pos[:, ankle])
    c = up_rotation(up_axis) * scale
    c_rot = up_rotation(up_axis)
    points = {n: pos[:, i] @ c.T for i, n in enumerate(names)}
    for i, off in raw["end_sites"].items():
        points[names[i] + END] = (pos[:, i] + np.einsum("fab,b->fa", rot[:, i], off)) @ c.T
    orientations = {n: np.einsum("ab,fbc->fac", c_rot, rot[:, i]) for i, n in enumerate(names)}
    neutral = cc_neutral() if kind == "cc" else _zero_pose_neutral(raw, c_rot, names)
    info = {"format": "bvh", "rig": kind, "units": unit_name or f"{scale} m/unit", "metres_per_unit": scale,
            "up": up_axis, "source_frames": len(raw["data"]), "source_joints": len(names)}
    return SourceMotion(str(path), 1.0 / raw["frame_time"], points, orientations, neutral, kind, info)


def _zero_pose_neutral(raw: dict, c_rot: np.ndarray, names: list[str]) -> dict[str, np.ndarray]:
    """Global orientations of the all-zero-channel pose (the CMU/cgspeed T-pose), turned to face +x."""
    rot, pos = forward_kinematics_bvh({**raw, "data": np.zeros((1, raw["data"].shape[1]))})
    idx = {n: i for i, n in enumerate(names)}
    left = c_rot @ (pos[0, idx["LeftUpLeg"]] - pos[0, idx["RightUpLeg"]])
    yaw = np.arctan2(-left[0], left[1])
    turn = Rotation.from_euler("z", -yaw).as_matrix() @ c_rot
    return {n: turn @ rot[0, i] for i, n in enumerate(names)}


def write_bvh(motion: Motion, path, *, units: str = "cm") -> None:
    """Write a `Motion` as a CMU-named, Y-up BVH whose zero pose is the avatar's rest pose.

    Local rotations are ``R_parent^T R_j`` (rest-relative, in the world-aligned rest frame), written as
    ZYX intrinsic Euler angles; end sites are the bone tails. Units: "m", "cm" or "mm".
    """
    s = 1.0 / parse_units(units)
    to_file = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # inverse of the y-up import rotation
    rig = motion.rig
    rest = rig.rest @ to_file.T * s
    tails = rig.tails @ to_file.T * s
    lines = ["HIERARCHY"]

    def emit(j, depth):
        pad = "  " * depth
        p = rig.parents[j]
        off = rest[j] - (rest[p] if p >= 0 else 0.0)
        lines.append(f"{pad}{'ROOT' if p < 0 else 'JOINT'} {rig.names[j]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {off[0]:.9g} {off[1]:.9g} {off[2]:.9g}")
        chans = "Xposition Yposition Zposition " if p < 0 else ""
        lines.append(f"{pad}  CHANNELS {6 if p < 0 else 3} {chans}Zrotation Yrotation Xrotation")
        kids = rig.children(j)
        for k in kids:
            emit(k, depth + 1)
        if not kids:
            e = tails[j] - rest[j]
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {e[0]:.9g} {e[1]:.9g} {e[2]:.9g}",
                          pad + "  }"])
        lines.append(pad + "}")

    emit(0, 0)
    dfs: list[int] = []  # channel columns follow the order joints appear in the hierarchy

    def visit(j):
        dfs.append(j)
        for k in rig.children(j):
            visit(k)

    visit(0)
    rot_file = np.einsum("ab,fjbc,dc->fjad", to_file, motion.rotations, to_file)
    cols = [motion.positions[:, 0] @ to_file.T * s]
    for j in dfs:
        p = rig.parents[j]
        local = rot_file[:, j] if p < 0 else np.einsum("fba,fbc->fac", rot_file[:, p], rot_file[:, j])
        cols.append(Rotation.from_matrix(local).as_euler("ZYX", degrees=True))
    data = np.concatenate(cols, axis=1)
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {1.0 / motion.fps:.8f}"]
    lines += [" ".join(f"{x:.9g}" for x in row) for row in data]
    Path(path).write_text("\n".join(lines) + "\n")


__all__ = ["read_bvh", "read_bvh_raw", "forward_kinematics_bvh", "write_bvh", "END"]
