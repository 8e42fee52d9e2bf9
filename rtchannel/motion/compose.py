"""Motion composition: walks back and forth (legs joined by turns on the spot) and fixed-length clips.

Real recordings have a fixed length (the Glasgow dataset: 5 s, walks 10 s) in which a walker goes
toward and away from the radar several times; these helpers build such motions from one straight walk.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from rtchannel.motion.pose import Motion
from processing.errors import InputError

ROOT = 0  # the hips: the rig's root joint
# placement bounds, as procedural motions' (`ProceduralParams`): a heading beyond +-10 turns is a typo or
# corruption, a start beyond `source.MAX_COORD_M` (100 m, the largest capture volume) is no room
MAX_HEADING_DEG = 3600.0
MAX_START_M = 100.0


def _rz(angle: float) -> np.ndarray:
    return Rotation.from_euler("z", angle).as_matrix()


def _about_vertical(motion: Motion, angle: float, centre_xy) -> Motion:
    c = np.array([centre_xy[0], centre_xy[1], 0.0])
    return motion.transformed(0.0, -c).transformed(angle, c)


def turn_frames(pos_a, rot_a, pos_b, rot_b, n: int) -> tuple[np.ndarray, np.ndarray]:
    """`n` frames [n, J, 3], [n, J, 3, 3] strictly between pose A and pose B (B facing the other way): the
    body turns 180 degrees about the vertical through its hips while its pose blends from A's to B's
    (rotations by slerp, hips-relative positions linearly in a common heading) and its hips move from A's
    to B's, with a smoothstep profile (at rest at both ends)."""
    s = (np.arange(1, n + 1) / (n + 1))
    s = s * s * (3 - 2 * s)
    back = _rz(-np.pi)
    off_a = pos_a - pos_a[ROOT]
    off_b = (pos_b - pos_b[ROOT]) @ back.T  # B's pose seen in A's heading
    rot_b = np.einsum("ab,jbc->jac", back, rot_b)
    pos = np.empty((n, *pos_a.shape))
    rot = np.empty((n, *rot_a.shape))
    for j in range(pos_a.shape[0]):
        key = Rotation.from_matrix(np.stack([rot_a[j], rot_b[j]]))
        rot[:, j] = Slerp([0.0, 1.0], key)(s).as_matrix()
    for k, sk in enumerate(s):
        turn = _rz(np.pi * sk)
        pos[k] = ((1 - sk) * off_a + sk * off_b) @ turn.T + (1 - sk) * pos_a[ROOT] + sk * pos_b[ROOT]
        rot[k] = np.einsum("ab,jbc->jac", turn, rot[k])
    return pos, rot


def back_and_forth(leg: Motion, legs: int, turn_s: float) -> Motion:
    """`legs` passes of the straight walk `leg`, every second one turned 180 degrees about the vertical
    through the midpoint of its hips' path (so it returns to the start), joined by turns on the spot
    lasting `turn_s` seconds (`turn_frames`). One leg returns `leg` unchanged."""
    if not (isinstance(legs, (int, np.integer)) and 1 <= legs <= 100):
        raise InputError(f"legs must be an integer 1..100, got {legs!r}")
    if not 0 < turn_s <= 10:
        raise InputError(f"turn_s must be in (0, 10] s, got {turn_s}")
    if legs == 1:
        return leg
    mid = 0.5 * (leg.positions[0, ROOT, :2] + leg.positions[-1, ROOT, :2])
    back = _about_vertical(leg, np.pi, mid)
    n_turn = max(1, int(round(turn_s * leg.fps)) - 1)
    pos, rot = [leg.positions], [leg.rotations]
    for k in range(1, legs):
        nxt = back if k % 2 else leg
        tp, tr = turn_frames(pos[-1][-1], rot[-1][-1], nxt.positions[0], nxt.rotations[0], n_turn)
        pos += [tp, nxt.positions]
        rot += [tr, nxt.rotations]
    return replace(leg, positions=np.concatenate(pos), rotations=np.concatenate(rot),
                   params={**leg.params, "back_and_forth": {"legs": int(legs), "turn_s": float(turn_s)}})


def fit_clip(motion: Motion, clip_s: float, lead: float = 0.5, start_s: float | None = None) -> Motion:
    """The motion as a recording of exactly `clip_s` seconds. With `start_s` [s] the motion's first frame
    sits at that time of the recording, its first pose held before it; a negative `start_s` starts the
    recording -start_s seconds into the motion (a recording begun late). Without it a shorter motion is
    padded by holding its first and last pose, a share `lead` in [0, 1] of the padding before it. Whatever
    runs past `clip_s` is cut; a recording that outlasts the motion holds its last pose."""
    if not 0 < clip_s <= 600:
        raise InputError(f"clip_s must be in (0, 600] s, got {clip_s}")
    if not 0 <= lead <= 1:
        raise InputError(f"lead must be in [0, 1], got {lead}")
    if start_s is not None and not -motion.duration < start_s < clip_s:
        raise InputError(f"start_s {start_s} s leaves nothing of a {motion.duration:.2f} s motion in a {clip_s} s clip")
    n = int(round(clip_s * motion.fps)) + 1
    if start_s is not None:
        first = int(round(start_s * motion.fps))  # recording frame of the motion's first frame
        idx = np.clip(np.arange(n) - first, 0, motion.n_frames - 1)
    elif motion.n_frames >= n:
        idx = np.arange(n)
    else:
        pad = n - motion.n_frames
        before = int(round(lead * pad))
        idx = np.concatenate([np.zeros(before, int), np.arange(motion.n_frames),
                              np.full(pad - before, motion.n_frames - 1)])
    clip = {"clip_s": float(clip_s), "lead": float(lead)} if start_s is None else \
        {"clip_s": float(clip_s), "start_s": float(start_s)}
    return replace(motion, positions=motion.positions[idx], rotations=motion.rotations[idx],
                   params={**motion.params, "clip": clip})


def clip_start_anywhere(duration_s: float, clip_s: float, u: float, overhang: float) -> float:
    """Start time [s] of a `duration_s` motion in a `clip_s` recording for `fit_clip`, at the point `u` in
    [0, 1] of the range of starts that keep all but the share `overhang` of the motion inside the recording:
    from -overhang * duration (the recording begins inside the motion) to clip_s - (1 - overhang) * duration
    (it ends before the motion does); for a motion longer than that allows, the other way round."""
    if not (0 <= u <= 1 and 0 <= overhang < 1 and duration_s > 0 and clip_s > 0):
        raise InputError(f"clip_start_anywhere: u {u}, overhang {overhang}, duration {duration_s} s, clip {clip_s} s")
    lo, hi = -overhang * duration_s, clip_s - (1 - overhang) * duration_s
    lo, hi = min(lo, hi), max(lo, hi)
    eps = 1e-3 * min(duration_s, clip_s)  # fit_clip needs -duration < start < clip
    return float(np.clip(lo + u * (hi - lo), -duration_s + eps, clip_s - eps))


def centre_walk(motion: Motion, back_and_forth_legs: int = 1) -> Motion:
    """A walk moved horizontally so that its path is centred on the origin (as procedural walks are): it
    then passes the room centre whatever its heading and length. The middle of a one-way walk is that of its
    end points; a back-and-forth walk (`back_and_forth_legs` > 1) may end where it began, so its middle is
    the middle of the hips' extent."""
    hips = motion.positions[:, 0, :2]
    mid = (0.5 * (hips.min(axis=0) + hips.max(axis=0)) if back_and_forth_legs > 1 else 0.5 * (hips[0] + hips[-1]))
    return motion.transformed(0.0, (-mid[0], -mid[1], 0.0))


def check_placement(start=None, heading_deg: float | None = None, start_name: str = "--start",
                    heading_name: str = "--heading") -> None:
    """InputError naming the option unless `start` (x, y) [m] lies within +-`MAX_START_M` and `heading_deg`
    [deg] within +-`MAX_HEADING_DEG` (the bounds of procedural placement), both finite."""
    if start is not None and not all(abs(float(x)) <= MAX_START_M for x in start):  # nan fails too
        raise InputError(f"{start_name}: {' '.join(f'{float(x):g}' for x in start)} m: each coordinate must lie within "
                         f"+-{MAX_START_M:g} m")
    if heading_deg is not None and not abs(float(heading_deg)) <= MAX_HEADING_DEG:
        raise InputError(f"{heading_name}: {float(heading_deg):g} deg is outside +-{MAX_HEADING_DEG:g} deg")


def place_take(motion: Motion, start=None, heading_deg: float | None = None, trim=None) -> Motion:
    """An imported take placed in the room: trimmed first, turned about its first frame's hips, then moved to its
    start; without a start a walk is centred on the origin like a procedural one (`centre_walk`), any other take
    starts over the origin as imported. InputError (naming --trim, --start or --heading) for a window outside the
    take or a placement beyond procedural motions' bounds (`check_placement`).

    Args:
        motion: the imported `Motion`.
        start: (x, y) [m] of the hips' ground point at the start, or None.
        heading_deg: direction faced at the start [deg, counter-clockwise from +x], or None (as imported).
        trim: (t0, t1) [s] of the take to keep, or None (all of it).
    """
    from rtchannel.motion.augment import augment

    check_placement(start, heading_deg)
    if trim is not None and not 0 <= trim[0] < trim[1]:
        raise InputError(f"--trim: need 0 <= START < END seconds, got {trim[0]:g} {trim[1]:g}")
    if trim is not None and trim[0] >= motion.duration:
        raise InputError(f"--trim: START {trim[0]:g} s lies after the take's end ({motion.duration:.2f} s)")
    out = augment(motion, heading_deg=heading_deg or 0.0, trim=None if trim is None else (trim[0], trim[1]),
                  start=None if start is None else tuple(start))
    if start is None and motion.activity == "walk":
        out = centre_walk(out)
    return out
