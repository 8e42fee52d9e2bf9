"""A chair under a seated person: where the built-in chair goes for a sit/stand motion.

`chair_for(motion)` finds the seated phase from the hip joints, then places the chair (`furniture.Furniture`)
so that the person sits on it and leans against it without the two intersecting:

* seated frames: the hip-joint midpoint stays within `SEATED_BAND_M` of its lowest *sustained* height
  (the lowest level the hips stay at or below for `SUSTAIN_S`, so a landing dip does not count), and that
  height is below `SEATED_MAX_HIP_FRACTION` of the standing hip height;
* facing: the circular mean over the seated frames of the direction perpendicular to the hip axis
  (left hip - right hip rotated -90 deg);
* seat height: the procedural generator's own seat (`procedural.SEAT_HEIGHT_M` scaled with the body
  height) for a procedural sit/stand, else the median over the seated frames of the lowest skin point
  under the pelvis (the buttocks rest on the seat);
* fore-aft: the backrest's front face `back_gap` behind the rearmost skin point that lies in the
  chair's vertical span above the seat and within its width, over all frames (the back touches the
  backrest, the ischial tuberosities then lie ~0.1 m in front of the seat's rear edge), moved back in
  2.5 mm steps (up to `MAX_BACK_SHIFT_M`) while the shins touch the front legs (knees wide apart over a
  low seat); sideways: the median hip midpoint of the seated frames.

The skin is the avatar's (`lod`, default "10k", the mesh backends' default). `chair_penetration`
measures how deep the body gets into the chair's boxes; the seat is the only box a body should touch
(its skin sinks ~1 cm into it: the generator's hip-to-seat 0.095 m against ~0.086 m of avatar buttock).
"""
from __future__ import annotations

import warnings

import numpy as np

from rtchannel.motion.pose import Motion
from rtchannel.scene.furniture import (BACK_TOP_ABOVE_SEAT_M, CHAIR, LEG_SECTION_M, SEAT_DEPTH_M,
                                       SEAT_THICKNESS_M, SEAT_WIDTH_M, Furniture, chair_boxes)
from processing.errors import InputError

SEATED_ACTIVITIES = ("sit", "stand")
SUSTAIN_S = 0.3  # the hips must stay this long at a level for it to count as the seat
SEATED_BAND_M = 0.03  # frames within this of the sustained lowest hip height are seated
SEATED_MAX_HIP_FRACTION = 0.75  # seated hips are below this fraction of the standing hip height
BACK_GAP_M = 0.01  # clearance between the body and the backrest's front face
MAX_BACK_SHIFT_M = 0.10  # furthest the chair is moved back from the body to clear the legs
_SHIFT_STEP_M = 0.0025
MAX_PENETRATION_M = 0.02  # skin deeper than this inside the chair is reported (soft tissue compresses ~1-2 cm)
_PELVIS_HALF_WIDTH_M = 0.15  # region under the pelvis searched for the lowest buttock skin (1.75 m body)
_PELVIS_FORE_AFT_M = (-0.20, 0.15)


def _hips(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    r = motion.rig
    left, right = motion.positions[:, r.index("LeftUpLeg")], motion.positions[:, r.index("RightUpLeg")]
    return 0.5 * (left + right), left - right


def seated_frames(motion: Motion) -> np.ndarray:
    """Boolean [F] of the frames in which the person sits (see the module doc); raises ValueError if none."""
    from scipy.ndimage import maximum_filter1d  # here: a walk through a mesh backend never needs scipy.ndimage

    mid, _ = _hips(motion)
    z = mid[:, 2]
    n = max(1, min(len(z), int(round(SUSTAIN_S * motion.fps)) + 1))
    sustained = float(maximum_filter1d(z, n, mode="nearest").min())
    r = motion.rig
    standing = 0.5 * (r.rest[r.index("LeftUpLeg"), 2] + r.rest[r.index("RightUpLeg"), 2])
    if sustained > SEATED_MAX_HIP_FRACTION * standing:
        raise InputError(f"no seated phase: the hips never stay below {SEATED_MAX_HIP_FRACTION:g} x the standing "
                         f"hip height ({SEATED_MAX_HIP_FRACTION * standing:.2f} m) for {SUSTAIN_S:g} s "
                         f"(lowest sustained {sustained:.2f} m)")
    return z <= sustained + SEATED_BAND_M


def procedural_seat_height(motion: Motion) -> float | None:
    """The seat height [m] a procedural sit/stand was generated for, or None for any other motion."""
    p = motion.params
    if p.get("activity") not in SEATED_ACTIVITIES or "format" in p or "pad_before" not in p:
        return None
    from rtchannel.motion.kinematics import NOMINAL_HEIGHT_M
    from rtchannel.motion.procedural import SEAT_HEIGHT_M

    return SEAT_HEIGHT_M * motion.rig.height / NOMINAL_HEIGHT_M


# Skin that can sit on a seat: pelvis and thighs. Feet tucked under a low seat (short legs) and hands resting by
# the hips also lie in the region under the pelvis; they would put the seat near the floor.
_SEATING_BONES = ("Hips", "LHipJoint", "RHipJoint", "LeftUpLeg", "RightUpLeg", "LowerBack")


def _skin(motion: Motion, lod: str) -> tuple[np.ndarray, np.ndarray]:
    """Skinned vertices (T, V, 3) [m], and which vertices (V,) are mainly moved by a seating bone."""
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices

    avatar = load_avatar(lod)
    dominant = np.asarray(avatar.dense_weights()).argmax(axis=1)
    names = avatar.rig.names
    seating = np.isin(dominant, [names.index(b) for b in _SEATING_BONES if b in names])
    return skin_vertices(avatar, motion), seating


def chair_for(motion: Motion, *, material: str = "wood", lod: str = "10k", back_gap: float = BACK_GAP_M,
              seat_height: float | None = None) -> Furniture:
    """The built-in chair placed under the seated person of `motion` (see the module doc).

    Args:
        motion: a motion with a seated phase (sit, stand, or a take that sits down).
        material: ITU material of the chair. lod: avatar LOD used for the skin (placement only).
        back_gap: clearance [m] between the body and the backrest.
        seat_height: override [m]; default from the motion.

    Returns:
        `Furniture` (mesh "chair", name "chair"); its `note` records how it was placed.

    Raises:
        ValueError: the motion has no seated phase.
    """
    seated = seated_frames(motion)
    mid, axis = _hips(motion)
    fwd = np.cross(axis[seated], [0.0, 0.0, 1.0])[:, :2]
    fwd = (fwd / np.linalg.norm(fwd, axis=1, keepdims=True)).mean(axis=0)
    yaw = float(np.arctan2(fwd[1], fwd[0]))
    centre = np.median(mid[seated, :2], axis=0)
    c, s = np.cos(yaw), np.sin(yaw)
    verts, seating = _skin(motion, lod)
    rel = verts[..., :2] - centre
    x, y, z = rel[..., 0] * c + rel[..., 1] * s, -rel[..., 0] * s + rel[..., 1] * c, verts[..., 2]
    from rtchannel.motion.kinematics import NOMINAL_HEIGHT_M

    k = motion.rig.height / NOMINAL_HEIGHT_M  # the pelvis search region is sized for a 1.75 m body
    if seat_height is not None:
        h, how = float(seat_height), "given"
    elif (drawn := procedural_seat_height(motion)) is not None:
        h, how = drawn, "the procedural generator's seat"
    else:
        under = (seating & (np.abs(y) < _PELVIS_HALF_WIDTH_M * k) & (x > _PELVIS_FORE_AFT_M[0] * k)
                 & (x < _PELVIS_FORE_AFT_M[1] * k) & (z < mid[:, None, 2]))
        lowest = np.where(under, z, np.inf).min(axis=1)[seated]
        h, how = float(np.median(lowest[np.isfinite(lowest)])), "median lowest buttock skin while seated"
    band = ((z >= h - SEAT_THICKNESS_M) & (z <= h + BACK_TOP_ABOVE_SEAT_M)
            & (np.abs(y) <= SEAT_WIDTH_M / 2 + 0.02))
    if not band.any():
        raise InputError(f"no skin above a {h:.2f} m seat: cannot place the backrest")
    rear = float(x[band].min())
    back_face = -SEAT_DEPTH_M / 2 + LEG_SECTION_M  # chair-local x of the backrest's front face
    offset = rear - back_gap - back_face  # chair origin ahead of the hip midpoint [m]

    def placed(shift: float, note: str = "") -> Furniture:
        pos = centre + (offset - shift) * np.array([c, s])
        return Furniture(mesh=CHAIR, material=material, position=(float(pos[0]), float(pos[1]), 0.0),
                         yaw_deg=float(np.degrees(yaw)), seat_height=round(h, 4), name="chair", note=note)

    # Knees wide apart over a low seat can put the shins where the front legs are: move the chair back (a
    # wider gap at the backrest) until legs, posts and backrest are clear of the body, within MAX_BACK_SHIFT_M.
    # In the hip frame the chair's local x is x - (offset - shift); only skin near the chair can touch it.
    near = ((np.abs(y) <= SEAT_WIDTH_M / 2) & (z <= h + BACK_TOP_ABOVE_SEAT_M)
            & (x >= offset - MAX_BACK_SHIFT_M - SEAT_DEPTH_M / 2) & (x <= offset + SEAT_DEPTH_M / 2))
    pts = np.column_stack([x[near] - offset, y[near], z[near]])
    # per leg/post/backrest box, the skin points it can reach for some shift in [0, MAX_BACK_SHIFT_M]
    reach = [(lo, hi, pts[np.all((pts >= lo - [MAX_BACK_SHIFT_M, 0, 0]) & (pts <= hi), axis=1)])
             for lo, hi in chair_boxes(h)[1:]]

    def clash(shift: float) -> float:
        return max(_deepest(q + [shift, 0.0, 0.0], lo, hi) for lo, hi, q in reach)

    shifts = np.arange(0.0, MAX_BACK_SHIFT_M + 1e-9, _SHIFT_STEP_M)
    depths = [clash(d) for d in shifts]
    shift = float(shifts[next((i for i, d in enumerate(depths) if d <= 0.0), int(np.argmin(depths)))])
    chair = placed(shift, f"chair_for: seat {h:.3f} m from {how}; {int(seated.sum())} seated frames; backrest "
                          f"{(back_gap + shift) * 100:.3g} cm behind the body"
                          + (f" (moved back {shift * 100:.3g} cm to clear the legs)" if shift else ""))
    depth = max(_deepest(pts + [shift, 0.0, 0.0], lo, hi) for lo, hi in chair_boxes(h))
    if depth > MAX_PENETRATION_M:
        warnings.warn(f"the body reaches {depth * 100:.1f} cm into the placed chair (more than "
                      f"{MAX_PENETRATION_M * 100:g} cm): this take's seat differs from a standard chair",
                      stacklevel=2)
    return chair


def _deepest(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Deepest [m] any point [N, 3] lies inside the box [lo, hi] (0 if none does)."""
    return float(np.minimum(points - lo, hi - points).min(axis=1).max(initial=0.0))


def chair_penetration(chair: Furniture, motion: Motion, lod: str = "10k") -> np.ndarray:
    """Per frame [F], the deepest [m] any skin vertex (avatar `lod`) lies inside the chair's boxes."""
    return chair.penetration(_skin(motion, lod)[0]).max(axis=1)


def wants_chair(motion: Motion) -> bool:
    """True for the activities that happen on a chair (sit, stand)."""
    return (motion.activity or motion.params.get("activity", "")) in SEATED_ACTIVITIES


CHAIR_MODES = ("auto", "none")
# The one chair default of the API (`rtchannel.trace`/`simulate`) and the CLI (`--chair`); a dataset plan's `chair`
# field defaults to the same "none". "auto" puts the chair under sit and stand.
DEFAULT_CHAIR = "none"


__all__ = ["CHAIR_MODES", "DEFAULT_CHAIR", "SEATED_ACTIVITIES", "chair_for", "chair_penetration",
           "procedural_seat_height", "seated_frames", "wants_chair"]
