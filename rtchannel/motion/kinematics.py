"""Pose-building helpers for the procedural motion generators.

Conventions (project frame, z up, the body facing +x, its left on +y): a *pitch* is a rotation about +y
(``rot_y``); a positive pitch tilts the upper end of an upright segment forward, so for a segment
hanging down (thigh, shank, arm) it swings the lower end backward. Knee flexion is therefore
``shank pitch - thigh pitch`` and hip flexion ``trunk pitch - thigh pitch``. A positive foot pitch
points the toes down (plantarflexion).

Smooth profiles: positions and angles are built from minimum-jerk steps (Flash & Hogan 1985,
J. Neurosci. 5:1688) or C1 piecewise-cubic key-frame curves, so joint velocities are continuous; the
radar simulator differentiates positions and would turn any jump into a spurious Doppler line.

Leg inverse kinematics is analytic: the hip's ab/adduction is solved first so that the ankle lies at
the requested lateral offset, after which the flexion rotations (all about the world y axis) leave that
offset unchanged and the remaining hip/knee angles follow from the law of cosines in the x-z plane.
"""
from __future__ import annotations

import numpy as np

from processing.cubic import hermite_spline, logsumexp, pchip_slopes
from rtchannel.motion.pose import Rig, forward_kinematics

DEG = np.pi / 180.0
NOMINAL_HEIGHT_M = 1.75  # body height the literature numbers below are quoted for [m]


def rot_x(a) -> np.ndarray:
    """Rotations [..., 3, 3] by angles `a` [rad] about +x."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros(a.shape + (3, 3))
    r[..., 0, 0] = 1.0
    r[..., 1, 1], r[..., 1, 2], r[..., 2, 1], r[..., 2, 2] = c, -s, s, c
    return r


def rot_y(a) -> np.ndarray:
    """Rotations [..., 3, 3] by angles `a` [rad] about +y (positive: +z towards +x)."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros(a.shape + (3, 3))
    r[..., 1, 1] = 1.0
    r[..., 0, 0], r[..., 0, 2], r[..., 2, 0], r[..., 2, 2] = c, s, -s, c
    return r


def rot_z(a) -> np.ndarray:
    """Rotations [..., 3, 3] by angles `a` [rad] about +z (positive: counter-clockwise seen from above)."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros(a.shape + (3, 3))
    r[..., 2, 2] = 1.0
    r[..., 0, 0], r[..., 0, 1], r[..., 1, 0], r[..., 1, 1] = c, -s, s, c
    return r


def rot_axis(axis, a) -> np.ndarray:
    """Rotations [..., 3, 3] by angles `a` [rad] about the fixed unit vector `axis` (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    a = np.asarray(a, float)[..., None, None]
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * (kx @ kx)


def minjerk(s) -> np.ndarray:
    """Minimum-jerk step 0 -> 1 of the normalised time `s` (clipped to [0, 1]); zero end velocity."""
    s = np.clip(np.asarray(s, float), 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def step(t, t0: float, t1: float) -> np.ndarray:
    """Minimum-jerk step from 0 at time `t0` to 1 at `t1` [s]."""
    return minjerk((np.asarray(t, float) - t0) / max(t1 - t0, 1e-9))


def keyframes(u, knots, values) -> np.ndarray:
    """C1 curve through (`knots`, `values`), held constant outside the knots.

    Interior slopes are monotone (Fritsch-Carlson, as PCHIP) so the curve never overshoots a key; the
    end slopes are zero so it joins the constant hold without a velocity jump.
    """
    knots, values = np.asarray(knots, float), np.asarray(values, float)
    slopes = pchip_slopes(knots, values)  # end slopes 0
    u = np.clip(np.asarray(u, float), knots[0], knots[-1])
    return hermite_spline(knots, values, slopes, u)


def hermite(s, p0, v0, p1, v1, duration: float) -> np.ndarray:
    """Cubic Hermite segment at normalised time `s` in [0, 1] with end values and end rates [per s]."""
    s = np.clip(np.asarray(s, float), 0.0, 1.0)
    h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
    h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    return h00 * p0 + h10 * v0 * duration + h01 * p1 + h11 * v1 * duration


def softmin(values, tau: float, axis: int = 0) -> np.ndarray:
    """Smooth minimum (never above the true minimum, at most tau*ln(n) below it)."""
    return -tau * logsumexp(-np.asarray(values) / tau, axis=axis)


def assemble(rig: Rig, n: int, globals_: dict, locals_: dict) -> np.ndarray:
    """Local rotations [n, J, 3, 3] for FK from a mix of prescribed global and local rotations.

    `globals_` maps joint names to rest-relative global rotations ([3, 3] or [n, 3, 3]) and wins over
    `locals_` (rotations relative to the parent); any other joint keeps its parent's orientation.
    """
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    glob = np.empty((n, rig.n_joints, 3, 3))
    loc = np.empty_like(glob)
    for j, name in enumerate(rig.names):
        gp = glob[:, rig.parents[j]] if rig.parents[j] >= 0 else eye
        if name in globals_:
            glob[:, j] = np.broadcast_to(globals_[name], (n, 3, 3))
            loc[:, j] = np.swapaxes(gp, -1, -2) @ glob[:, j]
        else:
            loc[:, j] = np.broadcast_to(locals_.get(name, eye), (n, 3, 3))
            glob[:, j] = gp @ loc[:, j]
    return loc


def pose(rig: Rig, n: int, globals_: dict, locals_: dict, root) -> tuple[np.ndarray, np.ndarray]:
    """(global rotations [n, J, 3, 3], positions [n, J, 3]) of a pose given like `assemble`, root [n, 3]."""
    return forward_kinematics(rig, assemble(rig, n, globals_, locals_), np.broadcast_to(root, (n, 3)))


def arm_local(rig: Rig, side: str, flexion, abduction, elbow) -> dict:
    """Local rotations of one arm relative to the chest for anatomical angles [deg, arrays].

    flexion: forward elevation of the upper arm (0 = along the trunk, 90 = pointing forward).
    abduction: sideways elevation (0 = against the trunk; the rest A-pose is ~42 deg).
    elbow: included-angle flexion (0 = straight); the rest pose has ~43 deg.
    """
    sign = 1.0 if side == "Left" else -1.0
    sh, el, wr = (rig.index(f"{side}{n}") for n in ("Arm", "ForeArm", "Hand"))
    upper, fore = rig.rest[el] - rig.rest[sh], rig.rest[wr] - rig.rest[el]
    rest_abd = np.arctan2(abs(upper[1]), -upper[2])
    rest_elbow = np.arccos(upper @ fore / np.linalg.norm(upper) / np.linalg.norm(fore))
    shoulder = rot_y(-np.asarray(flexion) * DEG) @ rot_x(sign * (np.asarray(abduction) * DEG - rest_abd))
    forearm = rot_axis(np.cross(upper, fore), np.asarray(elbow) * DEG - rest_elbow)
    return {f"{side}Arm": shoulder, f"{side}ForeArm": forearm}


def spine_local(pitch, roll=0.0, yaw=0.0, joints=("LowerBack", "Spine", "Spine1"),
                shares=(0.3, 0.35, 0.35)) -> dict:
    """Local rotations spreading a total bend [deg] (pitch forward, roll to the left, yaw) over a chain."""
    out = {}
    for name, w in zip(joints, shares):
        out[name] = rot_z(w * np.asarray(yaw) * DEG) @ rot_y(w * np.asarray(pitch) * DEG) @ rot_x(
            w * np.asarray(roll) * DEG)
    return out


def _leg_vectors(rig: Rig, side: str):
    """Rest thigh (hip -> knee) and shank (knee -> ankle) vectors [m]."""
    hip, knee, ankle = (rig.rest[rig.index(f"{side}{n}")] for n in ("UpLeg", "Leg", "Foot"))
    return knee - hip, ankle - knee


def _adduction(thigh, shank, dy) -> np.ndarray:
    """Rotation angle about x [rad] that puts the ankle `dy` [m] sideways of the hip (branch nearest 0)."""
    y, z = thigh[1] + shank[1], thigh[2] + shank[2]
    r, b = np.hypot(y, z), np.arctan2(z, y)
    c = np.arccos(np.clip(dy / r, -1.0, 1.0))
    a1, a2 = -b + c, -b - c
    a1, a2 = (a1 + np.pi) % (2 * np.pi) - np.pi, (a2 + np.pi) % (2 * np.pi) - np.pi
    return np.where(np.abs(a1) < np.abs(a2), a1, a2)


def _planar(vec, add):
    """x-z components [.., 2] of a rest vector after the rotation `add` about x."""
    v = rot_x(add) @ vec
    return v[..., [0, 2]]


def _ang(v):
    return np.arctan2(v[..., 1], v[..., 0])


def _ry2(b, v):
    c, s = np.cos(b), np.sin(b)
    return np.stack([v[..., 0] * c + v[..., 1] * s, -v[..., 0] * s + v[..., 1] * c], axis=-1)


def hip_centre(rig: Rig, side: str, root, pelvis) -> np.ndarray:
    """Hip joint centres [n, 3] for root positions [n, 3] and pelvis rotations [n, 3, 3]."""
    off = rig.rest[rig.index(f"{side}UpLeg")] - rig.rest[0]
    return np.asarray(root) + np.asarray(pelvis) @ off


def leg_ik(rig: Rig, side: str, hip, ankle, foot_pitch, min_flex_deg: float = 2.0) -> dict:
    """Global rotations of thigh, shank, foot and toes putting the ankle joint at `ankle` [n, 3].

    hip: hip joint centres [n, 3]; foot_pitch: foot angle [rad] about y (positive toes down). The knee
    bends forward (anatomical flexion only); targets out of reach leave the knee at `min_flex_deg`
    of geometric flexion and the ankle short of its target.
    """
    thigh, shank = _leg_vectors(rig, side)
    d = np.asarray(ankle) - np.asarray(hip)
    add = _adduction(thigh, shank, d[:, 1])
    t2, s2 = _planar(thigh, add), _planar(shank, add)
    lt, ls = np.linalg.norm(t2, axis=-1), np.linalg.norm(s2, axis=-1)
    dist = np.hypot(d[:, 0], d[:, 2])
    # Law of cosines in the leg plane; k = 0 is the rest knee, -(angle(t2) - angle(s2)) a straight leg.
    c = (dist ** 2 - lt ** 2 - ls ** 2) / (2 * lt * ls)
    k = -(_ang(t2) - _ang(s2)) + np.arccos(np.clip(c, -1.0, np.cos(min_flex_deg * DEG)))
    pitch = _ang(t2 + _ry2(k, s2)) - np.arctan2(d[:, 2], d[:, 0])
    pitch = (pitch + np.pi) % (2 * np.pi) - np.pi
    fp = np.asarray(foot_pitch, float)
    # The toes stay flat on the floor while the heel is up; they follow the foot when it points up.
    toe = fp - 0.05 * (np.logaddexp(0.0, fp / 0.05) - np.log(2.0))
    return {f"{side}UpLeg": rot_y(pitch) @ rot_x(add), f"{side}Leg": rot_y(pitch + k) @ rot_x(add),
            f"{side}Foot": rot_y(fp), f"{side}ToeBase": rot_y(toe)}


def root_height_cap(rig: Rig, side: str, root_xy, pelvis, ankle, flex_deg: float) -> np.ndarray:
    """Root heights [n] at which the leg reaches `ankle` [n, 3] with `flex_deg` geometric knee flexion."""
    thigh, shank = _leg_vectors(rig, side)
    n = len(ankle)
    hip = hip_centre(rig, side, np.column_stack([root_xy, np.zeros(n)]), pelvis)
    d = np.asarray(ankle) - hip
    add = _adduction(thigh, shank, d[:, 1])
    t2, s2 = _planar(thigh, add), _planar(shank, add)
    k = -(_ang(t2) - _ang(s2)) + flex_deg * DEG
    length = np.linalg.norm(t2 + _ry2(k, s2), axis=-1)
    return np.asarray(ankle)[:, 2] + np.sqrt(np.maximum(length ** 2 - d[:, 0] ** 2, 1e-6)) - hip[:, 2]


def ground_lift(rig: Rig, positions, radii: dict, tau: float) -> np.ndarray:
    """Vertical shifts [n] that put the body's (smoothly) lowest surface point on the floor.

    radii: joint name -> distance [m] from the joint centre to the skin it touches the floor with.
    """
    z = np.stack([positions[:, rig.index(k), 2] - r for k, r in radii.items()])
    return -softmin(z, tau)


def rocker_ankle(footprint, pivot_rel, pitch) -> np.ndarray:
    """Ankle (x, z) [n, 2] of a foot rolling about a floor pivot (heel or toe) by `pitch` [rad].

    footprint: ankle (x, z) when the foot is flat; pivot_rel: pivot minus ankle in the flat foot.
    """
    pivot_rel = np.asarray(pivot_rel, float)
    return np.asarray(footprint) + pivot_rel - _ry2(np.asarray(pitch, float), pivot_rel)


def ramp_integral(tau, duration: float) -> np.ndarray:
    """Integral over time [s] of a minimum-jerk 0 -> 1 step that starts at tau = 0 and lasts `duration`."""
    tau = np.asarray(tau, float)
    s = np.clip(tau / duration, 0.0, 1.0)
    inside = duration * (2.5 * s ** 4 - 3 * s ** 5 + s ** 6)
    return np.where(tau > duration, tau - 0.5 * duration, inside)


def _rocker_rate(pivot_rel, pitch: float) -> np.ndarray:
    """d(ankle x, z)/d(pitch) [m/rad] of a foot rolling about a floor pivot (see `rocker_ankle`)."""
    c, s = np.cos(pitch), np.sin(pitch)
    return np.array([pivot_rel[0] * s - pivot_rel[1] * c, pivot_rel[0] * c + pivot_rel[1] * s])


def foot_track(t, stances, heel, toe, heel_rock: float, heel_rise: float, lift: float, clearance: float):
    """Ankle positions [n, 3] and foot pitch [n] (rad, toes down positive) of one foot.

    stances: list of (t_on, t_off, x, y, pitch_on, pitch_off): heel strike and toe-off times [s]
        (-inf / +inf for a foot already standing at the start / staying at the end), the ankle (x, y)
        [m] of the flat foot, the toes-up angle at heel strike and the heel-up angle at toe-off [rad].
    heel, toe: floor pivots of the heel and of the toe joint relative to the flat foot's ankle (x, z).
    heel_rock: heel strike -> foot flat [s]; heel_rise: heel off -> toe off [s]; lift: further rise
        of the ankle after toe-off [m]; clearance: ankle height above its standing height at
        mid-swing [m].
    The foot rolls over the heel, lies flat, rolls over the toes, then swings along cubic Hermite
    curves that match the toe-off velocity and land with zero velocity.
    """
    t = np.asarray(t, float)
    ank, pitch = np.zeros((t.size, 3)), np.zeros(t.size)
    heel, toe = np.asarray(heel, float), np.asarray(toe, float)
    h = -heel[1]
    for i, (t_on, t_off, x, y, p_on, p_off) in enumerate(stances):
        m = (t >= t_on) & (t <= t_off)
        ph = np.zeros(m.sum())
        if np.isfinite(t_on):  # the foot lands still rotating and slows to flat (rate 1.5 p_on / heel_rock)
            ph += hermite((t[m] - t_on) / heel_rock, -p_on, 1.5 * p_on / heel_rock, 0.0, 0.0, heel_rock)
        if np.isfinite(t_off):
            s = np.clip((t[m] - t_off + heel_rise) / heel_rise, 0.0, 1.0)
            ph += p_off * (2 * s ** 2 - s ** 3)  # still rotating at toe-off (rate p_off / heel_rise)
        xz = rocker_ankle((x, h), np.where(ph[:, None] < 0, heel, toe), ph)
        ank[m] = np.column_stack([xz[:, 0], np.full(m.sum(), y), xz[:, 1]])
        pitch[m] = ph
        if i + 1 == len(stances):
            break
        t_next, _, x1, y1, p1, _ = stances[i + 1]
        rate, rate1 = p_off / heel_rise, 1.5 * p1 / heel_rock  # foot angular velocities at toe-off, strike
        p0 = rocker_ankle((x, h), toe, np.array([p_off]))[0]
        v0 = rate * _rocker_rate(toe, p_off)
        end = rocker_ankle((x1, h), heel, np.array([-p1]))[0]
        v1 = rate1 * _rocker_rate(heel, -p1)
        m = (t > t_off) & (t < t_next)
        dur = t_next - t_off
        s = (t[m] - t_off) / dur
        ank[m, 0] = hermite(s, p0[0], v0[0], end[0], v1[0], dur)
        ank[m, 1] = y + (y1 - y) * minjerk(s)
        # Heel highest early in swing, foot skimming the floor by mid-swing (Winter 1992, toe clearance).
        ank[m, 2] = hermite_spline([0.0, 0.25, 0.6, 1.0], [p0[1], p0[1] + lift, h + clearance, end[1]],
                                   [v0[1] * dur, 0.0, 0.0, v1[1] * dur], s)
        # The ankle dorsiflexes back to a level foot by mid-swing, then the toes come up for the strike.
        pitch[m] = hermite_spline([0.0, 0.45, 1.0], [p_off, 0.0, -p1], [rate * dur, -(p1 + p_off), rate1 * dur], s)
    return ank, pitch
