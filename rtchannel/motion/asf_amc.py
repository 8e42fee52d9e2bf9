"""ASF/AMC motion capture (the CMU database's native format, also HDM05's): an ASF skeleton file and an AMC
file of joint angles per frame.

ASF: ``:units`` (``length`` L: one file unit is 1/L inches, so metres per unit = 0.0254 / L; ``angle``
deg or rad), ``:root`` (``order`` of the AMC root channels, ``axis`` order of the root orientation,
``position``, ``orientation``), ``:bonedata`` (per bone: ``name``, ``direction`` (unit, in the world
frame of the zero pose), ``length``, ``axis`` angles and their order giving the bone's local frame C,
``dof`` rx ry rz ...) and ``:hierarchy``. AMC: ``:DEGREES``/``:RADIANS``, then per frame its number and one
line per bone: the root's channels in the root's ``order``, each bone's in its ``dof`` order.

Forward kinematics (Acclaim's definition): a bone's global rotation is G = G_parent C M C^-1, with M the
motion rotation of its dof angles (applied in the listed order about fixed axes) and C the rotation of its
``axis`` angles; its end lies at E = E_parent + G (length x direction); the root's E is its position. In
the zero pose every G is the identity (the ASF's rest pose).

The bones take the names of the cgspeed CMU BVH conversion (lfemur -> LeftUpLeg, ...) with points at the
bones' starts, as BVH joints are, and the same joint map retargets them (`rigs.JOINT_MAPS["cmu"]`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from rtchannel.motion.bvh import MAX_OFFSET
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.source import MAX_ANGLE_DEG, MAX_SOURCE_FRAMES, SourceMotion, check_extent, up_rotation

MAX_ASF_BYTES = 1 << 20  # a skeleton is a few kB
MAX_AMC_BYTES = 1 << 30
INCH_M = 0.0254
ROOT_CHANNELS = ("TX", "TY", "TZ", "RX", "RY", "RZ")
DOF_CHANNELS = ("rx", "ry", "rz")
# ASF bone -> cgspeed BVH joint (the CMU conversion everyone uses)
BVH_NAMES = {
    "root": "Hips", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
    "upperneck": "Neck1", "head": "Head",
    **{f"{s}{a}": f"{S}{b}" for s, S in (("l", "Left"), ("r", "Right")) for a, b in (
        ("femur", "UpLeg"), ("tibia", "Leg"), ("foot", "Foot"), ("toes", "ToeBase"), ("clavicle", "Shoulder"),
        ("humerus", "Arm"), ("radius", "ForeArm"), ("wrist", "Hand"), ("hand", "FingerBase"),
        ("fingers", "HandIndex1"))},
    "lhipjoint": "LHipJoint", "rhipjoint": "RHipJoint", "lthumb": "LThumb", "rthumb": "RThumb",
}


@dataclass
class Bone:
    """One ASF bone: unit direction [3] and length (file units), axis rotation C [3, 3], dof names."""

    name: str
    direction: np.ndarray
    length: float
    c: np.ndarray
    dof: list[str]


@dataclass
class Skeleton:
    """An ASF skeleton: metres per unit, whether angles are degrees, the root's channel order and axis
    rotation, bones by name, each bone's parent (the root's children have parent "root") and the file's name
    (for messages)."""

    metres_per_unit: float
    degrees: bool
    root_order: list[str]
    root_c: np.ndarray
    bones: dict[str, Bone]
    parent: dict[str, str]
    name: str = "the ASF"


def _euler(order: str, angles, degrees: bool) -> np.ndarray:
    """Rotation of `angles` applied in `order` (e.g. "XYZ": x first) about fixed axes."""
    return Rotation.from_euler(order.lower(), angles, degrees=degrees).as_matrix()


def _text(path: Path, limit: int) -> list[str]:
    if not path.is_file():
        raise MotionImportError(path, "no such file")
    if path.stat().st_size > limit:
        raise MotionImportError(path, f"file larger than {limit >> 20} MiB")
    data = path.read_bytes()
    if b"\0" in data[:65536]:
        raise MotionImportError(path, "not a text file (NUL bytes)")
    # latin-1: Vicon writes its Windows path (e.g. "Universit\xfct") into the header comment
    return data.decode("latin-1").splitlines()


def _axis_order(word: str) -> str:
    """An ASF axis order (a permutation of XYZ, e.g. "ZYX"); ValueError otherwise."""
    order = word.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"axis order {word[:12]!r} is not a permutation of XYZ")
    return order


def _numbers(words: list[str], n: int, what: str, limit: float) -> list[float]:
    """`n` finite numbers within +-`limit` from `words`; ValueError naming `what` otherwise."""
    if len(words) < n:
        raise ValueError(f"{what} needs {n} numbers")
    values = [float(w) for w in words[:n]]
    if not all(math.isfinite(v) and abs(v) <= limit for v in values):
        raise ValueError(f"{what} is not finite or beyond +-{limit:g}")
    return values


def _dof(words: list[str]) -> list[str]:
    """The rotation channels of a bone's ``dof`` line; ValueError for anything else (the forward kinematics
    has no translation or length channels, which no CMU/HDM05 skeleton uses)."""
    dof = [w.lower() for w in words]
    bad = [d for d in dof if d not in DOF_CHANNELS]
    if bad:
        what = "translation/length channels are not supported" if bad[0] in ("tx", "ty", "tz", "l") else \
            f"channels are {', '.join(DOF_CHANNELS)}"
        raise ValueError(f"dof {bad[0][:12]!r}: {what}")
    if len(set(dof)) != len(dof):
        raise ValueError("a dof channel is listed twice")
    return dof


def read_asf(path) -> Skeleton:
    """Parse an ASF skeleton; MotionImportError (file and line) for anything malformed, out of range
    (`validation.md`) or that the forward kinematics cannot use."""
    path = Path(path)
    lines = _text(path, MAX_ASF_BYTES)
    section, length_unit, degrees = "", 1.0, True
    root_order, root_axis, root_orient = ["TX", "TY", "TZ", "RX", "RY", "RZ"], "XYZ", [0.0, 0.0, 0.0]
    bones: dict[str, Bone] = {}
    parent: dict[str, str] = {}
    cur: dict | None = None
    for no, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        max_angle = MAX_ANGLE_DEG if degrees else math.radians(MAX_ANGLE_DEG)
        try:
            if words[0].startswith(":"):
                section = words[0][1:].lower()
                continue
            if section == "units":
                if words[0] == "length":
                    length_unit = float(words[1])
                elif words[0] == "angle":
                    unit = words[1].lower()
                    if not unit.startswith(("deg", "rad")):
                        raise ValueError(f"angle unit {words[1][:12]!r} is not deg or rad")
                    degrees = unit.startswith("deg")
            elif section == "root":
                if words[0] == "order":
                    root_order = [w.upper() for w in words[1:]]
                    bad = [w for w in root_order if w not in ROOT_CHANNELS]
                    if bad or len(set(root_order)) != len(root_order):
                        raise ValueError(f"root order: channels are {', '.join(ROOT_CHANNELS)}, each at most once"
                                         + (f", got {bad[0][:12]!r}" if bad else ""))
                elif words[0] == "axis":
                    root_axis = _axis_order(words[1])
                elif words[0] == "orientation":
                    root_orient = _numbers(words[1:], 3, "root orientation", max_angle)
                elif words[0] == "position":
                    _numbers(words[1:], 3, "root position", MAX_OFFSET)
            elif section == "bonedata":
                if words[0] == "begin":
                    cur = {"dof": []}
                elif words[0] == "end":
                    if cur is None or "name" not in cur or "direction" not in cur:
                        raise ValueError("a bone without name or direction")
                    d = np.asarray(cur["direction"], float)
                    if np.linalg.norm(d) == 0:
                        raise ValueError(f"bone {cur['name']!r}: zero direction")
                    if cur["name"] in bones or cur["name"] == "root":
                        raise ValueError(f"bone {cur['name']!r} is defined twice (or named root)")
                    bones[cur["name"]] = Bone(cur["name"], d / np.linalg.norm(d), float(cur.get("length", 0.0)),
                                              _euler(cur.get("order", "XYZ"), cur.get("axis", [0, 0, 0]), degrees),
                                              cur["dof"])
                    cur = None
                elif cur is not None:
                    if words[0] == "name":
                        cur["name"] = words[1]
                    elif words[0] == "direction":
                        cur["direction"] = _numbers(words[1:], 3, "direction", MAX_OFFSET)
                    elif words[0] == "length":
                        cur["length"] = _numbers(words[1:], 1, "length", MAX_OFFSET)[0]
                        if cur["length"] < 0:
                            raise ValueError("negative bone length")
                    elif words[0] == "axis":
                        cur["axis"] = _numbers(words[1:], 3, "axis", max_angle)
                        cur["order"] = _axis_order(words[4])
                    elif words[0] == "dof":
                        cur["dof"] = _dof(words[1:])
            elif section == "hierarchy" and words[0] not in ("begin", "end"):
                for child in words[1:]:
                    if parent.get(child, words[0]) != words[0]:
                        raise ValueError(f"bone {child[:40]!r} has two parents")
                    parent[child] = words[0]
        except (ValueError, IndexError) as e:
            raise MotionImportError(path, f"malformed ASF ({e})", line=no) from None
    if not bones:
        raise MotionImportError(path, "no :bonedata in the ASF file")
    missing = [b for b in bones if b not in parent]
    if missing:
        raise MotionImportError(path, f"bone {missing[0]!r} is not in the :hierarchy")
    if not 0 < length_unit < 1e6:
        raise MotionImportError(path, f"implausible :units length {length_unit}")
    return Skeleton(INCH_M / length_unit, degrees, root_order, _euler(root_axis, root_orient, degrees), bones,
                    parent, path.name)


def read_amc(path, skel: Skeleton) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(root channels [F, len(root order)], {bone: dof values [F, len(dof)]}) of an AMC file.

    Every frame (numbered 1, 2, ... or from any first number, consecutively) must give the root and every
    bone of `skel` that has a dof, each once, and no bone `skel` lacks: a frame that lacks a bone (a cut
    last frame, a take of another skeleton) is an error naming the bone, the frame (0-based) and its line,
    not a bone held at the rest pose. Angles are within +-`MAX_ANGLE_DEG` and root positions within
    +-`bvh.MAX_OFFSET` file units, as in BVH files.
    """
    path = Path(path)
    lines = _text(path, MAX_AMC_BYTES)
    degrees = skel.degrees
    need = {b for b, bone in skel.bones.items() if bone.dof} | {"root"}
    frames: list[dict[str, list[float]]] = []
    starts: list[int] = []  # line of each frame's number
    first = 1  # the first frame's number (the file's own, set when it is read)

    def complete(k: int, at_end: bool = False) -> None:
        lacking = sorted(need - frames[k].keys())
        if lacking:
            cut = " (the file ends inside it: truncated?)" if at_end and k > 0 else ""
            raise MotionImportError(path, f"the frame lacks bone {lacking[0]!r}{cut}"
                                    + (f" and {len(lacking) - 1} more" if len(lacking) > 1 else ""),
                                    line=starts[k], frame=k)

    for no, raw in enumerate(lines, 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith(":"):
            if line.upper().startswith(":RADIANS"):
                degrees = False
            elif line.upper().startswith(":DEGREES"):
                degrees = True
            continue
        words = line.split()
        if len(words) == 1 and words[0].isdigit():
            if frames:
                complete(len(frames) - 1)
                if int(words[0]) != first + len(frames):
                    raise MotionImportError(path, f"frame number {words[0][:12]} after {first + len(frames) - 1}: "
                                            "frames must be numbered consecutively", line=no, frame=len(frames))
            else:
                first = int(words[0])
            if len(frames) >= MAX_SOURCE_FRAMES:
                raise MotionImportError(path, f"more than {MAX_SOURCE_FRAMES} frames", line=no)
            frames.append({})
            starts.append(no)
            continue
        if not frames:
            raise MotionImportError(path, "values before the first frame number", line=no)
        bone = words[0]
        if bone != "root" and bone not in skel.bones:
            raise MotionImportError(path, f"bone {bone[:40]!r} is not in the skeleton {skel.name} (the take of "
                                    "another skeleton?)", line=no, frame=len(frames) - 1)
        if bone in frames[-1]:
            raise MotionImportError(path, f"bone {bone[:40]!r} twice in one frame", line=no, frame=len(frames) - 1)
        try:
            frames[-1][bone] = [float(w) for w in words[1:]]
        except ValueError:
            raise MotionImportError(path, f"bad number in {bone[:40]!r}", line=no) from None
        n_dof = len(skel.root_order) if bone == "root" else len(skel.bones[bone].dof)
        if len(words) - 1 != n_dof:
            raise MotionImportError(path, f"bone {bone!r} has {len(words) - 1} values, its "
                                    f"{'order' if bone == 'root' else 'dof'} {n_dof}", line=no, frame=len(frames) - 1)
    if len(frames) < 2:
        raise MotionImportError(path, "fewer than two frames")
    complete(len(frames) - 1, at_end=True)
    if degrees != skel.degrees:  # the AMC's own unit wins: convert to the skeleton's
        factor = 180.0 / np.pi if skel.degrees else np.pi / 180.0
    else:
        factor = 1.0
    root_rows = []
    values: dict[str, list[list[float]]] = {b: [] for b in skel.bones}
    for fr in frames:  # complete and of the right counts (checked above); bones without dof give []
        root_rows.append(fr["root"])
        for b in skel.bones:
            values[b].append(fr.get(b, []))
    root = np.asarray(root_rows, float).reshape(len(frames), len(skel.root_order))
    rot_cols = [i for i, c in enumerate(skel.root_order) if c.startswith("R")]
    root[:, rot_cols] *= factor
    out = {}
    for b, spec in skel.bones.items():
        arr = np.asarray(values[b], float).reshape(len(frames), len(spec.dof))
        rot = [i for i, d in enumerate(spec.dof) if d.startswith("r")]
        arr[:, rot] *= factor
        out[b] = arr
    max_angle = MAX_ANGLE_DEG if skel.degrees else np.radians(MAX_ANGLE_DEG)
    pos_cols = [i for i in range(len(skel.root_order)) if i not in rot_cols]
    for b, arr, limit, what in [("root", root[:, rot_cols], max_angle, "angle"),
                                ("root", root[:, pos_cols], MAX_OFFSET, "position"),
                                *((b, v, max_angle, "angle") for b, v in out.items())]:
        bad = ~(np.abs(arr) <= limit).all(axis=1)  # nan compares False: caught too
        if bad.any():
            k = int(np.argmax(bad))
            unit = "file units" if what == "position" else "deg" if skel.degrees else "rad"
            raise MotionImportError(path, f"bone {b!r}: {what} {np.abs(arr[k]).max():.3g} is not finite or beyond "
                                    f"+-{limit:g} {unit}", line=starts[k], frame=k)
    return root, out


def forward_kinematics_asf(skel: Skeleton, root: np.ndarray, values: dict[str, np.ndarray]
                           ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """({bone: global rotation G [F, 3, 3]}, {bone: start [F, 3]}, {bone: end [F, 3]}) in file units and axes;
    the root's start and end are its position."""
    n = len(root)
    order = skel.root_order
    pos = np.stack([root[:, order.index(f"T{a}")] if f"T{a}" in order else np.zeros(n) for a in "XYZ"], axis=1)
    r_axes = "".join(c[1] for c in order if c.startswith("R"))
    r_vals = root[:, [i for i, c in enumerate(order) if c.startswith("R")]]
    m_root = Rotation.from_euler(r_axes.lower(), r_vals, degrees=skel.degrees).as_matrix() if r_axes else \
        np.broadcast_to(np.eye(3), (n, 3, 3))
    g = {"root": skel.root_c @ m_root @ skel.root_c.T}
    start, end = {"root": pos}, {"root": pos}
    todo = list(skel.bones)
    while todo:  # parents first (the hierarchy may list children before their parents)
        progressed = False
        for b in list(todo):
            p = skel.parent[b]
            if p not in g:
                continue
            bone = skel.bones[b]
            rot = [d for d in bone.dof if d.startswith("r")]
            cols = [i for i, d in enumerate(bone.dof) if d.startswith("r")]
            m = (Rotation.from_euler("".join(d[1] for d in rot), values[b][:, cols], degrees=skel.degrees).as_matrix()
                 if rot else np.broadcast_to(np.eye(3), (n, 3, 3)))
            g[b] = g[p] @ (bone.c @ m @ bone.c.T)
            start[b] = end[p]
            end[b] = end[p] + np.einsum("fab,b->fa", g[b], bone.direction * bone.length)
            todo.remove(b)
            progressed = True
        if not progressed:
            raise ValueError(f"bones {todo[:3]} do not hang from the root")
    return g, start, end


def read_asf_amc(amc_path, asf_path, *, units=None, up=None) -> SourceMotion:
    """Import an AMC motion with its ASF skeleton into the project frame (metres, z up), before retargeting.

    Args:
        amc_path, asf_path: the files.
        units: metres per file unit (or a unit name); default the ASF's ``:units length`` (1/L inch).
        up: the file's up axis; default y, the ASF convention (CMU, HDM05): a guess from the frames would
            fail on takes that end lying down.
    """
    from rtchannel.motion.source import parse_units

    amc_path, asf_path = Path(amc_path), Path(asf_path)
    skel = read_asf(asf_path)
    need = {"lfemur", "rfemur", "ltibia", "lfoot", "head"}
    if not need <= set(skel.bones):
        raise MotionImportError(asf_path, f"not a CMU-topology skeleton: lacks {sorted(need - set(skel.bones))}")
    root, values = read_amc(amc_path, skel)
    try:
        g, start, end = forward_kinematics_asf(skel, root, values)
    except ValueError as e:
        raise MotionImportError(asf_path, str(e)) from None
    scale = parse_units(units) if units is not None else skel.metres_per_unit
    up_axis = up or "y"
    c_rot = up_rotation(up_axis)
    c = c_rot * scale
    points, orientations = {}, {}
    for b in ["root", *skel.bones]:
        name = BVH_NAMES.get(b, b)
        points[name] = start[b] @ c.T
        orientations[name] = np.einsum("ab,fbc->fac", c_rot, g[b])
    for b in skel.bones:  # end sites of the leaves (the joint map's bone tips)
        if b not in skel.parent.values():
            points[BVH_NAMES.get(b, b) + "/End"] = end[b] @ c.T
    check_extent(amc_path, points)
    # the zero pose (every G = I) is the ASF's rest T-pose: its orientations, turned to face +x
    left = c_rot @ (_rest_start(skel, "lfemur") - _rest_start(skel, "rfemur"))
    yaw = np.arctan2(-left[0], left[1])
    turn = Rotation.from_euler("z", -yaw).as_matrix() @ c_rot
    neutral = {name: turn for name in orientations}
    info = {"format": "asf/amc", "rig": "cmu", "skeleton": str(asf_path), "units": f"{scale} m/unit",
            "metres_per_unit": scale, "up": up_axis, "source_frames": len(root), "source_joints": len(skel.bones) + 1}
    return SourceMotion(str(amc_path), _amc_fps(amc_path), points, orientations, neutral, "cmu", info)


def _rest_start(skel: Skeleton, bone: str) -> np.ndarray:
    """Start of `bone` [3] (file units) in the zero pose: the sum of its ancestors' length x direction."""
    out, b = np.zeros(3), skel.parent[bone]
    while b != "root":
        out = out + skel.bones[b].direction * skel.bones[b].length
        b = skel.parent[b]
    return out


AMC_FPS = 120.0  # AMC files do not state their rate: CMU and HDM05 record at 120 Hz


def _amc_fps(path: Path) -> float:
    """Frame rate of an AMC file: a ``_<rate>`` suffix of its name (HDM05: ..._120.amc), else `AMC_FPS`."""
    stem = path.stem.rsplit("_", 1)
    return float(stem[1]) if len(stem) == 2 and stem[1].isdigit() and 10 <= int(stem[1]) <= 1000 else AMC_FPS


__all__ = ["Bone", "Skeleton", "read_asf", "read_amc", "forward_kinematics_asf", "read_asf_amc", "BVH_NAMES",
           "AMC_FPS"]
