"""Retarget an imported skeleton (`SourceMotion`) onto the avatar rig.

Two kinds of bones (`rigs.POSTURE`):
- limb bones (thigh, shank, clavicle, upper arm, forearm, hand, fingers) are matched by direction: the
  avatar's rest bone is rotated onto the source bone's world direction, so proportions may differ
  freely. The roll about the bone is copied from the source relative to its neutral pose (T-pose)
  when one is known (BVH), else from a twist vector rigid with the source bone (a marker offset in
  C3D) with the constant roll offset calibrated over the take (circular mean relative to the parent).
- posture bones (pelvis, spine, neck, head, feet, toes) copy the source orientation relative to its
  neutral pose: their bone directions are rig-specific (the iClone lumbar bone leans 36 deg forward in
  a T-pose, its ankle sits higher), so matching directions would bend the avatar. Without a neutral,
  the mean orientation relative to the parent over the take is taken as neutral.
Unmapped bones follow their parent. The root is placed so that the avatar's hip-joint midpoint follows
the source's, scaled by the leg-length ratio (hip -> knee -> ankle); then the floor is levelled and
found from the planted feet, and a per-frame vertical correction keeps planted feet on it.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from rtchannel.motion.rigs import JOINT_MAPS, POSTURE
from rtchannel.motion.source import SourceMotion
from rtchannel.assets import avatar_dir
from rtchannel.motion.pose import Motion, Rig, avatar_rig, blend_points


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0), n[..., 0]


def _perp(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


def _frame(p: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Orthonormal frames [..., 3, 3] with columns (p, s, p x s); p unit, s unit and perpendicular."""
    return np.stack([p, s, np.cross(p, s)], axis=-1)


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotations [F, 3, 3] taking unit vectors a [F, 3] to b [F, 3] by the smallest angle."""
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)
    k = np.zeros(a.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    # Rodrigues with 1/(1+c); antiparallel vectors (c ~ -1) get a half turn about a perpendicular axis.
    out = np.eye(3) + k + k @ k / np.maximum(1.0 + c, 1e-9)[..., None, None]
    flip = c < -1 + 1e-9
    if flip.any():
        ax = _unit(np.cross(a[flip], np.where(np.abs(a[flip, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])))[0]
        out[flip] = 2 * ax[:, :, None] * ax[:, None, :] - np.eye(3)
    return out


def _polar(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


class _Source:
    """Name resolution ("a|b" alternatives) over a SourceMotion."""

    def __init__(self, src: SourceMotion):
        self.src = src

    def _pick(self, table: dict, name: str):
        for alt in name.split("|"):
            if alt in table:
                return table[alt]
        raise KeyError(name)

    def point(self, name: str) -> np.ndarray:
        return self._pick(self.src.points, name)

    def orient(self, name: str) -> np.ndarray:
        return self._pick(self.src.orientations, name)

    def neutral(self, name: str) -> np.ndarray | None:
        try:
            return self._pick(self.src.neutral, name)
        except KeyError:
            return None


def source_leg_length(src: SourceMotion, kind: str | None = None) -> float:
    """Median hip -> knee -> ankle length of the source's left leg [m]."""
    hip, knee, ankle = (src.points[n] for n in JOINT_MAPS[kind or src.kind]["leg"])
    d = np.linalg.norm(knee - hip, axis=1) + np.linalg.norm(ankle - knee, axis=1)
    return float(np.median(d))


def rig_leg_length(rig: Rig) -> float:
    """Hip -> knee -> ankle length of the rig's left leg [m]."""
    i = [rig.index(n) for n in ("LeftUpLeg", "LeftLeg", "LeftFoot")]
    return float(np.linalg.norm(rig.rest[i[1]] - rig.rest[i[0]]) + np.linalg.norm(rig.rest[i[2]] - rig.rest[i[1]]))


def height_for_leg(leg_m: float) -> float:
    """Height [m] of the avatar scaled so that its leg (hip -> ankle) is `leg_m` long."""
    base = avatar_rig()
    return base.height * leg_m / rig_leg_length(base)


def _twist_vectors(s: _Source, spec, primary: np.ndarray) -> np.ndarray | None:
    if spec is None:
        return None
    if spec[0] == "vec":
        return s.point(spec[2]) - s.point(spec[1])
    g = s.orient(spec[1])
    local = _unit(np.einsum("fba,fb->a", g, primary))[0]  # bone direction in the joint's local axes
    e = np.eye(3)[int(np.argmin(np.abs(local)))]
    e = _unit(e - (e @ local) * local)[0]
    return g @ e


def _calibrated_twist(p: np.ndarray, w: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Twist vectors w [F, 3] turned about p by the constant angle that best aligns them with ref.

    The angle is the weighted circular mean over the take, weights |w_perp| |ref_perp| so that frames
    where either vector runs along the bone do not count.
    """
    ref, ref_n = _unit(_perp(ref, p))
    tw, tw_n = _unit(_perp(w, p))
    ang = np.arctan2(np.einsum("fi,fi->f", p, np.cross(tw, ref)), np.einsum("fi,fi->f", tw, ref))
    wt = ref_n * tw_n
    theta = np.arctan2(np.sum(wt * np.sin(ang)), np.sum(wt * np.cos(ang)))
    sv = np.cos(theta) * tw + np.sin(theta) * np.cross(p, tw)
    bad = tw_n < 1e-6
    sv[bad] = ref[bad]
    return sv


def _posture_rotation(g: np.ndarray, neutral: np.ndarray | None, r_par: np.ndarray) -> np.ndarray:
    if neutral is not None:
        return g @ neutral.T
    # No neutral pose known: the bone's mean orientation relative to its parent is taken as neutral.
    return g @ _polar(np.einsum("fba,fbc->ac", g, r_par))


def bone_rotations(src: SourceMotion, rig: Rig, kind: str | None = None) -> np.ndarray:
    """Rest-relative global rotations [F, J, 3, 3] of the avatar rig following the source bones."""
    s = _Source(src)
    bones = JOINT_MAPS[kind or src.kind]["bones"]
    f = src.n_frames
    rots = np.empty((f, rig.n_joints, 3, 3))
    hip_l, hip_r = rig.rest[rig.index("LeftUpLeg")], rig.rest[rig.index("RightUpLeg")]
    for j, name in enumerate(rig.names):
        parent = rig.parents[j]
        r_par = rots[:, parent] if parent >= 0 else np.broadcast_to(np.eye(3), (f, 3, 3))
        spec = bones.get(name)
        if spec is None:
            rots[:, j] = r_par
            continue
        a, b, twist = spec
        oriented = twist is not None and twist[0] in ("orient", "only")
        neutral = s.neutral(twist[1]) if oriented else None
        if oriented and (name in POSTURE or twist[0] == "only" or a is None):
            rots[:, j] = _posture_rotation(s.orient(twist[1]), neutral, r_par)
            continue
        p0 = _unit(hip_l - hip_r if name == "Hips" else rig.tails[j] - rig.rest[j])[0]
        p = _unit(s.point(b) - s.point(a))[0]
        if oriented and neutral is not None:
            # Copy the rotation from the neutral pose, after swinging the avatar's rest bone onto the
            # source's neutral bone direction (e.g. A-pose arm -> T-pose arm).
            g = s.orient(twist[1])
            d_n = neutral @ _unit(np.einsum("fba,fb->a", g, p))[0]
            rots[:, j] = g @ neutral.T @ _min_rotation(p0[None], d_n[None])[0]
            continue
        w = _twist_vectors(s, twist, p)
        if w is None:
            rots[:, j] = _min_rotation(np.einsum("fab,b->fa", r_par, p0), p) @ r_par
            continue
        s0 = _unit(_perp(np.eye(3)[int(np.argmin(np.abs(p0)))], p0))[0]
        sv = _calibrated_twist(p, w, np.einsum("fab,b->fa", r_par, s0))
        rots[:, j] = _frame(p, sv) @ _frame(p0, s0).T
    return rots


def chain_positions(rig: Rig, rots: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Joint positions [F, J, 3] from global rotations and the root (Hips) position [F, 3]."""
    pos = np.empty(rots.shape[:2] + (3,))
    pos[:, 0] = root
    for j in range(1, rig.n_joints):
        p = rig.parents[j]
        pos[:, j] = pos[:, p] + rots[:, p] @ (rig.rest[j] - rig.rest[p])
    return pos


@lru_cache(maxsize=1)
def _soles() -> dict[str, np.ndarray]:
    # the avatar's sole vertices, precomputed by rtchannel.body.avatar.sole_asset (a test pins the file to
    # it): retargeting needs only these, so the motion layer never loads the body mesh
    with np.load(avatar_dir() / "soles.npz") as f:
        return {k: f[k] for k in f.files}


def sole_points(motion: Motion) -> dict[str, np.ndarray]:
    """Skinned sole vertices per foot, {"Left": [F, n, 3], "Right": [F, n, 3]} (m), full mesh."""
    s = _soles()
    rest = s["rest"] if abs(float(s["height"]) - motion.rig.height) < 1e-9 else s["rest"] * (
        motion.rig.height / float(s["height"]))
    mats = motion.skinning_matrices()
    return {side: blend_points(s["weights"][idx], rest[idx], mats)
            for side, idx in (("Left", np.flatnonzero(s["side"] > 0)), ("Right", np.flatnonzero(s["side"] < 0)))}


def _planted_lowest(motion: Motion, max_speed: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Per foot and frame: lowest sole point [2, F, 3] (m) and whether that foot is planted [2, F]
    (its ankle moves slower than `max_speed` m/s horizontally)."""
    low, planted = [], []
    for side, pts in sole_points(motion).items():
        ankle = motion.positions[:, motion.rig.index(f"{side}Foot"), :2]
        speed = np.linalg.norm(np.gradient(ankle, axis=0), axis=1) * motion.fps
        k = np.argmin(pts[..., 2], axis=1)
        low.append(pts[np.arange(len(k)), k])
        planted.append(speed < max_speed)
    return np.stack(low), np.stack(planted)


def stance_contacts(motion: Motion, max_speed: float = 0.3) -> np.ndarray:
    """Lowest sole points [N, 3] (m) of the feet in the frames where they are planted."""
    low, planted = _planted_lowest(motion, max_speed)
    return low[planted]


def contact_correction(motion: Motion, max_shift: float = 0.08, smooth_s: float = 0.04) -> tuple[Motion, float]:
    """Shift each frame vertically so the lowest planted sole touches z = 0; returns (motion, RMS shift m).

    Some converted takes lost the pelvis' vertical motion (the iClone takes with an RL_BoneRoot root
    keep the hips at one height, so planted feet hover up to 5 cm). Only planted (or sinking) feet within
    `max_shift` of the floor count as contacts (a lying body's raised, still legs do not); frames without
    one are interpolated, and the shift is smoothed with a Gaussian of `smooth_s` seconds.
    """
    from scipy.ndimage import gaussian_filter1d

    low, planted = _planted_lowest(motion)
    z = low[..., 2]
    # A sole dipping into the floor counts as contact too, planted or not (toe-off scuffs).
    contact = (planted | (z < 0)) & (np.abs(z) < max_shift)
    h = np.where(contact, z, np.inf).min(axis=0)
    ok = np.isfinite(h)
    if ok.sum() < 2:
        return motion, 0.0
    t = np.arange(motion.n_frames)
    dz = -gaussian_filter1d(np.interp(t, t[ok], h[ok]), smooth_s * motion.fps, mode="nearest")
    pos = motion.positions.copy()
    pos[..., 2] += dz[:, None]
    out = Motion(motion.rig, motion.fps, motion.rotations, pos, motion.activity, dict(motion.params))
    return out, float(np.sqrt(np.mean(dz ** 2)))


def ground(motion: Motion, percentile: float = 20.0, level: bool = True) -> tuple[Motion, dict]:
    """Level the floor and put the planted soles on z = 0; returns (motion, what was done).

    Mocap floors are rarely at the file's zero, and some takes walk on a floor tilted by 1-2 deg
    against the file's up axis (CMU subject 07: planted feet rise 7 cm over 4 m). When feet are
    planted over more than 1.5 m of travel, the slope of their contact heights along the direction
    of travel is fitted and removed by a rotation about the horizontal axis across it (tilts of
    0.2-8 deg only). Then the `percentile` of the planted-sole heights is put at z = 0 (a low
    percentile: one sinking toe should not lift the whole take); without planted feet, the lowest
    sole point per frame is used instead.
    """
    info = {"level_deg": 0.0, "ground_shift_m": 0.0}
    contacts = stance_contacts(motion)
    if level and len(contacts) >= 10:
        xy = contacts[:, :2] - contacts[:, :2].mean(axis=0)
        axis = np.linalg.svd(xy, full_matrices=False)[2][0]
        u = xy @ axis
        if np.ptp(u) > 1.5:
            slope = np.polyfit(u, contacts[:, 2], 1)[0]
            tilt = float(np.arctan(slope))
            if np.radians(0.2) < abs(tilt) < np.radians(8.0):
                from scipy.spatial.transform import Rotation

                # z x axis: lowers +u
                turn = Rotation.from_rotvec(tilt * np.array([-axis[1], axis[0], 0.0])).as_matrix()
                centre = np.array([*contacts[:, :2].mean(axis=0), 0.0])
                pos = (motion.positions - centre) @ turn.T + centre
                rot = np.einsum("ab,fjbc->fjac", turn, motion.rotations)
                motion = Motion(motion.rig, motion.fps, rot, pos, motion.activity, dict(motion.params))
                contacts = stance_contacts(motion)
                info["level_deg"] = float(np.degrees(tilt))
    if len(contacts) >= 10:
        dz = -float(np.percentile(contacts[:, 2], percentile))
    else:
        soles = np.concatenate(list(sole_points(motion).values()), axis=1)
        dz = -float(np.percentile(soles[..., 2].min(axis=1), 10.0))
    info["ground_shift_m"] = dz
    pos = motion.positions + np.array([0.0, 0.0, dz])
    return Motion(motion.rig, motion.fps, motion.rotations, pos, motion.activity, dict(motion.params)), info


def facing_yaw(motion: Motion, frames: int = 15) -> float:
    """Heading [rad] of the body's forward axis (left-hip direction turned -90 deg) over the first frames."""
    i_l, i_r = motion.rig.index("LeftUpLeg"), motion.rig.index("RightUpLeg")
    left = (motion.positions[:frames, i_l] - motion.positions[:frames, i_r]).mean(axis=0)
    return float(np.arctan2(-left[0], left[1]))


def drop_leading_discontinuities(src: SourceMotion, max_scan: int = 10,
                                 max_speed: float = 8.0) -> tuple[SourceMotion, int]:
    """Drop leading frames cut off from the rest by a jump (e.g. a converter's or a capture system's
    reference T-pose in frame 0).

    A transition is a jump when any tracked point (joint, end site or marker) moves faster than
    `max_speed` m/s and more than ten times that point's median speed over the take; only the first
    `max_scan` frames are examined. Every point counts, not only the hips: a reference pose often
    keeps the root where the take starts and differs only in the arms (CMU 75_17: hands 0.5 m apart
    between frames 0 and 1 at 30 fps, 15 m/s).
    """
    pts = np.stack(list(src.points.values()), axis=1)  # [F, M, 3]
    if len(pts) < 4:
        return src, 0
    speed = np.linalg.norm(np.diff(pts, axis=0), axis=2) * src.fps  # [F-1, M]
    typical = np.nanmedian(speed, axis=0)
    with np.errstate(invalid="ignore"):
        jump = (speed[:max_scan] > max_speed) & (speed[:max_scan] > 10 * typical)
    rows = np.flatnonzero(jump.any(axis=1))
    if not len(rows):
        return src, 0
    k = int(rows[-1]) + 1
    return src.sliced(k), k


def retarget(src: SourceMotion, *, height: float | None = None, activity: str = "",
             align: bool = True, floor: bool = True, foot_contact: bool = True,
             kind: str | None = None) -> Motion:
    """Map an imported motion onto the avatar rig.

    Args:
        src: imported motion (project frame, metres).
        height: avatar height [m]; None keeps the source's leg length (stride and speed unchanged).
        activity: activity label stored in the Motion.
        align: start the hips above the origin with the body facing +x.
        floor: level the floor and put the planted soles on z = 0 (`ground`); False keeps the
            source's vertical placement (the file's floor, converted to metres and z up).
        foot_contact: per-frame vertical correction putting planted feet on the floor
            (`contact_correction`), after `ground`; only with `floor`.
        kind: joint map ("cc", "cmu", "c3d"); defaults to the importer's.

    Returns:
        The retargeted, grounded `Motion`; ``params`` records the source, scaling and shifts.
    """
    kind = kind or src.kind
    leg_src = source_leg_length(src, kind)
    if height is None:
        height = height_for_leg(leg_src)
    rig = avatar_rig(height)
    ratio = rig_leg_length(rig) / leg_src
    rots = bone_rotations(src, rig, kind)
    hl, hr = JOINT_MAPS[kind]["hips"]
    mid_src = 0.5 * (src.points[hl] + src.points[hr])
    # Place the root so that the avatar's hip-joint midpoint follows the scaled source midpoint.
    rel = chain_positions(rig, rots, np.zeros((src.n_frames, 3)))
    mid_rel = 0.5 * (rel[:, rig.index("LeftUpLeg")] + rel[:, rig.index("RightUpLeg")])
    motion = Motion(rig, src.fps, rots, rel + (ratio * mid_src - mid_rel)[:, None], activity)
    ground_info = {"level_deg": 0.0, "ground_shift_m": 0.0, "contact_rms_m": 0.0}
    if floor:
        motion, found = ground(motion)
        ground_info.update(found)
    if floor and foot_contact:
        motion, ground_info["contact_rms_m"] = contact_correction(motion)
    yaw, shift = 0.0, np.zeros(3)
    if align:
        yaw = -facing_yaw(motion)
        motion = motion.transformed(yaw)
        shift = -np.array([*motion.positions[0, 0, :2], 0.0])
        motion = motion.transformed(0.0, shift)
    motion = replace(motion, params={**src.info, "source": src.path, "height": float(height), "leg_ratio": float(ratio),
                     "source_leg_m": leg_src, **ground_info, "floor": bool(floor),
                     "foot_contact": bool(floor and foot_contact), "align": bool(align),
                     "align_yaw_rad": float(yaw), "align_shift_m": shift[:2].tolist(), "activity": activity})
    return motion


__all__ = ["JOINT_MAPS", "POSTURE", "retarget", "bone_rotations", "ground", "drop_leading_discontinuities",
           "source_leg_length", "height_for_leg", "contact_correction", "stance_contacts"]
