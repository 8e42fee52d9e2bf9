"""BVH import (own line-numbered parser, channel data through numpy) and BVH export of a `Motion`.

The grammar is small, so it is parsed here rather than by bvhio, whose reader loops forever on a file
cut inside the hierarchy, cannot take text (a UTF-8 byte-order mark makes it refuse the file), stores
offsets as float32 and reports errors as SyntaxError tuples. Every error is a `MotionImportError`
naming the file and line (and frame). Limits (`rtchannel.motion.source`): frame time 0.1 ms..1 s, at most
`MAX_SOURCE_FRAMES` frames and `MAX_VALUES` channel values, angles within +-`MAX_ANGLE_DEG`, every point
within `MAX_COORD_M` of the origin, header frame count equal to the data rows.
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from processing.atomic import write_text_atomic
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.rigs import JOINT_MAPS, cc_neutral
from rtchannel.motion.source import (FILE_FPS_RANGE, MAX_ANGLE_DEG, MAX_DURATION_S, MAX_SOURCE_FRAMES,
                                     SourceMotion, check_extent, guess_units, guess_up, parse_units, up_rotation)
from rtchannel.motion.pose import Motion
from processing.errors import InputError

END = "/End"  # suffix naming a joint's End Site point
MAX_BVH_BYTES = 1 << 30  # text; ~10 bytes per value, so MAX_VALUES of text is ~0.5 GB
MAX_VALUES = 50_000_000  # frames x channels: 400 MB as float64 (e.g. 2.3 h of the 96-channel CMU rig at 60 Hz)
MAX_JOINTS = 1000  # the largest rigs (iClone CC with fingers and face) have ~250 joints
MAX_LINES = 2 * MAX_SOURCE_FRAMES + 10 * MAX_JOINTS  # data rows, hierarchy and some blank lines
MAX_OFFSET = 1e6  # |OFFSET| in file units: 10 km in mm; larger is a corrupted number
_CHANNELS = {f"{a}{k}": f"{a.upper()}{k}" for a in "xyzXYZ" for k in ("position", "rotation")}


class _Tokens:
    """Whitespace-separated tokens of the HIERARCHY section with their (1-based) line numbers."""

    def __init__(self, path: Path, lines: list[str], stop: int):
        self.path = path
        self.items = [(tok, i + 1) for i, ln in enumerate(lines[:stop]) for tok in ln.split()]
        self.k = 0
        self.last_line = stop

    def next(self, what: str) -> tuple[str, int]:
        if self.k >= len(self.items):
            raise MotionImportError(self.path, f"file ends inside the HIERARCHY section while expecting {what} "
                                    "(truncated?)", line=self.last_line)
        self.k += 1
        return self.items[self.k - 1]

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok != word:
            raise MotionImportError(self.path, f"expected {word!r}, found {tok[:40]!r}", line=line)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            v = float(tok)
        except ValueError:
            raise MotionImportError(self.path, f"{what} is not a number: {tok[:40]!r}", line=line) from None
        if not math.isfinite(v) or abs(v) > MAX_OFFSET:
            raise MotionImportError(self.path, f"{what} {tok[:40]} is not finite or beyond +-{MAX_OFFSET:g}", line=line)
        return v


def _parse_hierarchy(path: Path, lines: list[str], motion_at: int) -> dict:
    """Joints (depth-first), parents, offsets [J, 3], channels, end sites of the HIERARCHY section."""
    tk = _Tokens(path, lines, motion_at)
    tk.expect("HIERARCHY")
    names: list[str] = []
    lines_of: dict[str, int] = {}
    parents, offsets, channels, ends = [], [], [], {}
    stack: list[int] = []  # open joints

    def offset(owner: str) -> list[float]:
        tk.expect("OFFSET")
        return [tk.number(f"OFFSET of {owner}") for _ in range(3)]

    def open_joint(kind_line: int) -> None:
        name, line = tk.next("a joint name")
        if name in ("{", "}"):
            raise MotionImportError(path, "joint name missing", line=line)
        if name in lines_of:
            raise MotionImportError(path, f"joint {name[:40]!r} defined twice (first at line {lines_of[name]})",
                                    line=line)
        if len(names) >= MAX_JOINTS:
            raise MotionImportError(path, f"more than {MAX_JOINTS} joints", line=line)
        lines_of[name] = line
        tk.expect("{")
        names.append(name)
        parents.append(stack[-1] if stack else -1)
        offsets.append(offset(name))
        chans: list[str] = []
        if tk.k < len(tk.items) and tk.items[tk.k][0] == "CHANNELS":
            tk.next("CHANNELS")
            n = tk.number(f"channel count of {name}")
            _, cline = tk.items[tk.k - 1]
            if not n.is_integer() or not 0 <= n <= 6:
                raise MotionImportError(path, f"channel count of {name[:40]} must be an integer 0..6, got {n:g}",
                                        line=cline)
            for _ in range(int(n)):
                tok, ln = tk.next(f"a channel name of {name}")
                canon = _CHANNELS.get(tok)
                if canon is None:
                    raise MotionImportError(path, f"unknown channel {tok[:40]!r} (use Xposition ... Zrotation)",
                                            line=ln)
                if canon in chans:
                    raise MotionImportError(path, f"channel {canon} listed twice for joint {name[:40]}", line=ln)
                chans.append(canon)
        channels.append(chans)
        stack.append(len(names) - 1)

    tk.expect("ROOT")
    open_joint(0)
    while stack:
        tok, line = tk.next("JOINT, End Site or '}'")
        if tok == "JOINT":
            open_joint(line)
        elif tok == "End":
            tk.expect("Site")
            tk.expect("{")
            ends[stack[-1]] = np.array(offset(f"End Site of {names[stack[-1]]}"))
            tk.expect("}")
        elif tok == "}":
            stack.pop()
        else:
            raise MotionImportError(path, f"expected JOINT, End Site or '}}', found {tok[:40]!r}", line=line)
    if tk.k < len(tk.items):
        tok, line = tk.items[tk.k]
        raise MotionImportError(path, f"unexpected {tok[:40]!r} after the root joint (one ROOT per file)", line=line)
    for j in range(len(names)):  # a leaf without End Site ends where it starts
        if j not in parents and j not in ends:
            ends[j] = np.zeros(3)
    return dict(names=names, parents=np.array(parents), offsets=np.array(offsets, float), channels=channels,
                end_sites=ends)


def _motion_header(path: Path, lines: list[str], motion_at: int) -> tuple[int, float, int]:
    """(frame count, frame time [s], index of the first data line) from the lines after MOTION."""
    if lines[motion_at].split() != ["MOTION"]:
        raise MotionImportError(path, "MOTION line must hold the word MOTION only", line=motion_at + 1)
    rest = [i for i in range(motion_at + 1, min(len(lines), motion_at + 50)) if lines[i].strip()][:2]
    if len(rest) < 2:
        raise MotionImportError(path, "MOTION header (Frames, Frame Time) is missing (truncated?)", line=len(lines))
    i_frames, i_time = rest
    tok = lines[i_frames].split()
    if len(tok) != 2 or tok[0] != "Frames:":
        raise MotionImportError(path, "expected 'Frames: N' after MOTION", line=i_frames + 1)
    try:
        n = int(tok[1])
    except ValueError:
        raise MotionImportError(path, f"frame count is not an integer: {tok[1][:40]!r}", line=i_frames + 1) from None
    if not 1 <= n <= MAX_SOURCE_FRAMES:
        raise MotionImportError(path, f"frame count {n} outside 1..{MAX_SOURCE_FRAMES}", line=i_frames + 1)
    tok = lines[i_time].split()
    if len(tok) != 3 or tok[:2] != ["Frame", "Time:"]:
        raise MotionImportError(path, "expected 'Frame Time: SECONDS' after the frame count", line=i_time + 1)
    try:
        dt = float(tok[2])
    except ValueError:
        raise MotionImportError(path, f"frame time is not a number: {tok[2][:40]!r}", line=i_time + 1) from None
    lo, hi = 1.0 / FILE_FPS_RANGE[1], 1.0 / FILE_FPS_RANGE[0]
    if not lo <= dt <= hi:  # also refuses nan and inf
        raise MotionImportError(path, f"frame time {tok[2][:40]} s outside {lo:g}..{hi:g} s "
                                f"({FILE_FPS_RANGE[0]:g}..{FILE_FPS_RANGE[1]:g} frames/s)", line=i_time + 1)
    if n * dt > MAX_DURATION_S:
        raise MotionImportError(path, f"{n} frames of {dt:g} s last {n * dt:.0f} s, more than the "
                                f"{MAX_DURATION_S:.0f} s limit (split the take)", line=i_frames + 1)
    return n, dt, i_time + 1


def _parse_frames(path: Path, lines: list[str], first: int, n_frames: int,
                  n_channels: int) -> tuple[np.ndarray, np.ndarray]:
    """Channel data [F, C] and the 1-based line number of each frame."""
    rows = [i for i in range(first, len(lines)) if lines[i].strip()]
    if n_frames * max(n_channels, 1) > MAX_VALUES:
        raise MotionImportError(path, f"{n_frames} frames x {n_channels} channels exceed the limit of "
                                f"{MAX_VALUES} values", line=first)
    for k, i in enumerate(rows[:n_frames]):
        got = len(lines[i].split())
        if got != n_channels:
            raise MotionImportError(path, f"expected {n_channels} channel values, found {got} "
                                    "(truncated or corrupted line)", line=i + 1, frame=k)
    if len(rows) < n_frames:
        last = rows[-1] + 1 if rows else first
        raise MotionImportError(path, f"truncated: header says {n_frames} frames, file holds {len(rows)} "
                                f"(frame {len(rows)} is missing)", line=last + 1, frame=len(rows))
    if len(rows) > n_frames:
        raise MotionImportError(path, f"header says {n_frames} frames but the file holds {len(rows)} data rows "
                                "(wrong Frames: count or appended data)", line=rows[n_frames] + 1, frame=n_frames)
    line_no = np.asarray(rows, dtype=np.int64) + 1
    if n_channels == 0:
        return np.zeros((n_frames, 0)), line_no
    try:  # numpy's C parser: no Python object per value
        data = np.loadtxt(io.StringIO("\n".join(lines[i] for i in rows)), dtype=float, ndmin=2)
    except ValueError:
        for k, i in enumerate(rows):
            for tok in lines[i].split():
                try:
                    float(tok)
                except ValueError:
                    raise MotionImportError(path, f"not a number: {tok[:40]!r}", line=i + 1, frame=k) from None
        raise
    data = data.reshape(n_frames, n_channels)
    bad = ~np.isfinite(data)
    if bad.any():
        k = int(np.argwhere(bad)[0, 0])
        raise MotionImportError(path, "non-finite channel value", line=int(line_no[k]), frame=k)
    return data, line_no


def read_bvh_raw(path) -> dict:
    """Parse a BVH file: joints, parents, offsets, channels, end sites, frame time, channel data.

    Returns a dict with ``names`` [J], ``parents`` [J], ``offsets`` [J, 3] and ``end_sites`` {index:
    [3]} (file units), ``channels`` (list per joint), ``frame_time`` (s), ``data`` [F, C] and
    ``line_of_frame`` [F] (1-based line numbers, for messages).
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_BVH_BYTES:
            raise MotionImportError(path, f"file of {size / 2**20:.0f} MiB exceeds the {MAX_BVH_BYTES >> 20} MiB limit")
        text = path.read_bytes().decode("utf-8-sig", errors="replace")  # a byte-order mark is allowed
    except OSError as exc:
        raise MotionImportError(path, f"cannot read file: {exc.strerror or exc}") from None
    n_lines = max(text.count("\n"), text.count("\r")) + 1  # counted before splitting: a line costs ~60 B
    if n_lines > MAX_LINES:
        raise MotionImportError(path, f"more than {MAX_LINES} lines: not a motion take (the frame limit is "
                                f"{MAX_SOURCE_FRAMES})")
    lines = text.splitlines()
    if not lines or lines[0].split()[:1] != ["HIERARCHY"]:
        raise MotionImportError(path, "not a BVH file (first line must be HIERARCHY)", line=1)
    motion_at = next((i for i, ln in enumerate(lines) if ln.split()[:1] == ["MOTION"]), None)
    if motion_at is None:
        raise MotionImportError(path, "file ends inside the HIERARCHY section (no MOTION line): truncated?",
                                line=len(lines))
    raw = _parse_hierarchy(path, lines, motion_at)
    n_frames, frame_time, first = _motion_header(path, lines, motion_at)
    n_ch = sum(len(c) for c in raw["channels"])
    data, line_no = _parse_frames(path, lines, first, n_frames, n_ch)
    col = 0
    for name, chans in zip(raw["names"], raw["channels"]):
        for ch in chans:
            limit, unit = (MAX_ANGLE_DEG, " deg") if ch.endswith("rotation") else (MAX_OFFSET, " file units")
            big = np.abs(data[:, col]) > limit
            if big.any():
                k = int(np.argmax(big))
                raise MotionImportError(path, f"{name[:40]} {ch} = {data[k, col]:.3g}{unit} is beyond "
                                        f"+-{limit:g}{unit}: corrupted data", line=int(line_no[k]), frame=k)
            col += 1
    return {**raw, "frame_time": float(frame_time), "data": data, "line_of_frame": line_no}


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
    if RIG_JOINTS["mixamo"] <= set(names) and "LHipJoint" not in names:
        return "mixamo"
    if {"Hips", "LeftUpLeg", "RightUpLeg", "LeftLeg", "LeftFoot"} <= set(names):
        return "cmu"
    if {"hip", "abdomen", "chest", "lThigh", "rThigh", "lShin", "lFoot", "head"} <= set(names):
        return "daz"
    best = max(RIG_JOINTS, key=lambda k: len(RIG_JOINTS[k] & set(names)))
    raise InputError(f"unknown BVH skeleton: closest known rig {best!r} lacks joints "
                     f"{', '.join(sorted(RIG_JOINTS[best] - set(names))[:8])} (known rigs: cgspeed CMU, iClone "
                     f"CC_Base, Daz/Genesis, Mixamo)")


# the joints that identify each rig (named in the error for a skeleton that matches none)
RIG_JOINTS = {"cmu": {"Hips", "LeftUpLeg", "RightUpLeg", "LeftLeg", "LeftFoot"},
              "cc": {"CC_Base_Hip", "CC_Base_L_Thigh", "CC_Base_L_Calf", "CC_Base_L_Foot"},
              "daz": {"hip", "abdomen", "chest", "lThigh", "rThigh", "lShin", "lFoot", "head"},
              "mixamo": {"Hips", "Spine", "Spine1", "Spine2", "Neck", "Head", "LeftUpLeg", "LeftLeg", "LeftFoot",
                         "RightUpLeg", "LeftArm", "LeftForeArm", "LeftHand"}}


_LEG = {"cc": ("CC_Base_L_Thigh", "CC_Base_L_Calf", "CC_Base_L_Foot", "CC_Base_Head"),
        "cmu": ("LeftUpLeg", "LeftLeg", "LeftFoot", "Head"), "daz": ("lThigh", "lShin", "lFoot", "head"),
        "mixamo": ("LeftUpLeg", "LeftLeg", "LeftFoot", "Head")}


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
    # namespaces ("mixamorig:Hips", "mixamorig1:Hips") name the exporter, not the joint
    names = raw["names"] = [n.rsplit(":", 1)[-1] for n in raw["names"]]
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
    check_extent(path, points, raw["line_of_frame"])
    orientations = {n: np.einsum("ab,fbc->fac", c_rot, rot[:, i]) for i, n in enumerate(names)}
    neutral = cc_neutral() if kind == "cc" else _zero_pose_neutral(raw, c_rot, names, JOINT_MAPS[kind]["hips"])
    info = {"format": "bvh", "rig": kind, "units": unit_name or f"{scale} m/unit", "metres_per_unit": scale,
            "up": up_axis, "source_frames": len(raw["data"]), "source_joints": len(names)}
    return SourceMotion(str(path), 1.0 / raw["frame_time"], points, orientations, neutral, kind, info)


def _zero_pose_neutral(raw: dict, c_rot: np.ndarray, names: list[str], hips: tuple[str, str]) -> dict[str, np.ndarray]:
    """Global orientations of the all-zero-channel pose (the CMU/cgspeed or Daz T-pose), turned to face +x;
    `hips` names the (left, right) hip joints."""
    rot, pos = forward_kinematics_bvh({**raw, "data": np.zeros((1, raw["data"].shape[1]))})
    idx = {n: i for i, n in enumerate(names)}
    left = c_rot @ (pos[0, idx[hips[0]]] - pos[0, idx[hips[1]]])
    yaw = np.arctan2(-left[0], left[1])
    turn = Rotation.from_euler("z", -yaw).as_matrix() @ c_rot
    return {n: turn @ rot[0, i] for i, n in enumerate(names)}


def write_bvh(motion: Motion, path, *, units: str = "cm") -> None:
    """Write a `Motion` as a CMU-named, Y-up BVH whose zero pose is the avatar's rest pose.

    Local rotations are ``R_parent^T R_j`` (rest-relative, in the world-aligned rest frame), written as
    ZYX intrinsic Euler angles; end sites are the bone tails. Units: "m", "cm" or "mm".
    """
    per_unit = parse_units(units)
    if per_unit is None:  # parse_units(None) means "not given": a written file needs a unit
        raise InputError("write_bvh: units must be given (m, cm or mm)")
    s = 1.0 / per_unit
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
    write_text_atomic(path, "\n".join(lines) + "\n")


__all__ = ["read_bvh", "read_bvh_raw", "forward_kinematics_bvh", "write_bvh", "END"]
