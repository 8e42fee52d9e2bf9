"""Small self-made motion files for hostile-input tests (no third-party data): an ASF skeleton of the CMU
topology in metres (``:units length 0.0254``: one unit = 1/0.0254 inch = 1 m), y up, x to the person's left,
standing in a T-pose when every angle is zero, and the AMC of a person standing still; an OpenCap body
kinematics JSON and joint-position NPZ/CSV of the same still person."""
from __future__ import annotations

import json

import numpy as np

# (name, parent, direction (x left, y up, z forward), length [m], dof)
_BONES = [("lowerback", "root", (0, 1, 0), 0.12, "rx ry rz"), ("upperback", "lowerback", (0, 1, 0), 0.12, "rx ry rz"),
          ("thorax", "upperback", (0, 1, 0), 0.12, "rx ry rz"), ("lowerneck", "thorax", (0, 1, 0), 0.08, "rx ry rz"),
          ("upperneck", "lowerneck", (0, 1, 0), 0.08, "rx ry rz"), ("head", "upperneck", (0, 1, 0), 0.10, "rx ry rz")]
for _s, _x in (("l", 1), ("r", -1)):
    _BONES += [(f"{_s}hipjoint", "root", (_x, -0.5, 0), 0.12, ""),
               (f"{_s}femur", f"{_s}hipjoint", (0, -1, 0), 0.43, "rx ry rz"),
               (f"{_s}tibia", f"{_s}femur", (0, -1, 0), 0.42, "rx"),
               (f"{_s}foot", f"{_s}tibia", (0, -0.3, 1), 0.14, "rx rz"),
               (f"{_s}toes", f"{_s}foot", (0, 0, 1), 0.05, "rx"),
               (f"{_s}clavicle", "thorax", (_x, 0.2, 0), 0.17, "ry rz"),
               (f"{_s}humerus", f"{_s}clavicle", (_x, 0, 0), 0.28, "rx ry rz"),
               (f"{_s}radius", f"{_s}humerus", (_x, 0, 0), 0.25, "rx"),
               (f"{_s}wrist", f"{_s}radius", (_x, 0, 0), 0.05, "ry"),
               (f"{_s}hand", f"{_s}wrist", (_x, 0, 0), 0.08, "rx rz"),
               (f"{_s}fingers", f"{_s}hand", (_x, 0, 0), 0.04, "rx"),
               (f"{_s}thumb", f"{_s}wrist", (_x, 0, 0.5), 0.04, "rx rz")]
BONES = {b[0]: b for b in _BONES}
HIPS_Y = 0.054 + 0.43 + 0.42 + 0.042 + 0.03  # root height standing: hip joint, femur, tibia, foot drop, sole


def asf_text(root_order: str = "TX TY TZ RX RY RZ", root_axis: str = "XYZ", extra_bones=()) -> str:
    """The ASF skeleton (metres, degrees)."""
    out = [":version 1.10", ":name synthetic", ":units", "  mass 1.0", "  length 0.0254", "  angle deg", ":root",
           f"   order {root_order}", f"   axis {root_axis}", "   position 0 0 0", "   orientation 0 0 0", ":bonedata"]
    for k, (name, _p, d, length, dof) in enumerate([*_BONES, *extra_bones], 1):
        out += ["  begin", f"     id {k}", f"     name {name}", f"     direction {d[0]} {d[1]} {d[2]}",
                f"     length {length}", "     axis 0 0 0 XYZ"] + ([f"     dof {dof}"] if dof else []) + ["  end"]
    children: dict[str, list[str]] = {}
    for name, parent, *_ in [*_BONES, *extra_bones]:
        children.setdefault(parent, []).append(name)
    out += [":hierarchy", "  begin"] + [f"    {p} {' '.join(c)}" for p, c in children.items()] + ["  end"]
    return "\n".join(out) + "\n"


def amc_frames(n: int = 60, sway_deg: float = 5.0) -> list[dict[str, list[float]]]:
    """`n` frames of a person standing, swaying the lower back by +-`sway_deg` (values per bone)."""
    frames = []
    for k in range(n):
        fr = {"root": [0.0, HIPS_Y, 0.0, 0.0, 0.0, 0.0]}
        for name, _p, _d, _l, dof in _BONES:
            if dof:
                fr[name] = [0.0] * len(dof.split())
        fr["lowerback"][0] = sway_deg * np.sin(2 * np.pi * k / n)
        frames.append(fr)
    return frames


def amc_text(frames=None, header=":FULLY-SPECIFIED\n:DEGREES\n") -> str:
    """The AMC text of `frames` (default `amc_frames()`)."""
    frames = amc_frames() if frames is None else frames
    lines = [header.rstrip("\n")]
    for k, fr in enumerate(frames, 1):
        lines.append(str(k))
        lines += [f"{b} " + " ".join(repr(float(v)) for v in vals) for b, vals in fr.items()]
    return "\n".join(lines) + "\n"


def write_asf_amc(folder, frames=None, **asf_kwargs):
    """(amc path, asf path) written into `folder`."""
    asf, amc = folder / "actor.asf", folder / "take.amc"
    asf.write_text(asf_text(**asf_kwargs))
    amc.write_text(amc_text(frames))
    return amc, asf


def standing_joints(n: int = 60, fps: float = 60.0) -> tuple[list[str], np.ndarray]:
    """(names, positions [n, J, 3] m, z up) of a 1.7 m person standing still facing +x."""
    pts = {"left_hip": (0, 0.09, 0.95), "right_hip": (0, -0.09, 0.95), "left_knee": (0, 0.09, 0.52),
           "right_knee": (0, -0.09, 0.52), "left_ankle": (0, 0.09, 0.09), "right_ankle": (0, -0.09, 0.09),
           "left_shoulder": (0, 0.18, 1.42), "right_shoulder": (0, -0.18, 1.42), "left_elbow": (0, 0.2, 1.14),
           "right_elbow": (0, -0.2, 1.14), "left_wrist": (0, 0.21, 0.88), "right_wrist": (0, -0.21, 0.88),
           "neck": (0, 0, 1.5), "head": (0, 0, 1.62), "left_toe": (0.15, 0.09, 0.02), "right_toe": (0.15, -0.09, 0.02),
           "left_heel": (-0.05, 0.09, 0.02), "right_heel": (-0.05, -0.09, 0.02)}
    pos = np.repeat(np.array(list(pts.values()), float)[None], n, axis=0)
    pos[:, :, 0] += 0.01 * np.sin(np.linspace(0, 2 * np.pi, n))[:, None]  # a little sway
    return list(pts), pos


def joints_csv_text(names, pos, fps: float = 60.0) -> str:
    """The joint-position CSV (time,<name>_x,_y,_z,...) of `pos` [F, J, 3]."""
    cols = ["time"] + [f"{n}_{a}" for n in names for a in "xyz"]
    t = np.arange(len(pos)) / fps
    rows = np.column_stack([t, pos.reshape(len(pos), -1)])
    return ",".join(cols) + "\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows) + "\n"


def opencap_doc(n: int = 60, fps: float = 100.0) -> dict:
    """OpenCap body kinematics of a person standing still (y up, OpenSim default pose: every body frame the
    ground's), translations of a 1.7 m adult."""
    from rtchannel.motion.opencap import BODIES

    y = {"pelvis": 0.95, "femur": 0.92, "tibia": 0.5, "talus": 0.08, "calcn": 0.04, "torso": 1.05,
         "humerus": 1.42, "ulna": 1.14, "hand": 0.88}
    z = {"pelvis": 0.0, "torso": 0.0, "femur": 0.09, "tibia": 0.09, "talus": 0.09, "calcn": 0.09,
         "humerus": 0.18, "ulna": 0.2, "hand": 0.21}
    bodies = {}
    for b in BODIES:
        base, _, side = b.partition("_")
        zz = z[base] * (1 if side == "r" else -1 if side == "l" else 0)
        bodies[b] = {"translation": [[0.0, y[base], zz]] * n, "rotation": [[0.0, 0.0, 0.0]] * n}
    return {"time": list(np.arange(n) / fps), "bodies": bodies}


def write_opencap(path, doc=None) -> None:
    path.write_text(json.dumps(opencap_doc() if doc is None else doc))
